"""The diagnosis in the regime of real fabrics (as the stiff-fibre table of docs/diagnosis.md:
nearly inextensible fibres, k_l/k_s = 2500, large shear, grips holding node columns, model-form
error above the noise), on Hencky-lattice data of our own generator at a small size:

* the complete model (fibre_stretch + shear + geodesic_bending, the lattice's continuum limit)
  gives no verdict — the lattice–continuum form error (several noise levels) is not taken for a
  missing effect; it is reported as unexplained misfit, because that is what it is;
* geodesic bending hidden from fibre_stretch + shear, fibres at ±40°, data written in m and kN:
  loaded, diagnosed and named (the misfit left is the form error of a 1.6 mm lattice, which
  the tool then reports as not adequate);
* shear hidden from fibre_stretch + geodesic_bending: shear or, honestly, unexplained misfit
  with shear as the best lead (the test's docstring);
* geodesic bending hidden at ±45°, strong and weak, on a 1 mm lattice: named.
Criteria: the significance rule of docs/diagnosis.md; no tolerance is tuned here.
"""

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fabricsurf.inverse.contract.data import load_experiment, write_experiment
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import generate as sy

K_L, K_S = 1000.0, 0.4
LENGTH, WIDTH = 48.0, 24.0
SERIAL = pytest.mark.serial(
    "lattice data are diagnosed on 2 ranks by the hidden-effect demo "
    "(test_demos), and the diagnosis CLI by test_diagnose"
)


def lattice(angles, A_g, seed, spacing=1.6, noise=0.02):
    path = list(np.linspace(0.04 * LENGTH, 0.12 * LENGTH, 3))
    exp = sy.template(LENGTH, WIDTH, path, np.zeros((0, 2)), angles=angles, name="regime")
    sy.lattice_data(exp, spacing, k_l=K_L, k_s=K_S, A_g=A_g, every=2)
    return sy.add_noise(exp, noise, 0.02, seed)


@SERIAL
def test_complete_model_no_false_alarm_in_the_stiff_regime():
    exp = lattice((45.0, -45.0), A_g=K_S * 25.0, seed=3)
    d = diagnose(
        exp,
        ["fibre_stretch", "shear", "geodesic_bending"],
        h=3.0,
        confirm=1,
        max_effects=1,
        check_discretisation=False,
    )
    print(
        d.outcome(),
        d.base_fit.misfit["combined"],
        [(r["effect"], r["refit_misfit"], r["significant"]) for r in d.ranking],
    )
    assert d.verdict is None
    assert d.outcome() in ("nothing missing", "unexplained misfit")
    if not d.adequate:  # the best lead is the refit that came closest, and it failed the rule
        lead = d.unexplained["best_lead"]
        assert lead["effect"] == d.ranking[0]["effect"]
        assert lead["wald_p"] >= lead["wald_p_needed"] or not lead["f_test_passed"]


@SERIAL
def test_hidden_geodesic_bending_at_40_degrees_in_m_and_kn(tmp_path):
    comm = MPI.COMM_WORLD
    exp = lattice((40.0, -40.0), A_g=K_S * 100.0, seed=4)
    root = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    if comm.rank == 0:
        write_experiment(root / "data", exp)
        sy.rewrite_in_m_kn(root / "data")
    comm.barrier()
    loaded = load_experiment(root / "data")
    assert np.allclose(loaded.u, exp.u) and np.isclose(loaded.length, LENGTH)
    assert np.allclose(loaded.force, exp.force)
    d = diagnose(
        loaded,
        ["fibre_stretch", "shear"],
        h=3.0,
        confirm=1,
        max_effects=1,
        check_discretisation=False,
    )
    print(d.outcome(), d.path, [(r["effect"], r["refit_misfit"]) for r in d.ranking])
    assert d.verdict == "geodesic_bending" == d.ranking[0]["effect"]
    assert d.ranking[0]["significant"] and d.final_fit.chi2 < d.base_fit.chi2


