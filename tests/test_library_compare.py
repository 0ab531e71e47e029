"""``compare()`` in Python is ``fabricsurf compare`` without the output directory: it refuses
what the command line refuses, before any forward solve, with the same message substance (the
options' names replaced by the arguments': ``--terms a,b`` → ``terms ['a', 'b']``,
``--params FILE`` → ``params``, ``--h X`` → ``h = X``), takes the signed moduli that fit
refuses, and its numbers (misfit, per-step errors, bands) are the command line's; a tie's
separating experiment is returned, not written into the diagnosis; the DIC import writes the
contract with the contract's own writer, so import → load gives back the very arrays.
"""

import json
import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from mpi4py import MPI
from test_hardening import good_experiment, params_file, run_cli, shared_root, variant

import fabricsurf
import fabricsurf.inverse.forward.runs as runs
from fabricsurf.cli import main
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.data import load_experiment, write_experiment
from fabricsurf.inverse.fitting.compare import Comparison, compare, compare_preconditions
from fabricsurf.inverse.fitting.preconditions import fit_preconditions, positive_start
from fabricsurf.model.terms import Term, make_term

COMM = MPI.COMM_WORLD
TERMS = "fibre_stretch,shear"
GIVEN = {"fibre_stretch": {"k_l": 30.0, "k_m": 30.0}, "shear": {"k_s": 0.5}}
NAMES = ["fibre_stretch.k_l", "fibre_stretch.k_m", "shear.k_s"]
SAVED = {
    "terms": TERMS.split(","),
    "params": GIVEN,  # a saved fit with its covariance
    "uncertainty": {
        "covariance": {"names": NAMES, "statistical": np.diag([1.0, 1.0, 1e-4]).tolist()},
        "statistics": {"t95": 2.0},
    },
    "moduli": {n: {"systematic_model": 0.0, "mesh_shift_h_to_h2": 0.0} for n in NAMES},
}


def cantilever(base: Path) -> None:
    """A 3D cantilever field (uz measured, nothing solved) called ``cantilever``."""
    from fabricsurf.inverse.synthetic import generate as sy

    exp = sy.template(
        30.0,
        10.0,
        [0.5, 1.0],
        sy.grid_points(30.0, 10.0, 4, 2),
        test="cantilever",
        options={"areal_density_g_m2": 200.0},
        force=False,
    )
    x = exp.X[:, 0] / 30.0
    exp.u = np.column_stack([0.0 * x, 0.0 * x, -2.0 * x**2 * exp.field_step])
    exp.noise_std = 0.01
    write_experiment(base / "cantilever", exp)


MAKE = [
    variant("twin", lambda d: None),
    cantilever,
    params_file("given.json", GIVEN),
    params_file("saved.json", SAVED),
    params_file("shear_only.json", {"shear": {"k_s": 0.8}}),
    params_file("huge.json", {"fibre_stretch": {"k_l": 1e308, "k_m": 1.0}, "shear": {"k_s": 1.0}}),
]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return shared_root(tmp_path_factory, "libcompare", [dict(make=m) for m in MAKE])


def terms(spec: str, params: dict | None = None) -> list:
    return [make_term(n, **(params or {}).get(n, {})) for n in spec.split(",")]


# id; DATA; --terms; extra options; the library's call (data, terms, keyword arguments);
# the substance both messages hold (a pattern); whether the library's message is the command
# line's with the names replaced (``neutral``) word for word
CASES = [
    (
        "planar-out-of-plane",
        ["good"],
        TERMS + ",twist",
        [],
        {},
        r"twist is an out-of-plane effect, and experiment 'synthetic' \(test 'bias_extension'\) "
        r"is planar",
        True,
    ),
    (
        "bending-test-without-bending",
        ["cantilever"],
        TERMS,
        ["--params", "given.json"],
        {},
        r"experiment 'synthetic' is a cantilever, and no term has a second gradient, so the sheet "
        r"would have no bending stiffness",
        True,
    ),
    (
        "h-too-large",
        ["good"],
        TERMS,
        ["--h", "1e5"],
        {"h": 1e5},
        r"100000: must be a positive element size in mm, at most 10 \(two elements across the "
        r"narrowest specimen\)",
        True,
    ),
    (
        "h-zero",
        ["good"],
        TERMS,
        ["--h", "0"],
        {"h": 0.0},
        r"0: must be a positive element size in mm",
        False,
    ),
    (
        "params-incomplete",
        ["good"],
        TERMS,
        ["--params", "shear_only.json"],
        {"params": {"shear": {"k_s": 0.8}}},
        r"gives no value for fibre_stretch.k_l, fibre_stretch.k_m of .*, so compare would use the "
        r"defaults \(fibre_stretch.k_l = 1 N/mm, fibre_stretch.k_m = 1 N/mm\), nobody's estimate",
        False,
    ),
    (
        "modulus-huge",
        ["good"],
        TERMS,
        ["--params", "huge.json"],
        {"model": GIVEN | {"fibre_stretch": {"k_l": 1e308, "k_m": 1.0}}},
        r"fibre_stretch.k_l = 1e\+308 N/mm is beyond any sheet \(at most 1e\+12 N/mm",
        False,
    ),
    (
        "modulus-huge-params",
        ["good"],
        TERMS,
        ["--params", "huge.json"],
        {
            "model": {},
            "params": {"fibre_stretch": {"k_l": 1e308, "k_m": 1.0}, "shear": {"k_s": 1.0}},
        },
        r"fibre_stretch.k_l = 1e\+308 N/mm is beyond any sheet \(at most 1e\+12 N/mm",
        True,
    ),
    (
        "names-twice",
        ["good", "twin"],
        TERMS,
        [],
        {},
        r"experiments must have distinct names \(.*\), got \['synthetic', 'synthetic'\]",
        False,
    ),
    ("term-twice", ["good"], "shear,shear", [], {}, r"'shear' is given twice", False),
]


