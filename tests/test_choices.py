"""The questions a diagnosis may be asked are checked once
(fabricsurf/inverse/diagnosis/choices.py): the library's ``diagnose`` refuses what the command
line refuses, with the same message worded with its own argument names, before anything is
built."""

from __future__ import annotations

import pytest

from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.experiment import template
from fabricsurf.inverse.diagnosis import diagnose as dg
from fabricsurf.inverse.diagnosis.choices import Labels, check_choices, library_labels

BASE = ["fibre_stretch", "shear"]
PARAMS = {"shear": {"k_s": 0.5}}
PLANAR = [n for n, cls in dg.EFFECTS.items() if cls.in_plane]

CASES = [  # (candidates, fixed, confirm, max_effects, library message, command-line message)
    (None, None, 0, 1, r"^confirm 0: must be at least 1$", r"^--confirm 0: must be"),
    (None, None, 1, -1, r"^max_effects -1: must be at least 0$", r"^--max-effects -1: must"),
    (
        ["sheer"],
        None,
        1,
        1,
        r"^candidates \['sheer'\]: unknown term 'sheer'",
        r"^--candidates sheer: unknown term 'sheer'",
    ),
    (
        ["twist"],
        None,
        1,
        1,
        r"^candidates \['twist'\]: these data cannot see twist",
        r"^--candidates twist: these data cannot see twist",
    ),
    (
        ["shear"],
        None,
        1,
        1,
        r"every candidate is already in the baseline \(baseline \[",
        r"every candidate is already in the baseline \(--terms fibre_stretch,shear\)",
    ),
    (
        None,
        ["shear_locking"],
        1,
        1,
        r"^fixed \['shear_locking'\]: 'shear_locking' is not a "
        "baseline term",
        r"^--fixed shear_locking: 'shear_locking' is not a baseline term",
    ),
    (
        None,
        ["fibre_stretch"],
        1,
        1,
        r"fibre_stretch.k_l, fibre_stretch.k_m is not given in "
        r"params",
        r"is not given in --params p.json",
    ),
    (None, ["shear", "shear"], 1, 1, r"'shear' is given twice", r"'shear' is given twice"),
]


@pytest.mark.parametrize("case", CASES, ids=[c[4][:30] for c in CASES])
def test_library_and_command_line_refuse_alike(case):
    cands, fixed, confirm, max_effects, lib, cli = case
    with pytest.raises(InputError, match=lib):
        check_choices(
            BASE,
            cands,
            fixed,
            PARAMS,
            PLANAR,
            confirm,
            max_effects,
            library_labels(BASE, cands, fixed),
        )
    spell = ",".join
    labels = Labels(
        f"--candidates {spell(cands or [])}",
        f"--fixed {spell(fixed or [])}",
        "--terms fibre_stretch,shear",
        "--params",
        "in --params p.json",
        "--confirm",
        "--max-effects",
    )
    with pytest.raises(InputError, match=cli):
        check_choices(BASE, cands, fixed, PARAMS, PLANAR, confirm, max_effects, labels)


def test_diagnose_refuses_before_building(monkeypatch):
    """``diagnose`` with a fixed term whose moduli are not given (before: the term's default
    moduli were used silently) raises before any forward model is built."""
    built = []
    monkeypatch.setattr(dg, "ForwardSet", lambda *a, **k: built.append(a))
    exp = template(40.0, 20.0, [1.0, 2.0], [[10.0, 10.0]])
    with pytest.raises(InputError, match=r"fixed \['fibre_stretch'\]: a fixed term is held"):
        dg.diagnose(exp, BASE, fixed=["fibre_stretch"], params=PARAMS)
    with pytest.raises(ValueError, match=r"candidates \['normal_bending'\]: these data cannot"):
        dg.diagnose(exp, BASE, candidates=["normal_bending"])
    assert not built
