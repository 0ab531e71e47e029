"""Uncertainty of fitted moduli (docs/uncertainty.md): the sandwich covariance against the exact
covariance of a linear model with block-correlated noise, the mesh shift as an exact refit of
a linear model, the model-form spread, the Wald test, the correlated noise generator and the
contract keys of a fit. Linear models and numpy only: seconds."""

import numpy as np
from scipy import stats

from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.inverse.uncertainty import intervals, systematic
from fabricsurf.inverse.uncertainty import statistical as unc

RNG = np.random.default_rng(7)
G, M, RHO = 60, 10, 0.5  # blocks, residuals per block, correlation inside a block


def linear_design():
    x = np.linspace(0.0, 1.0, G * M)
    return np.column_stack([np.ones_like(x), x]), np.repeat(np.arange(G), M)


def block_noise(draws):
    """Unit-variance noise, correlation RHO inside each block, none between blocks."""
    common = RNG.normal(size=(draws, G))
    own = RNG.normal(size=(draws, G * M))
    return np.sqrt(RHO) * np.repeat(common, M, axis=1) + np.sqrt(1 - RHO) * own


def test_sandwich_matches_the_exact_covariance_under_block_correlation():
    """For least squares on a linear model the exact covariance is B JᵀΣJ B; the sandwich over
    the true blocks recovers it on average, the classical (JᵀJ)⁻¹ misses it by about the
    design effect 1 + (M − 1)ρ (Kish 1965), and the reported design effect says so."""
    J, labels = linear_design()
    Sigma = RHO * (labels[:, None] == labels[None, :]) + (1 - RHO) * np.eye(len(labels))
    B = np.linalg.inv(J.T @ J)
    exact = B @ J.T @ Sigma @ J @ B
    draws = block_noise(400)
    covs, deffs = [], []
    for e in draws:
        r = e - J @ (B @ J.T @ e)  # residuals at the least-squares optimum
        st = unc.sandwich(J, r, labels, noise_known=False)
        covs.append(st.cov)
        deffs.append(st.design_effect)
    mean = np.mean(covs, axis=0)
    # the mean of 400 draws: a relative standard error of about √(2/(G − 2))/√400 ≈ 1 %
    assert np.allclose(np.diag(mean), np.diag(exact), rtol=0.05)
    assert np.all(np.diag(exact) / np.diag(B) > 0.8 * (1 + (M - 1) * RHO))
    assert abs(np.mean(deffs) - (1 + (M - 1) * RHO)) < 0.15 * (1 + (M - 1) * RHO)
    assert st.n_blocks == G and st.dof == G - 2


def test_sandwich_by_hand_and_noise_floor():
    """The formula by hand on three blocks; with a stated noise level no standard deviation
    falls below the classical one."""
    J = np.array([[1.0, 0.0], [1.0, 1.0], [1.0, 2.0], [1.0, 3.0], [1.0, 4.0], [1.0, 5.0]])
    r = np.array([0.1, -0.2, 0.05, 0.3, -0.1, -0.15])
    labels = np.array([0, 0, 1, 1, 2, 2])
    B = np.linalg.inv(J.T @ J)
    meat = sum(
        np.outer(J[labels == g].T @ r[labels == g], J[labels == g].T @ r[labels == g])
        for g in range(3)
    )
    st = unc.sandwich(J, r, labels, noise_known=False)
    assert np.allclose(st.cov, 3 / (3 - 2) * B @ meat @ B)
    floored = unc.sandwich(J, r, labels, noise_known=True)
    assert np.all(np.diag(floored.cov) >= np.diag(B) * (1 - 1e-12))


def test_mesh_shift_is_the_refit_of_a_linear_model():
    """For a linear model the Gauss–Newton step is exact: the shift equals the difference of
    the least-squares fits to the data with and without the residual change d."""
    J, _ = linear_design()
    y = RNG.normal(size=len(J))
    d = 0.3 * np.sin(np.arange(len(J)))
    fit0 = np.linalg.lstsq(J, y, rcond=None)[0]
    fit1 = np.linalg.lstsq(J, y - d, rcond=None)[0]  # r = J p − y + d on the finer mesh
    assert np.allclose(systematic.mesh_shift(J, d), fit1 - fit0)


