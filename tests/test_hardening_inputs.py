"""Hardening, fourth round (issue 52): inputs that used to be accepted and then failed late or
gave a wrong answer without a word.

* a modulus beyond any sheet (``k_l = 1e308``) failed 13 load-step cuts later: refused by
  ``--params`` (stiff yarns, K/k_s = 1e9, still pass);
* ``compare --params`` lacking a modulus of ``--terms`` compared it at the default 1.0: refused
  (without ``--params`` the defaults are said in a note);
* ``test = "tensile"`` was an alias of the bias test, which then refused a tensile test's 0/90
  fibres as "a tensile test of the yarns": the name is refused, saying what it means;
* a force-only ±45° fit reported k_m/k_l with a zero-width interval while naming the same
  direction undetermined: a combination along a null direction gets no interval;
* a displacement field all zero while the grip moved ended in "unexplained misfit": refused,
  naming the file and the steps (the loader and the Python ``diagnose``).

The rejected inputs (``CASES``) join docs/input_errors.md (benchmarks/regenerate_input_errors.py).
No FEniCSx solve except one small compare (the note of the defaults).
"""

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import test_hardening as th
from mpi4py import MPI

from fabricsurf.errors import DataError, InputError
from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.data import check_field_moves, load_experiment, write_experiment
from fabricsurf.inverse.fitting.fit import FitResult
from fabricsurf.inverse.fitting.optimum import undetermined
from fabricsurf.inverse.fitting.params import MAX_MODULUS, load_params
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.inverse.uncertainty import intervals
from fabricsurf.inverse.uncertainty import statistical as unc

COMM = MPI.COMM_WORLD
TERMS = th.TERMS


def zero_field(steps=None):
    """An edit of field.csv setting ux, uy to 0 at ``steps`` (None: every step)."""

    def edit(d: Path) -> None:
        rows = list(csv.reader((d / "field.csv").open()))
        body = [r[:3] + ["0", "0"] if steps is None or int(r[0]) in steps else r for r in rows[1:]]
        (d / "field.csv").write_text("\n".join(",".join(r) for r in [rows[0], *body]) + "\n")

    return edit


SAVED_FIT = {
    "terms": ["fibre_stretch", "shear"],
    "params": {"fibre_stretch": {"k_l": 30.0, "k_m": 30.0}, "shear": {"k_s": 0.5}},
    "std": {"fibre_stretch.k_l": 1.0, "fibre_stretch.k_m": 1.0, "shear.k_s": 0.01},
}

CASES = [
    dict(
        id="params-modulus-huge",
        klass="`--params` with a modulus beyond any sheet (`k_l = 1e308`)",
        make=th.params_file(
            "kl_1e308.json", {"fibre_stretch": {"k_l": 1e308, "k_m": 1.0}, "shear": {"k_s": 1.0}}
        ),
        argv=th.cmp("good", "--params", "kl_1e308.json"),
        pattern=r"--params kl_1e308.json: fibre_stretch.k_l = 1e\+308 N/mm is beyond any "
        r"sheet \(at most 1e\+12 N/mm.*check the value and its unit",
    ),
    dict(
        id="compare-params-incomplete",
        klass="`compare --params` lacking moduli of `--terms`",
        make=th.params_file("shear_only.json", {"shear": {"k_s": 0.8}}),
        argv=th.cmp("good", "--params", "shear_only.json"),
        pattern=r"--params shear_only.json: gives no value for fibre_stretch.k_l, "
        r"fibre_stretch.k_m of --terms fibre_stretch,shear, so compare would use the defaults "
        r"\(fibre_stretch.k_l = 1 N/mm, fibre_stretch.k_m = 1 N/mm\), nobody's estimate; add "
        r"them to shear_only.json, or drop the term from --terms",
    ),
    dict(
        id="compare-fit-lacks-term",
        klass="`compare --params fit.json` lacking a term of `--terms`",
        make=th.params_file("fit_no_Ag.json", SAVED_FIT),
        argv=[
            "compare",
            "good",
            "--terms",
            TERMS + ",geodesic_bending",
            "--params",
            "fit_no_Ag.json",
            "--out",
            "out",
        ],
        pattern=r"--params fit_no_Ag.json: gives no value for geodesic_bending.A_g .*default "
        r"\(geodesic_bending.A_g = 1 N·mm\).*leave --terms out to compare the fit's own model",
    ),
    dict(
        id="test-tensile",
        klass='`[loading] test = "tensile"` (fibres at 0/90°)',
        make=th.variant(
            "tensile_0_90",
            th.edits(
                th.replace("experiment.toml", 'test = "bias_extension"', 'test = "tensile"'),
                th.replace("experiment.toml", "[45.0, -45.0]", "[0.0, 90.0]"),
            ),
        ),
        argv=th.cmp("tensile_0_90"),
        pattern=r"experiment.toml: \[loading\] test = 'tensile': a tensile test \(the yarns "
        r"pulled along the load, fibres at 0/90 deg\) is not modelled.*write test = "
        r"\"bias_extension\"",
    ),
    dict(
        id="field-still",
        klass="field.csv all zero while the grip moves",
        make=th.variant("field_still", zero_field()),
        argv=["diagnose", "field_still", "--terms", TERMS, "--out", "out"],
        pattern=r"field.csv: every displacement of steps 1, 2 \(all its steps\) is 0 while the "
        r"grip displacement \(mm\) is 0.8, 1.6: nothing moved in the data",
    ),
    dict(
        id="field-still-step",
        klass="field.csv all zero at one step while the grip moves",
        make=th.variant("field_still_2", zero_field({2})),
        argv=th.cmp("field_still_2"),
        pattern=r"field.csv: every displacement of step 2 is 0 while the grip displacement "
        r"\(mm\) is 1.6",
    ),
    dict(
        id="force-negative",
        klass="force.csv of a bias test with negative (compressive) forces",
        make=th.variant(
            "force_negative",
            th.replace("force.csv", "1,0.8,0.0\r\n2,1.6,0.0", "1,0.8,-2.0\r\n2,1.6,-4.5"),
        ),
        argv=th.cmp("force_negative"),
        pattern=r"force.csv: step 1 \(numbered 1\): force -2 N is negative \(2 of 2 steps "
        r"are\); the 'bias_extension' test pulls the specimen.*flip the sign",
    ),
]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return th.shared_root(tmp_path_factory, "hard4", CASES)


