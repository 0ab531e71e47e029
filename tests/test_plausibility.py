"""Moduli no fabric has (docs/diagnosis.md): a fitted yarn modulus that lets the yarns carry
the shear the data impose is reported with the effect it stands in for and what to do; yarns
as stiff as a fabric's are not; a range the user states is kept.

The real case is the shipped Cao et al. 2008 curve (115 × 230 mm, ±45°, force only), fitted
with fibre_stretch + shear from the moduli that fit reaches at the diagnosis's mesh (k_l ≈ 137,
k_s ≈ 0.026 N/mm; the full diagnosis then lowers k_l to about 75 N/mm with shear_locking and
crossover_friction): its model shears the fabric by about 70° where the grip displacement
imposes 84° on yarns that do not stretch. Every 6th step of the curve (and the last) keeps the
runs short; the rule looks at the last step, which is kept.
"""

import logging
from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI

from fabricsurf.datasets import cao2008_plain_weave
from fabricsurf.errors import InputError
from fabricsurf.experiments.three_zone import zone_c_shear_angle
from fabricsurf.inverse.contract.data import load_experiment
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.plausibility import (
    CORRELATION,
    DEFICIT,
    check_moduli,
    implied_strains,
    kinematic_shear_deg,
    parse_plausible,
    stands_in_for,
)
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.terms import FibreStretch, GeodesicBending, Shear


def test_parse_plausible():
    got = parse_plausible("fibre_stretch.k_l=1000:1e5, shear.k_s=0.01:1")
    assert got == {"fibre_stretch.k_l": (1000.0, 1e5), "shear.k_s": (0.01, 1.0)}
    assert parse_plausible({"shear.k_s": (0.1, 2)}) == {"shear.k_s": (0.1, 2.0)}
    for bad in ("fibre_stretch.k_l=1000", "fibre_stretch.k_q=1:2", "shear.k_s=2:1", "x=a:b"):
        with pytest.raises(InputError, match="--plausible"):
            parse_plausible(bad)


def test_kinematic_shear_angle():
    """Cao et al. 2008 eq. 13 at ±45° (experiments/three_zone.py), and its ±θ form: at ±40°
    the net locks at d = (L − W/tan 40°)(1/cos 40° − 1) (docs/diagnosis.md), beyond which no
    angle is claimed."""
    exp = sy.template(230.0, 115.0, [10.0, 30.0], np.zeros((0, 2)))
    want = np.degrees(zone_c_shear_angle(30.0, 230.0, 115.0))
    assert kinematic_shear_deg(exp) == pytest.approx(float(want))
    D = 187.0 - 119.0 / np.tan(np.radians(40.0))
    lock = D * (1.0 / np.cos(np.radians(40.0)) - 1.0)
    at = sy.template(187.0, 119.0, [0.999 * lock], np.zeros((0, 2)), angles=(40.0, -40.0))
    assert 70.0 < kinematic_shear_deg(at) <= 80.0  # 2θ at the lock
    beyond = sy.template(187.0, 119.0, [1.01 * lock], np.zeros((0, 2)), angles=(40.0, -40.0))
    assert kinematic_shear_deg(beyond) is None


@pytest.fixture(scope="module")
def cao():
    exp = load_experiment(cao2008_plain_weave())
    keep = np.r_[np.arange(0, len(exp.steps) - 1, 6), len(exp.steps) - 1]
    return replace(exp, steps=exp.steps[keep], path=exp.path[keep], force=exp.force[keep])


def cao_fit(exp):
    fs = ForwardSet([exp], [FibreStretch(k_l=137.0, k_m=137.0), Shear(k_s=0.0256)], h=23.0)
    return fs, fit(fs, space="linear", scale_start=False, max_iter=3)


def test_cao_fit_warns(cao, caplog):
    """The fit keeps the yarns soft (< 300 N/mm: real glass yarns 10³–10⁵); the outcome names
    the rule with its numbers, shear as what the yarns stand in for (the other fitted term),
    the real options to act on it, and it is said once, as a warning, on rank 0 only."""
    fs, res = cao_fit(cao)
    with fs:
        assert res.params()["fibre_stretch"]["k_l"] < 300.0
        with caplog.at_level(logging.WARNING, logger="fabricsurf"):
            found = check_moduli(fs, res)
            again = check_moduli(fs, res)
        strains = implied_strains(fs, res.values)
    assert len(found) == 1  # one entry for the yarns, both families' moduli
    q = found[0]
    assert list(q["moduli"]) == ["fibre_stretch.k_l", "fibre_stretch.k_m"]
    assert q["rule"] == "shear deficit" and q["deficit"] > DEFICIT
    assert q["data_shear_deg"] == pytest.approx(84.1, abs=0.1)
    assert q["stands_in_for"] == "shear"
    text = q["text"]
    assert "--fixed fibre_stretch" in text and "inextensible=True" in text
    assert "--beyond-features" in text
    said = [r for r in caplog.records if "implausible modulus" in r.getMessage()]
    assert len(said) == (1 if MPI.COMM_WORLD.rank == 0 else 0)  # once, though checked twice
    assert [x["text"] for x in again] == [x["text"] for x in found]
    res.implausible = found
    assert res.as_dict()["implausible_moduli"][0]["modulus"] == "fibre_stretch.k_l"
    # every number the rule uses is the same on every rank (reduced over them)
    flat = [strains[0][k] for k in ("max_strain_l", "max_shear_deg")]
    assert MPI.COMM_WORLD.allgather(flat) == [flat] * MPI.COMM_WORLD.size


