"""The search beyond the vocabulary against the mesh's own error
(fabricsurf/inverse/diagnosis/beyond/finer_mesh.py): a feature must stand on the h/2 check's
residuals too.

(a) The arithmetic on a linear toy: a residual that is noise plus an error along the feature's
sensitivity, which the finer mesh removes, gives a large reduction on the coarse residual and
only the noise's on the finer one; a true signal with a mesh error in another direction keeps
its reduction. (b) Data of our own continuum made at h = 0.75 mm (no lattice, nothing beyond
the vocabulary: fibre_stretch, shear and geodesic bending, A_g = 15 N·mm, whose fibre-bending
layer √(A_g/k_l) ≈ 0.7 mm no mesh of the diagnosis resolves), ±40° fibres on 48 × 20 mm, 12 × 6
points reaching the clamps and free edges, noise 0.005 mm, diagnosed at h = 3 mm: the crimp
interchange passes the corrected rule on the fit's mesh (the premise, asserted), and the finer
mesh's rule finds nothing, on 1 and 2 ranks alike. (c) The same data at 0.0025 mm: the feature
also stands on the h/2 residuals, but its evidence has not settled, so it is judged again one
mesh finer (fabricsurf/inverse/diagnosis/beyond/refine.py), where it falls.
"""

from dataclasses import replace

import numpy as np
import pytest

from fabricsurf.inverse.diagnosis.beyond import NOTHING, search_beyond
from fabricsurf.inverse.diagnosis.beyond.finer_mesh import (
    finer_reductions,
    settled,
    stands_on_finer_mesh,
)
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.terms import make_term


def toy(seed: int = 0, n: int = 400):
    """Two fitted moduli's sensitivities, a feature's (orthogonal to them), and unit noise."""
    rng = np.random.default_rng(seed)
    Jr = rng.standard_normal((n, 3))
    Q, _ = np.linalg.qr(Jr[:, :2])
    j = Jr[:, 2] - Q @ (Q.T @ Jr[:, 2])
    return Jr, j / np.linalg.norm(j), rng.standard_normal(n)


def test_error_along_the_feature_does_not_stand():
    """r = noise − 6ĵ: the coarse reduction is ≈ 36 + noise; d = +6ĵ removes it, leaving the
    noise's own (χ²₁, far below 36)."""
    Jr, jhat, noise = toy()
    vals, cand = np.ones(3), {"f": [2]}
    r, d = noise - 6.0 * jhat, 6.0 * jhat
    coarse = finer_reductions(r, np.zeros_like(r), Jr, vals, [0, 1], cand)["f"]
    finer = finer_reductions(r, d, Jr, vals, [0, 1], cand)["f"]
    assert coarse == pytest.approx((noise @ jhat - 6.0) ** 2)
    assert finer == pytest.approx((noise @ jhat) ** 2, abs=1e-9)
    row = {"score": coarse, "delta_chi2": coarse, "f_statistic": coarse, "f_needed": 16.0}
    out = stands_on_finer_mesh(row, finer)
    assert out["finer_mesh_delta_chi2"] == pytest.approx(finer)
    assert not out["stands_on_finer_mesh"]


def test_signal_with_an_error_elsewhere_stands():
    """r = noise − 6ĵ + e, e ⟂ ĵ with |e|² = 40 (more than the reduction): the finer residual
    r − e keeps the reduction exactly, and the scaled F passes."""
    Jr, jhat, noise = toy(1)
    e = np.random.default_rng(2).standard_normal(len(noise))
    e -= jhat * (jhat @ e)
    e *= np.sqrt(40.0) / np.linalg.norm(e)
    r = noise - 6.0 * jhat + e
    vals, cand = np.ones(3), {"f": [2]}
    coarse = finer_reductions(r, np.zeros_like(r), Jr, vals, [0, 1], cand)["f"]
    finer = finer_reductions(r, -e, Jr, vals, [0, 1], cand)["f"]
    assert finer == pytest.approx(coarse, rel=1e-6)
    row = {"score": coarse, "delta_chi2": 1.3 * coarse, "f_statistic": 1.2 * coarse}
    out = stands_on_finer_mesh(row | {"f_needed": 16.0}, finer)
    assert out["finer_mesh_delta_chi2"] == pytest.approx(1.3 * coarse, rel=1e-6)
    assert out["stands_on_finer_mesh"] == (1.2 * coarse > 16.0)


@pytest.fixture(scope="module")
def bending_clean():
    """The module docstring's (b) and (c), before the noise."""
    pts = sy.grid_points(48.0, 20.0, 12, 6, margin=0.01)
    exp = sy.template(48.0, 20.0, [1.2, 2.4, 3.6], pts, angles=(40.0, -40.0))
    model = [
        make_term("fibre_stretch", k_l=30.0, k_m=30.0),
        make_term("shear", k_s=0.5),
        make_term("geodesic_bending", A_g=15.0),
    ]
    sy.continuum_data(exp, model, h=0.75)
    return exp


def searched(clean, noise: float):
    """The data with ``noise`` (mm), diagnosed at h = 3 mm and searched, forced."""
    exp = sy.add_noise(replace(clean), noise, 0.02, 1000)
    d = diagnose(exp, ["fibre_stretch", "shear"], h=3.0, confirm=2, max_effects=1)
    assert d.terms[-1] == "geodesic_bending"
    return search_beyond(d, exp, force=True)


def test_the_mesh_error_is_not_a_missing_energy(bending_clean):
    rec = searched(bending_clean, 0.005)
    q = next(q for q in rec["rounds"][0] if q.get("refit_chi2") is not None)
    # the premise: on the fit's mesh the feature passes the corrected rule
    assert q["significant_on_this_mesh"], q
    assert q["delta_chi2"] > q["f_needed"]
    # on the h/2 check's residuals it is the mesh's: under the need, by a margin
    assert q["finer_mesh_f"] < 0.8 * q["f_needed"], q
    assert not rec["found"]
    assert rec["outcome"].startswith(NOTHING) and "discretisation error" in rec["outcome"]
    assert "at_finer_mesh" not in q  # settled by the h/2 residuals alone


def test_evidence_that_moved_is_judged_again_one_mesh_finer(bending_clean):
    """(c): at half the noise the mesh's error is four times the evidence: the crimp feature
    stands on the h/2 check's residuals too, but its evidence fell there by more than half its
    margin, so it is judged again at h = 1.5 mm, where the h/2 check (h = 0.75 mm, the data's
    own mesh) leaves it nothing."""
    rec = searched(bending_clean, 0.0025)
    q = next(q for q in rec["rounds"][0] if q.get("refit_chi2") is not None)
    assert q["significant_on_this_mesh"] and q["stands_on_finer_mesh"], q
    assert not settled(q)
    again = q["at_finer_mesh"]
    assert again["h_mm"] == pytest.approx(1.5)
    assert again["refitted"] and again["finer_mesh_f"] < 0.5 * again["f_needed"], again
    assert not again["significant"] and not rec["found"]
    assert "judged again at h = 1.5 mm" in rec["outcome"]


@pytest.mark.parametrize(
    "finer, expected",
    [(36.0, True), (30.0, True), (20.0, False), (4.0, False)],
)
def test_settled(finer, expected):
    """score 36 (a = 6), F 36 against 16: b = √finer − 6; settled when (6 + 2b)²·F/36 > 16,
    i.e. 6 + 2b > 4, b > −1, finer > 25."""
    row = {"score": 36.0, "f_statistic": 36.0, "f_needed": 16.0, "finer_mesh_score": finer}
    assert settled(row) == expected
