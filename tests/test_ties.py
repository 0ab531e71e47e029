"""The tie rule's statistic (fabricsurf/inverse/diagnosis/ties.py, docs/diagnosis.md "Ties") on
residuals drawn here, no forward model: its resolution is that of Δχ² under the noise, so a
difference of predictions |δ| is resolved when |δ|/2 exceeds the critical z, and correlated
noise widens it; the separation of a candidate experiment (discrimination.py) is Σ(Δ/σ)²."""

import numpy as np

from fabricsurf.experiments.picture_frame import frame_displacement, frame_shear_angle
from fabricsurf.experiments.three_zone import zone_c_shear_angle
from fabricsurf.inverse.contract.experiment import template
from fabricsurf.inverse.diagnosis import discrimination as dc
from fabricsurf.inverse.diagnosis.ties import vuong
from fabricsurf.inverse.forward.load_path import Prediction

N, G = 4000, 40
LABELS = np.repeat(np.arange(G), N // G)


def pair(delta_norm: float, rng, correlated: float = 0.0):
    """Residuals of the true model a (noise) and of b, whose prediction differs by a smooth δ of
    norm ``delta_norm``; ``correlated``: the share of each block's noise common to the block."""
    e = rng.normal(size=N) * np.sqrt(1 - correlated)
    e += np.sqrt(correlated) * np.repeat(rng.normal(size=G), N // G)
    shape = np.sin(np.linspace(0.0, 7.0, N)) + 0.3
    delta = delta_norm * shape / np.linalg.norm(shape)
    return e, e + delta


def test_identical_predictions_tie():
    r = np.random.default_rng(0).normal(size=N)
    out = vuong(r, r.copy(), LABELS)
    assert out["z"] == 0.0 and out["p"] == 1.0 and out["delta_chi2"] == 0.0


def test_resolution_is_that_of_delta_chi2():
    """White noise: the resolution is 2|δ| (the floor, within the sandwich's scatter) and the
    z of the true model over the other is about |δ|/2 (its mean |δ|²/(2|δ|)): a |δ| of 2 noise
    units is a tie at the 0.999 level (critical z 3.29), one of 20 is not. Over 200 draws the
    mean z is |δ|/2 within 3 standard errors (sd 1)."""
    rng = np.random.default_rng(1)
    for dn, tied in ((2.0, True), (20.0, False)):
        zs, res = [], []
        for _ in range(200):
            a, b = pair(dn, rng)
            out = vuong(a, b, LABELS)
            zs.append(out["z"])
            res.append(out["resolution"])
        assert abs(np.mean(zs) - dn / 2) < 3 / np.sqrt(200) + 0.1 * dn / 2
        assert np.median(res) >= 2 * dn and np.median(res) < 2.4 * dn
        assert bool(np.median(np.abs(zs)) < dc.Z_CRIT) == tied


def test_correlated_noise_widens_the_resolution():
    """Half of every block's noise common to the block (a DIC subset, a smooth model-form
    error): Σδe has a variance larger than |δ|² and the clustered estimate sees it, so the
    same |δ| = 20 that white noise resolves is no longer resolved as often."""
    rng = np.random.default_rng(2)
    white = [vuong(*pair(20.0, rng), LABELS)["resolution"] for _ in range(50)]
    corr = [vuong(*pair(20.0, rng, 0.5), LABELS)["resolution"] for _ in range(50)]
    assert np.median(corr) > 2.0 * np.median(white)


def test_separation_counts_noise_units():
    """S = Σ(Δu/s_u)² + Σ(ΔF/s_F)², the expected z = √S/2 (3.16: below the critical 3.29)
    and the data it takes for an expected z of z_crit + 2."""
    exp = template(40.0, 20.0, [1.0, 2.0], np.array([[10.0, 5.0], [20.0, 10.0]]))
    exp.noise_std, exp.force_noise_std = 0.01, 0.5
    u = np.zeros((4, 2))
    pa = Prediction(u, np.array([1.0, 2.0]))
    pb = Prediction(u + np.array([0.03, 0.0]), np.array([1.0, 3.0]))
    out = dc.separation(exp, pa, pb)
    assert np.isclose(out["field"], 4 * 9.0) and np.isclose(out["force"], 4.0)
    assert np.isclose(out["expected_z"], 0.5 * np.sqrt(40.0)) and not out["separates"]
    assert np.isclose(out["data_factor"], (2 * (dc.Z_CRIT + 2)) ** 2 / 40.0)


def test_candidates_measure_what_the_data_measure():
    """Force-only data: the candidates measure the force only, but for the one that adds the
    field; the picture frame (square, clamped) is tried only for a first-gradient tie (its
    homogeneous shear has no second gradient)."""
    e = template(60.0, 30.0, [1.0, 2.0], np.zeros((0, 2)))
    e.force_noise_std = 0.1
    second = {c.key: c.exp for c in dc.candidates(e, first_gradient=False)}
    assert set(second) == {
        "larger_displacement",
        "other_fibre_angle",
        "narrower_specimen",
        "field_data",
    }
    assert [k for k, x in second.items() if x.has_field] == ["field_data"]
    assert all(x.force_noise_std == 0.1 for x in second.values())
    assert list(second["larger_displacement"].path) == [2.0, 4.0]
    frame = {c.key: c.exp for c in dc.candidates(e)}["picture_frame"]
    assert frame.length == frame.width == 30.0 and frame.setup.options == {"frame": "clamped"}
    assert np.isclose(
        frame_displacement(float(zone_c_shear_angle(2.0, 60.0, 30.0)), 30.0), frame.path[-1]
    )


def test_frame_displacement_inverts_the_frame_shear_angle():
    """d(γ) is the inverse of the frame's γ(d) over the frame's range (a round trip to
    round-off), so the separating picture-frame test reaches the bias test's zone-C shear."""
    for a in (30.0, 80.0):
        for g in np.radians([0.5, 10.0, 35.0, 60.0, 85.0]):
            assert abs(frame_shear_angle(frame_displacement(float(g), a), a) - g) < 1e-12