def test_user_range(cao):
    """A stated range is kept: the fitted k_s outside [1, 10] N/mm is reported (standing in
    for the yarns, its only partner); inside it, not; the yarn modulus, already reported by
    its rule, is not reported twice."""
    fs, res = cao_fit(cao)
    with fs:
        found = check_moduli(fs, res, "shear.k_s=1:10,fibre_stretch.k_l=1000:1e5")
        inside = check_moduli(fs, res, {"shear.k_s": (0.001, 1.0)})
    names = [list(q["moduli"]) for q in found]
    assert names == [["fibre_stretch.k_l", "fibre_stretch.k_m"], ["shear.k_s"]]
    ks = found[-1]
    assert ks["rule"] == "stated range" and ks["range"] == [1.0, 10.0]
    assert ks["stands_in_for"] == "fibre_stretch"
    assert "shear.k_s" not in [q["modulus"] for q in inside]


def test_fit_checks_when_asked(cao):
    """``fit(..., plausible=…)`` runs the same check as the command line (into
    ``implausible``); a bad range is refused before any solve; by default nothing is checked
    (the diagnosis's inner fits)."""
    with ForwardSet([cao], [FibreStretch(k_l=137.0, k_m=137.0), Shear(k_s=0.0256)], h=23.0) as fs:
        with pytest.raises(InputError, match="--plausible"):
            fit(fs, plausible="shear.k_s=2:1")
        assert fs.forward_runs == 0
        kw = {"space": "linear", "scale_start": False, "max_iter": 3}
        res = fit(fs, plausible="shear.k_s=1:10", **kw)
        direct = check_moduli(fs, res, "shear.k_s=1:10")
        assert [q["text"] for q in res.implausible] == [q["text"] for q in direct]
        assert len(direct) == 2  # the yarns by their rule, k_s by the range
        assert fit(fs, **kw).implausible is None


def test_stiff_yarn_lattice_no_warning():
    """Hencky-lattice data of the suite's stiff-fibre regime (k_l = 1000, k_s = 0.4 N/mm,
    A_g = 10 N·mm; 48 × 24 mm, ±45°, 12 %), fitted with the lattice's continuum limit: the
    model shears the fabric by more than the inextensible net's zone-C angle (32.5°), so no
    yarn modulus is reported (though at the grips' corners its yarns stretch by ~2 %)."""
    L, W = 48.0, 24.0
    exp = sy.template(L, W, list(np.linspace(0.04 * L, 0.12 * L, 3)), np.zeros((0, 2)))
    sy.lattice_data(exp, 1.6, k_l=1000.0, k_s=0.4, A_g=10.0, every=4)
    exp = sy.add_noise(exp, 0.02, 0.02, 3)
    model = [FibreStretch(k_l=1000.0, k_m=1000.0), Shear(k_s=0.4), GeodesicBending(A_g=10.0)]
    with ForwardSet([exp], model, h=3.0) as fs:
        res = fit(fs, space="linear", scale_start=False, max_iter=3)
        assert check_moduli(fs, res) == []
        s = implied_strains(fs, res.values)[0]
    assert s["max_shear_deg"] > s["kinematic_shear_deg"]


def test_stretch_the_field_shows_is_not_reported():
    """Continuum data of yarns that do stretch (k_l = 30, k_s = 0.5 N/mm, A_g = 15 N·mm; the
    suite's synthetic fabric, as tests/test_diagnose.py makes it, at a smaller size), with a
    displacement field: the model shears the fabric more than 10 % short of the net's angle,
    but the field determines the yarns apart from the shear (correlation far below
    CORRELATION), so the stretch is the fabric's own and nothing is reported."""
    params = {
        "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
        "shear": {"k_s": 0.5},
        "geodesic_bending": {"A_g": 15.0},
    }
    exp = sy.template(48.0, 24.0, [1.2, 2.4, 3.6], sy.grid_points(48.0, 24.0, 8, 4))
    sy.continuum_data(exp, full_model(list(params), params), h=3.0)
    exp = sy.add_noise(exp, 0.01, 0.02, 11)
    model = [FibreStretch(k_l=30.0, k_m=30.0), Shear(k_s=0.5), GeodesicBending(A_g=15.0)]
    with ForwardSet([exp], model, h=3.0) as fs:
        res = fit(fs, space="linear", scale_start=False, max_iter=3)
        s = implied_strains(fs, res.values)[0]
        assert 1.0 - s["max_shear_deg"] / s["kinematic_shear_deg"] > DEFICIT
        assert abs(stands_in_for(res, "fibre_stretch.k_l")[1]) < CORRELATION
        assert check_moduli(fs, res) == []