@pytest.fixture
def in_root(root, monkeypatch):
    monkeypatch.chdir(root)
    return root


@pytest.mark.parametrize("case", CASES, ids=[c["id"] for c in CASES])
def test_rejected_before_any_solve(case, in_root, capsys, monkeypatch):
    """Each input: exit 2 on every rank, one message naming the file, key and value, nothing
    built or written."""
    msg = th.rejected_message(case, in_root, capsys, monkeypatch)
    assert len(msg.splitlines()) == 1, msg


# -- 1. the range of a modulus -----------------------------------------------------------------
def test_stiff_yarns_pass_and_the_bound_is_per_unit(tmp_path):
    """K/k_s = 1e9 at k_s = 1 N/mm (a near-inextensible penalty in use) and the bound itself
    pass; just above it, a second-gradient modulus is refused in its own unit."""
    p = tmp_path / f"stiff{COMM.rank}.json"
    ok = {"fibre_stretch": {"k_l": 1e10, "k_m": MAX_MODULUS}, "shear": {"k_s": 1.0}}
    p.write_text(json.dumps(ok))
    assert load_params(p) == ok
    p.write_text(json.dumps({"geodesic_bending": {"A_g": 2 * MAX_MODULUS}}))
    with pytest.raises(
        InputError,
        match=r"geodesic_bending.A_g = 2e\+12 N·mm is beyond any "
        r"sheet \(at most 1e\+12 N·mm",
    ):
        load_params(p)


# -- 2. compare's moduli: all given, or the defaults said ----------------------------------------
def test_compare_without_params_says_the_defaults(in_root, capsys):
    """No --params: the defaults are the model compared, and a note (rank 0, once) says which;
    a complete --params file runs without a note."""
    rc, msg = th.run_cli(th.cmp("good", "--h", "10", "--out", "defaults"), capsys)
    assert rc == 0, msg
    assert (
        "note: no --params given: every modulus takes its default (fibre_stretch.k_l = 1 "
        "N/mm, fibre_stretch.k_m = 1 N/mm, shear.k_s = 1 N/mm)"
    ) in msg
    if COMM.rank == 0:
        (in_root / "complete.json").write_text(json.dumps(SAVED_FIT))
    COMM.barrier()
    rc, msg = th.run_cli(
        th.cmp("good", "--h", "10", "--params", "complete.json", "--no-band", "--out", "given"),
        capsys,
    )
    assert rc == 0 and "note: no --params" not in msg, msg
    used = json.loads((in_root / "given" / "misfit.json").read_text())["provenance"]["params"]
    assert used == SAVED_FIT["params"]


def test_bias_with_a_partial_params_file_names_the_defaults(in_root, capsys):
    """``bias`` solves the model it is given (the terms' defaults are documented), but a
    --params file that gives only some moduli says which took their defaults."""
    if COMM.rank == 0:
        (in_root / "partial.json").write_text(json.dumps({"shear": {"k_s": 0.8}}))
    COMM.barrier()
    rc, msg = th.run_cli(
        [
            "bias",
            "--length",
            "40",
            "--width",
            "20",
            "--h",
            "10",
            "--steps",
            "1",
            "--ubar",
            "1",
            "--terms",
            TERMS,
            "--params",
            "partial.json",
            "--out",
            "partial",
        ],
        capsys,
    )
    assert rc == 0, msg
    assert (
        "note: --params partial.json gives no value for fibre_stretch.k_l = 1 N/mm, "
        "fibre_stretch.k_m = 1 N/mm: the term's default is used"
    ) in msg