def test_model_form_spread_two_parts():
    """Two parts with the same design and white noise σ = 1 (V = σ²/n per part) whose fits
    differ by Δ: τ² = Δ²/2 − V (DerSimonian & Laird 1986 with two equal weights); zero when
    the parts agree within their noise."""
    n = 50
    J = np.ones((2 * n, 1))
    masks = [np.arange(2 * n) < n, np.arange(2 * n) >= n]
    for delta in (1.0, 0.05):
        r = np.where(masks[0], -delta / 2, delta / 2)  # part fits at ±Δ/2 from the optimum
        tau = systematic.model_form(J, r, masks, None, noise_known=True)
        V = 1.0 / n
        assert np.isclose(tau[0] ** 2, max(delta**2 / 2 - V, 0.0))


def test_model_form_spread_follows_the_modulus_units_without_overflow():
    """τ is in the modulus's units: with the sensitivity scaled by c, τ scales by 1/c. At c =
    1e140 the parts' variances are ~1e-282 and their weights' squares exceed the floating-point
    range (a modulus held at its stiff limit gives such columns); τ must still follow."""
    n = 50
    J = np.ones((2 * n, 1))
    masks = [np.arange(2 * n) < n, np.arange(2 * n) >= n]
    r = np.where(masks[0], -0.5, 0.5)
    tau = systematic.model_form(J, r, masks, None, noise_known=True)
    with np.errstate(over="raise"):
        scaled = systematic.model_form(J * 1e140, r, masks, None, noise_known=True)
    assert np.isclose(scaled[0] * 1e140, tau[0], rtol=1e-12)


def test_wald_one_sided():
    """k = 1: the one-sided t-test of a modulus ≥ 0; k = 2: F(2, dof)."""
    F, p = unc.wald(np.array([3.0]), np.array([[1.0]]), 20)
    assert np.isclose(F, 9.0) and np.isclose(p, stats.t.sf(3.0, 20))
    F, p = unc.wald(np.array([1.0, 2.0]), np.diag([1.0, 4.0]), 30)
    assert np.isclose(F, 1.0) and np.isclose(p, stats.f.sf(1.0, 2, 30))


def test_symmetric_pair_reports_its_mean():
    """k_l = k_m seen only through their sum (a symmetric test): neither is identifiable, the
    geometric mean (weights ½, ½: the mean to first order) is, with an interval from the
    covariance of the sum."""
    p = np.array([30.0, 30.0])
    # var(k_l + k_m) = 4, var(k_l − k_m) = 1e4: a strongly anticorrelated pair
    R = np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2)
    cov = R @ np.diag([2.0, 5e3]) @ R.T
    out = intervals.summarise(["f.k_l", "f.k_m"], p, cov, 2.0, None, None, set())
    assert not out["moduli"]["f.k_l"]["identifiable"]
    assert out["moduli"]["f.k_l"]["ci95"][0] == 0.0  # clipped at the bound, not printed
    (c,) = out["identifiable_combinations"]
    assert np.allclose(list(c["weights"].values()), 0.5) and np.isclose(c["value"], 30.0)
    sd_log = np.sqrt(4.0) / 2 / 30.0  # σ of (k_l + k_m)/2 relative to 30
    assert np.allclose(c["ci95"], 30.0 * np.exp([-2.0 * sd_log, 2.0 * sd_log]))
    assert out["weak_directions"][0]["direction"].startswith("0.71 log f.k_l - 0.71 log f.k_m")


def test_interval_parts_combine():
    """ci95 half-width = √((tσ)² + (1.96τ)²) + 2|δ| and each part is reported."""
    out = intervals.summarise(
        ["a.k"], np.array([10.0]), np.array([[1.0]]), 2.0, np.array([0.5]), np.array([-0.25]), set()
    )
    m = out["moduli"]["a.k"]
    half = np.sqrt(4.0 + (intervals.Z95 * 0.5) ** 2) + 0.5
    assert np.allclose(m["ci95"], [10 - half, 10 + half]) and m["identifiable"]
    assert set(m) == {
        "value",
        "ci95",
        "std_statistical",
        "systematic_mesh",
        "mesh_shift_h_to_h2",
        "systematic_model",
        "identifiable",
    }
    assert m["systematic_mesh"] == 0.5 and m["std_statistical"] == 1.0