def neutral(msg: str, spec: str, options: list[str]) -> str:
    """The command line's message with the library's names for the inputs."""
    msg = msg.replace(f"--terms {spec}", f"terms {spec.split(',')}")
    msg = msg.replace("from --terms", "from the terms")
    if "--h" in options:
        h = options[options.index("--h") + 1]
        msg = msg.replace(f"--h {float(h):g}", f"h = {float(h):g}")
    if "--params" in options:
        msg = msg.replace(f"--params {options[options.index('--params') + 1]}", "params")
    return msg


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_compare_refuses_like_the_cli(case, root, capsys, monkeypatch):
    """Each refusal: exit 2 from the command line, an InputError from ``compare()``, both
    before any forward model is built, with the same substance."""
    _, data, spec, options, call, pattern, word_for_word = case
    call = dict(call)
    moduli = call.pop("model", GIVEN)
    built = []
    monkeypatch.setattr(runs, "ForwardSet", lambda *a, **k: built.append(a))
    monkeypatch.chdir(root)
    rc, msg = run_cli(["compare", *data, "--terms", spec, "--out", "out", *options], capsys)
    assert rc == 2, msg
    cli = msg.splitlines()[-1].split("error: ", 1)[1]
    exps = [load_experiment(d) for d in data]
    with pytest.raises(InputError) as err:
        compare(exps, terms(spec, moduli), **call)
    lib = str(err.value)
    assert not built and not (root / "out").exists()
    for text in (cli, lib):
        assert re.search(pattern, text), (pattern, text)
    if word_for_word:
        assert lib == neutral(cli, spec, options), (lib, cli)


def test_compare_and_fit_take_signed_moduli_diagnose_refuses():
    """A coupling whose modulus may be negative (a user's effect with ``signed``) at a
    negative value: compare's and fit's checks pass (a fit steps it linearly), the
    diagnosis's refuse it; a band needs a covariance."""

    @dataclass
    class Coupling(Term):
        """½k_c γ² (λ − 1)."""

        k_c: float = 1.0
        name: ClassVar[str] = "coupling_compare_test"
        units: ClassVar[dict[str, str]] = {"k_c": "N/mm"}
        signed: ClassVar[tuple[str, ...]] = ("k_c",)

    exp = good_experiment()
    model = terms(TERMS, GIVEN) + [Coupling(k_c=-2.0)]
    assert compare_preconditions([exp], model) == ()
    fit_preconditions([exp], model)
    with pytest.raises(InputError, match=r"coupling_compare_test.k_c may be negative"):
        positive_start(model, command="diagnose")
    with pytest.raises(InputError, match=r"band: the saved fit has no covariance"):
        compare_preconditions([exp], model, band={"params": GIVEN})
    with pytest.raises(
        InputError,
        match=r"band: the saved fit's moduli \['twist.k_t'\] are "
        r"not in the model",
    ):
        compare_preconditions(
            [exp],
            terms(TERMS),
            band=SAVED
            | {"uncertainty": {"covariance": {"names": ["twist.k_t"], "statistical": [[1.0]]}}},
        )