@SERIAL
@pytest.mark.parametrize("l_b", [10.0, 5.0])
def test_hidden_geodesic_bending_strong_and_weak(l_b):
    """Geodesic bending hidden from fibre_stretch + shear at ±45° in the stiff regime, strong
    (l_b = 10 mm, A_g = 40 N·mm) and weak (l_b = 5 mm, A_g = 10 N·mm), on a 1 mm lattice:
    named in both. On the 1.6 mm lattice of the other tests the continuum at the lattice's own
    moduli misses by several noise levels and a fit of the complete model gets no lower than
    the baseline: there the bending is not identifiable and the tool says unexplained misfit
    (the misfits are in docs/verification.md, "Margins of the tests")."""
    exp = lattice((45.0, -45.0), A_g=K_S * l_b**2, seed=8, spacing=1.0)
    d = diagnose(
        exp, ["fibre_stretch", "shear"], h=3.0, confirm=1, max_effects=1, check_discretisation=False
    )
    print(
        l_b,
        d.outcome(),
        [round(p["misfit"], 3) for p in d.path],
        [(r["effect"], r["refit_misfit"], r["significant"]) for r in d.ranking],
    )
    assert d.verdict == "geodesic_bending" == d.ranking[0]["effect"]
    assert d.ranking[0]["significant"] and d.final_fit.chi2 < d.base_fit.chi2


@SERIAL
def test_hidden_shear_in_the_stiff_regime():
    """Shear hidden from fibre_stretch + geodesic_bending (the first row of the stiff-fibre
    table, at a small size): the baseline mimics the pivot stiffness with stiffer fibres and
    bending; the nested refit, stepping in the moduli, finds k_s (log-moduli steps crawl from
    zero, docs/diagnosis.md). At this size the shear's own signal is small against the 1.6 mm
    lattice's form error: when the refit's Wald test (on the correlated-residual model) does not
    pass, the tool reports unexplained misfit with shear as its best lead. It must never name
    another effect; on the full 187 × 119 mm specimen shear is named (docs/diagnosis.md)."""
    exp = lattice((45.0, -45.0), A_g=K_S * 25.0, seed=6)
    d = diagnose(
        exp,
        ["fibre_stretch", "geodesic_bending"],
        h=3.0,
        confirm=1,
        max_effects=1,
        check_discretisation=False,
    )
    row = d.ranking[0]
    print(d.outcome(), d.path, row["refit_params"], d.unexplained and d.unexplained["best_lead"])
    assert row["effect"] == "shear" and 0.5 * K_S < row["refit_params"]["k_s"] < 2.0 * K_S
    if d.verdict is None:
        lead = d.unexplained["best_lead"]
        assert d.outcome() == "unexplained misfit" and lead["effect"] == "shear"
        assert lead["wald_p"] >= lead["wald_p_needed"]
    else:
        assert d.verdict == "shear" and row["significant"]


def test_discretisation_credit_is_capped():
    """Adequacy with the h/2 check (docs/diagnosis.md): the discretisation error is credited only
    up to the tolerance band. Numbers of the full-size weak-geodesic run at h = 6 mm: χ²/ν = 4.41
    with χ²_h/ν = 25.6 — the mesh is too coarse, and the model must not be called adequate (the
    uncapped rule, (χ² − χ²_h)/ν < 0, did). A small credit still counts: χ²/ν = 1.30 with
    χ²_h/ν = 0.1 is adequate (1.20 ≤ 1.21), and not without it."""
    n, p = 20820, 5
    nu = n - p
    assert sg.adequacy_bound(n, p) == sg.ADEQUATE_MISFIT**2
    assert sg.too_coarse(25.6 * nu, n, p) and not sg.adequate(4.41 * nu, n, p, 25.6 * nu)
    assert not sg.too_coarse(0.1 * nu, n, p)
    assert sg.adequate(1.30 * nu, n, p, 0.1 * nu) and not sg.adequate(1.30 * nu, n, p)