def test_correlated_noise_has_its_correlation_length():
    """The generator's field: unit variance, correlation e^(−1/2) at one correlation length
    (squared-exponential), independent at five."""
    pts = sy.grid_points(60.0, 30.0, 31, 16, margin=0.0)
    ell = 2.0  # the grid spacing
    f = sy.correlated_field(pts, ell, np.random.default_rng(3), 200).T  # 200 fields
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    corr = np.corrcoef(f.T)
    assert abs(f.var() - 1.0) < 0.05
    near = corr[np.isclose(d, ell, atol=0.05)]
    far = corr[d > 5 * ell]
    assert abs(near.mean() - np.exp(-0.5)) < 0.05 and abs(far.mean()) < 0.05


def test_force_band_of_a_linear_model():
    """A force and displacements linear in the moduli: the band of each is t·√(gᵀCg) (+ the
    parts), the linearisation check finds no departure."""
    from types import SimpleNamespace

    from fabricsurf.inverse.fitting.band import force_band

    A = np.array([[1.0, 0.5], [2.0, 1.0], [3.0, 2.5]])  # dF/dp at three loads
    D = np.array([[[0.1, 0.0], [0.0, 0.2]], [[0.3, 0.1], [0.2, 0.0]]])  # du/dp: 2 rows × 2

    class Linear:
        names = ["a.k", "b.k"]

        def __init__(self):
            self.params = [(SimpleNamespace(name="a"), "k"), (SimpleNamespace(name="b"), "k")]
            self.exp = SimpleNamespace(
                has_force=True, has_field=True, path=np.array([1.0, 2.0, 3.0])
            )
            self.v = np.zeros(2)

        def values(self):
            return self.v.copy()

        def set_values(self, v):
            self.v = np.array(v, float)

        def run(self, sens=False):
            return SimpleNamespace(
                force=A @ self.v, dforce=A if sens else None, u=D @ self.v, du=D if sens else None
            )

    C = np.array([[0.04, 0.01], [0.01, 0.09]])
    saved = {
        "params": {"a": {"k": 2.0}, "b": {"k": 3.0}},
        "moduli": {
            "a.k": {"systematic_model": 0.1, "mesh_shift_h_to_h2": 0.05},
            "b.k": {"systematic_model": 0.0, "mesh_shift_h_to_h2": 0.0},
        },
        "uncertainty": {
            "statistics": {"t95": 2.1},
            "covariance": {"names": ["a.k", "b.k"], "statistical": C},
        },
    }
    band = force_band(Linear(), saved)
    stat = 2.1 * np.sqrt(np.einsum("ki,ij,kj->k", A, C, A))
    half = np.sqrt(stat**2 + (intervals.Z95 * 0.1 * A[:, 0]) ** 2) + 2 * 0.05 * A[:, 0]
    assert np.allclose(band["force"], A @ [2.0, 3.0])
    assert np.allclose(band["half_width"], half)
    assert band["nonlinearity"] < 1e-12 and band["reliable"]
    stat_u = 2.1 * np.sqrt(np.einsum("rci,ij,rcj->rc", D, C, D))
    half_u = np.sqrt(stat_u**2 + (intervals.Z95 * 0.1 * D[..., 0]) ** 2) + 2 * 0.05 * np.abs(
        D[..., 0]
    )
    assert np.allclose(band["field_half_width"], half_u)