def test_compare_numbers_are_the_clis(root, capsys):
    """``compare()`` at a saved fit's moduli with its band: the misfit (every per-step entry),
    the meshes and the band the command line writes, to the last digit."""
    rc, msg = run_cli(
        [
            "compare",
            str(root / "good"),
            "--params",
            str(root / "saved.json"),
            "--h",
            "10",
            "--out",
            str(root / "cmp"),
        ],
        capsys,
    )
    assert rc == 0, msg
    written = json.loads((root / "cmp" / "misfit.json").read_text())
    given = terms(TERMS)
    before = [t.values() for t in given]
    res = compare(
        load_experiment(root / "good"),
        given,
        h=10.0,
        params=GIVEN,
        band=root / "saved.json",
        comm=COMM,
    )
    assert isinstance(res, Comparison) and res.label == "fibre_stretch+shear"
    assert [t.values() for t in given] == before  # params set on copies
    ours = json.loads(json.dumps(res.as_dict()))
    for key in ("combined", "chi2", "n", "experiments", "model"):
        assert ours[key] == written[key], key
    assert ours["force_bands"] == written["force_bands"]
    assert written["provenance"]["h_mm"] == res.h == [10.0]
    assert written["provenance"]["discretisation"] == json.loads(json.dumps(res.discretisation))
    band = np.loadtxt(root / "cmp" / "force_band.csv", delimiter=",", skiprows=1)
    mine = res.bands["synthetic"]
    np.testing.assert_allclose(
        band[:, 1:], np.column_stack([mine["force"], mine["lower"], mine["upper"]]), rtol=1e-5
    )  # the CSV's %.6g
    assert len(res.predictions) == 1 and res.predictions[0].force.shape == (2,)
    # the same through the curated root, the model's own moduli (no params)
    again = fabricsurf.compare([load_experiment(root / "good")], terms(TERMS, GIVEN), h=10.0)
    assert again.misfit["combined"] == res.misfit["combined"] and again.bands is None
    assert "compare" in fabricsurf.__all__ and "Comparison" in fabricsurf.__all__


def test_separate_tie_returns_a_copy(monkeypatch):
    """``separate_tie`` leaves the diagnosis as it was: no tie, (d, None); a tie, a copy that
    holds the design's dict, and the design (its maps for the figure)."""
    from types import SimpleNamespace

    from fabricsurf.inverse.diagnosis import discrimination as dc
    from fabricsurf.inverse.diagnosis.report import Diagnosis

    d = Diagnosis(
        baseline=["shear"],
        base_fit=None,
        final_fit=None,
        terms=["shear"],
        ranking=[],
        rounds=[],
        verdict=None,
        adequate=True,
        path=[],
        not_identifiable=[],
        discretisation_chi2=None,
        unexplained=None,
        fit_seconds=0.0,
        noise_known=True,
    )
    assert dc.separate_tie(d, []) == (d, None)
    tie = SimpleNamespace(tied=True, members=["a", "b"], refits={"a": "ra", "b": "rb"})
    d.tie = tie
    calls = []

    def design(exps, ra, rb, effects, h=None, comm=None):
        calls.append((ra, rb, effects, h))
        return dc.Design(effects, {"separation": 1.0}, [], [])

    monkeypatch.setattr(dc, "design", design)
    new, des = dc.separate_tie(d, ["exp"], h=3.0)
    assert calls == [("ra", "rb", ["a", "b"], 3.0)] and des.effects == ["a", "b"]
    assert new.separating_experiment == des.as_dict() and new is not d
    assert d.separating_experiment is None and new.tie is d.tie


def test_dic_import_round_trip_is_exact(tmp_path):
    """``import-dic`` writes with the contract's writer (full precision): loading the written
    directory gives back the imported experiment's very arrays, noise and force included."""
    from test_dic import grid, make, shared

    from fabricsurf.inverse.dic.description.spec import read_spec
    from fabricsurf.inverse.dic.importer import import_dic

    base = shared(tmp_path)
    if COMM.rank == 0:
        spec, _ = make(base, "dice", points=grid(spacing=4.0), noise=0.013)
        spec.write_text(spec.read_text().replace("[steps]", "[steps]\nforce = [1.1, 2.3, 2.9]"))
    COMM.barrier()
    out = base / "measured"
    assert main(["import-dic", str(base / "dic.toml"), "--out", str(out)]) == 0
    back = load_experiment(out)
    ref, _ = import_dic(read_spec(base / "dic.toml"))
    for key in ("steps", "path", "force", "field_step", "X", "u"):
        a, b = np.asarray(getattr(back, key)), np.asarray(getattr(ref, key))
        assert a.shape == b.shape and np.array_equal(a, b), key
    assert back.noise_std == ref.noise_std and back.force_noise_std == ref.force_noise_std
    assert (back.name, back.length, back.width) == (ref.name, ref.length, ref.width)
    assert list(back.fibre_angles_deg) == list(ref.fibre_angles_deg)
    COMM.barrier()
    if COMM.rank == 0:
        shutil.rmtree(out)