# -- 3. "tensile" ------------------------------------------------------------------------------
def test_tensile_is_refused_whatever_the_angles():
    """Not an alias any more (with ±45° fibres it was a bias test under another name): the
    name itself is refused, saying what to write instead."""
    with pytest.raises(
        DataError,
        match=r"test = 'tensile': a tensile test .* write test = "
        r"\"bias_extension\"",
    ):
        get_test("tensile")
    assert get_test("bias_extension").name == "bias_extension"


# -- 4. no interval along an undetermined direction ---------------------------------------------
def symmetric_fit(leak: float) -> FitResult:
    """A force-only ±45° fit in miniature: k_l and k_m enter only through their sum (equal
    sensitivity columns), a third modulus c is determined. The covariance carries, along the
    null direction k_l − k_m, a variance ``leak`` times that of the sum: the round-off the
    other moduli's entries leave in the pseudo-inverse's zero."""
    rng = np.random.default_rng(3)
    a, c = rng.normal(size=40), rng.normal(size=40)
    vals = np.array([25.0, 25.0, 0.4])
    J = np.column_stack([a / vals[0], a / vals[1], c / vals[2]])  # dr/dp: dr/dlog p = a, a, c
    s = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)  # the determined sum, in log-moduli
    n = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)  # the null direction
    C_log = 1e-3 * np.outer(s, s) + 1e-3 * leak * np.outer(n, n) + np.diag([0, 0, 1e-4])
    cov = C_log * np.outer(vals, vals)
    stat = unc.Statistical(cov, cov, 20, 17, 1.0, 40.0)
    names = ["fibre_stretch.k_l", "fibre_stretch.k_m", "shear.k_s"]
    std = np.sqrt(np.diag(cov))
    und = undetermined(names, J * vals)
    return FitResult(
        names,
        vals,
        std,
        40.0,
        {},
        None,
        1,
        1,
        undetermined=und,
        free=[0, 1, 2],
        J=J,
        r=rng.normal(size=40),
        statistical=stat,
    )


def test_no_interval_along_an_undetermined_direction():
    """The ratio k_l/k_m is named undetermined; it must not also come with a (near zero-width)
    interval, however much round-off sits in its variance; the sum's geometric mean keeps its
    interval."""
    res = symmetric_fit(leak=1e-9)
    u = res.as_dict()
    assert u["undetermined"] == ["0.71 log fibre_stretch.k_l - 0.71 log fibre_stretch.k_m"]
    (comb,) = u["identifiable_combinations"]
    assert np.allclose(list(comb["weights"].values()), 0.5), comb
    lo, hi = comb["ci95"]
    assert lo < 25.0 < hi and hi / lo > 1.01
    # the function itself: along the null direction nothing, without it the ratio appeared
    cov, t = res.statistical.cov, res.statistical.t95()
    null = intervals.null_directions(res.J * res.values)
    args = (res.names, res.values, cov, t, None, None, [0, 1])
    assert len(intervals.combinations(*args)) == 2  # the ratio too: the incoherent report
    assert len(intervals.combinations(*args, null)) == 1


def test_determined_directions_are_untouched():
    """Without a null direction (k_l, k_m distinguished), the combinations are those of the
    covariance as before."""
    J = np.random.default_rng(4).normal(size=(30, 2))
    assert intervals.null_directions(J).shape == (2, 0)
    p = np.array([30.0, 30.0])
    R = np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2)
    cov = R @ np.diag([2.0, 5e3]) @ R.T
    a = intervals.combinations(["a", "b"], p, cov, 2.0, None, None, [0, 1])
    b = intervals.combinations(
        ["a", "b"], p, cov, 2.0, None, None, [0, 1], intervals.null_directions(J)
    )
    assert a == b and len(a) == 1


# -- 5. a field that did not move --------------------------------------------------------------
def test_still_field_refused_by_the_python_diagnose(monkeypatch):
    """The Python API refuses it too, before any forward model; a step whose load is 0 may
    show no displacement."""
    import fabricsurf.inverse.diagnosis.diagnose as dg

    built = []
    monkeypatch.setattr(dg, "ForwardSet", lambda *a, **k: built.append(a))
    exp = sy.template(40.0, 20.0, [0.8, 1.6], sy.grid_points(40.0, 20.0, 4, 2))
    exp.noise_std = 0.01
    with pytest.raises(
        DataError,
        match=r"the field of experiment 'synthetic': every "
        r"displacement of steps 1, 2 \(all its steps\) is 0",
    ):
        dg.diagnose(exp, ["fibre_stretch", "shear"])
    assert not built
    exp.path = np.array([0.0, 1.6])
    exp.u[exp.step_rows(2)] = 0.01
    check_field_moves(exp, "field.csv")  # at rest at a zero load, moved at the other: fine


def test_loader_refuses_still_field_with_its_noise(tmp_path):
    """Before: with [data] noise_std given, an all-zero field loaded and was fitted."""
    d = tmp_path / f"still{COMM.rank}"
    exp = th.good_experiment()
    exp.u = np.zeros_like(exp.u)
    write_experiment(d, exp)
    with pytest.raises(DataError, match=r"field.csv: every displacement of steps 1, 2"):
        load_experiment(d)