def test_fit_contract_and_params_read_back(tmp_path):
    """A fit of continuum data made with the fitted model itself: fit.json carries the
    contract object per modulus, every modulus identifiable with an interval containing the
    truth, the mesh part measured, and the file still reads back as --params."""
    import json
    from pathlib import Path

    from mpi4py import MPI

    from fabricsurf.discretise.output import write_json
    from fabricsurf.inverse.diagnosis.diagnose import full_model
    from fabricsurf.inverse.diagnosis.result_text import result_lines
    from fabricsurf.inverse.fitting.fit import fit
    from fabricsurf.inverse.fitting.params import load_params
    from fabricsurf.inverse.forward.runs import ForwardModel

    comm = MPI.COMM_WORLD
    truth = {"fibre_stretch": {"k_l": 25.0, "k_m": 25.0}, "shear": {"k_s": 0.4}}
    exp = sy.template(48.0, 24.0, [1.0, 2.0], sy.grid_points(48.0, 24.0, 8, 4))
    sy.continuum_data(exp, full_model(list(truth), truth), h=4.0, comm=comm)
    sy.add_noise(exp, 0.005, 0.005, 5)
    fm = ForwardModel(exp, full_model(list(truth), truth), h=4.0, comm=comm)
    free = [i for i, (t, _) in enumerate(fm.params) if t.name in truth]
    res = fit(fm, free, scale_start=False)
    res.check_mesh(fm)
    saved = res.as_dict()
    assert set(saved["moduli"]) == {"fibre_stretch.k_l", "fibre_stretch.k_m", "shear.k_s"}
    for name, m in saved["moduli"].items():
        t, p = name.split(".")
        assert {"value", "ci95", "std_statistical", "systematic_mesh", "identifiable"} <= set(m)
        assert m["identifiable"] and m["ci95"][0] <= truth[t][p] <= m["ci95"][1], (name, m)
        assert m["systematic_mesh"] is not None
    assert saved["identifiable_combinations"] == [] and saved["undetermined"] == []
    st = saved["uncertainty"]["statistics"]
    assert st["blocks"] == 2 * 16 + 2  # 4 x 4 regions x 2 steps, and 2 forces
    assert np.isclose(saved["uncertainty"]["chi2_h_vs_h2"], res.chi2_h)
    assert all("95 % interval" in ln for ln in result_lines(saved))
    path = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None)) / "fit.json"
    write_json(comm, path, saved)
    comm.barrier()
    assert load_params(path) == json.loads(path.read_text())["params"]
    bands_from_the_saved_fit(path, exp, truth, comm)


def bands_from_the_saved_fit(fit_json, exp, truth: dict, comm) -> None:
    """compare and bias with --params fit.json carry the fit's uncertainty into their force
    curves: compare's band around the fitted prediction contains the force of the true moduli
    at every step (their interval contains the truth, and the force is linear in them here);
    bias, whose own solve is another code path, predicts the band's centre."""
    import json

    from fabricsurf.cli import main
    from fabricsurf.inverse.contract.data import write_experiment
    from fabricsurf.inverse.diagnosis.diagnose import full_model
    from fabricsurf.inverse.forward.runs import ForwardModel

    root = fit_json.parent
    if comm.rank == 0:
        write_experiment(root / "data", exp)
    comm.barrier()
    assert (
        main(
            [
                "compare",
                str(root / "data"),
                "--params",
                str(fit_json),
                "--h",
                "4",
                "--out",
                str(root / "cmp"),
            ]
        )
        == 0
    )
    comm.barrier()
    band = np.loadtxt(root / "cmp" / "force_band.csv", delimiter=",", skiprows=1)
    info = json.loads((root / "cmp" / "misfit.json").read_text())["force_bands"][exp.name]
    assert info["reliable"] and (root / "cmp" / "force_band.png").is_file()
    field = np.loadtxt(root / "cmp" / "field_band.csv", delimiter=",", skiprows=1)
    assert field.shape == (len(exp.X), 5) and np.all(field[:, 3:] > 0)
    assert np.isclose(field[:, 3:].max(), info["field_half_width_max"])
    with ForwardModel(exp, full_model(list(truth), truth), h=4.0, comm=comm) as fm:
        f_true = fm.run().force
    assert np.all((band[:, 2] <= f_true) & (f_true <= band[:, 3])), (band, f_true)
    assert (
        main(
            [
                "bias",
                "--params",
                str(fit_json),
                "--length",
                "48",
                "--width",
                "24",
                "--h",
                "4",
                "--ubar",
                "2",
                "--steps",
                "2",
                "--out",
                str(root / "bias"),
            ]
        )
        == 0
    )
    comm.barrier()
    s = json.loads((root / "bias" / "summary.json").read_text())
    assert np.allclose(s["force_band"]["force"], s["force"], rtol=1e-6)
    assert (root / "bias" / "force_band.csv").is_file()
