"""Dispersion of the 1D chain of Mühlhaus & Oka 1996 and of the Hencky lattice against
(gradient) continua.

Each assertion compares a computed quantity with Mühlhaus & Oka 1996 eqs. (12), (14), (15) or with
the closed-form lattice/continuum relations derived in demos/demo_dispersion.py, to the order in qD
that the expansion promises. Runs serially and under ``mpirun -n 2`` (dolfinx parts gather to
rank 0 and broadcast, so every rank asserts the same numbers).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI
from scipy.optimize import brentq

from fabricsurf.verification import dispersion as dp

N = 40  # chain masses; q_n D = nπ/41 spans (0, π)
NEXT = {2: -1.0 / 12.0, 4: 1.0 / 360.0, 6: -1.0 / 20160.0}  # first neglected coefficient


@pytest.fixture(scope="module")
def cont() -> dp.GradientContinuum1D:
    return dp.GradientContinuum1D(MPI.COMM_WORLD, N + 1.0, 2 * (N + 1), degree=5)


@pytest.fixture(scope="module")
def fe_modes(cont) -> dict[int, np.ndarray]:
    out = {}
    for p in (2, 4, 6):
        w2, overlap, _, _ = cont.modes(*dp.gradient_moduli(p), 1.0, N)
        assert overlap.min() > 0.999  # every picked eigenvector is the expected sine
        out[p] = w2
    return out


@pytest.mark.parametrize("p", [2, 4, 6])
def test_series_is_expansion_of_eq12(p):
    # eq. (15) truncations: the remainder is the next term, C_p x^p (1 + O(x²))
    x = np.geomspace(0.05, 0.4, 8)
    rem = dp.vp2_exact(x) - dp.vp2_truncated(x, p)
    assert np.all(np.abs(rem / (NEXT[p] * x**p) - 1) < 0.1 * x**2)
    assert abs(dp.fit_order(x, rem) - p) < 0.01
    assert np.allclose(dp.vp2_exact(x), 2 * (1 - np.cos(x)) / x**2, rtol=1e-12)


def test_sign_of_gradient_terms():
    # footnote of Mühlhaus & Oka 1996: the D²/12 term enters the energy with a negative sign
    a4, b4, c4 = dp.gradient_moduli(4)
    assert (a4, b4, c4) == (1.0, -1.0 / 12.0, 0.0)
    assert dp.gradient_moduli(6)[2] == pytest.approx(1.0 / 360.0)
    x = np.linspace(0.0, 50.0, 5001)
    assert np.all(dp.vp2_truncated(x, 6) > 0.3)  # 1 - x²/12 + x⁴/360 has no real root
    assert np.all(dp.vp2_truncated(x[x > math.sqrt(12) + 1e-9], 4) < 0)


@pytest.mark.parametrize(("k", "m", "D"), [(1.0, 1.0, 1.0), (3.0, 2.0, 0.5)])
def test_engine_chain_equals_eq12(k, m, D):
    q = dp.fixed_chain_wavenumbers(N, D)
    w2 = dp.chain_modes(N, k, m, D)
    assert np.max(np.abs(w2 / dp.omega2_chain(q * D, k, m) - 1)) < 1e-12


@pytest.mark.parametrize(("p", "tol"), [(2, 1e-9), (4, 1e-6), (6, 1e-5)])
def test_continuum_modes_match_truncated_formula(fe_modes, p, tol):
    # rho ω² = a q² + b q⁴ + c q⁶ (eqs. 10, 15); tol = round-off floor eps·max|λ|/ω_1² (x~10)
    q = dp.fixed_chain_wavenumbers(N)
    rel = np.abs(fe_modes[p] / (q**2 * dp.vp2_truncated(q, p)) - 1)
    assert rel[q <= 1.5].max() < tol
    assert rel.max() < 1e-4  # P5 on h = D/2 up to the zone edge qD → π


@pytest.mark.parametrize("p", [2, 4, 6])
def test_truncation_error_order_measured(fe_modes, p):
    # chain (eq. 12) minus ∂^p continuum ≈ C_p (qD)^(p+2) in mω²/k: slope and prefactor
    q = dp.fixed_chain_wavenumbers(N)
    e = dp.chain_modes(N) - fe_modes[p]
    sel = (np.abs(e) > 1e-6) & (q <= 1.6)
    assert sel.sum() >= 5
    assert abs(dp.fit_order(q[sel], e[sel]) - (p + 2)) < 0.1
    i0 = np.flatnonzero(sel)[0]
    assert abs(e[i0] / (NEXT[p] * q[i0] ** (p + 2)) - 1) < 0.02


def test_fourth_order_ill_posed_sixth_order_not():
    comm = MPI.COMM_WORLD
    lmin = {4: [], 6: []}
    for cpd in (2, 4):
        short = dp.GradientContinuum1D(comm, 11.0, 11 * cpd, degree=5)
        for p in (4, 6):
            lmin[p].append(short.modes(*dp.gradient_moduli(p), 1.0, 1)[2].min())
    # ∂⁴: rho ω² ≈ b q⁴ with q ~ 1/h resolved → min eigenvalue ∝ -h⁻⁴, no limit
    assert lmin[4][0] < 0 and lmin[4][1] / lmin[4][0] == pytest.approx(16.0, rel=0.05)
    # ∂⁶: the smallest eigenvalue is the first physical mode, independent of h
    q1 = np.pi / 11.0
    assert np.allclose(lmin[6], q1**2 * dp.vp2_truncated(q1, 6), rtol=1e-5)


@pytest.fixture(scope="module")
def bloch():
    from fabricsurf.network.hencky import hencky_lattice
    from fabricsurf.network.hencky_moduli import lattice_from_continuum

    def run(k_l, k_s, A_g, x):
        lat = hencky_lattice(
            4.0, 4.0, 1.0, (0.0, 90.0), **lattice_from_continuum(k_l, k_s, A_g, 1.0, (0.0, 90.0))
        )
        H = lat.net.hessian(lat.net.X)
        return dp.bloch_omega2(H, lat.net.X, int(lat.grid[2, 2]), x, lat.L, 1.0)

    return run


def test_hencky_bloch_and_continuum_limit(bloch):
    k_l, k_s, A_g = 30.0, 0.5, 40.0
    x = np.geomspace(0.02, np.pi, 60)
    wl, wt = bloch(k_l, k_s, A_g, x)
    assert np.allclose(wl, dp.hencky_omega2(x, 1.0, k_l), rtol=1e-9)
    assert np.allclose(wt, dp.hencky_omega2(x, 1.0, k_s, A_g), rtol=1e-9)
    # continuum limit with the hencky.py identification: relative error ∝ (qε)²,
    # coefficient -1/12 (longitudinal) and -1/6 (transverse, bending-dominated at β = 80)
    small = x < 0.3
    rl = wl / dp.fabric_omega2(x, k_l, 0.0) - 1
    rt = wt / dp.fabric_omega2(x, k_s, A_g) - 1
    assert abs(dp.fit_order(x[small], rl[small]) - 2) < 0.02
    assert np.allclose(rl[small] / x[small] ** 2, -1 / 12, rtol=0.01)
    beta = A_g / k_s
    coef = -(1 / 12 + beta * x**2 / 6) / (1 + beta * x**2)  # from the two series
    assert np.allclose(rt[small] / x[small] ** 2, coef[small], rtol=0.02)


def test_departure_points(bloch):
    x = np.geomspace(1e-4, np.pi, 4000)
    k_l, k_s, A_g = 30.0, 0.5, 40.0
    wl, wt = bloch(k_l, k_s, A_g, x)
    # fibre_stretch alone = ∂² chain continuum: 1 % where c0/v_p(eq. 12) = 1.01
    ref = brentq(lambda s: 1 / math.sqrt(dp.vp2_exact(s)) - 1.01, 0.1, 1.0)
    dep_l = dp.departure_point(x, np.sqrt(dp.fabric_omega2(x, k_l, 0.0) / wl))
    assert dep_l == pytest.approx(ref, rel=1e-3)
    # a stable (A_s > 0) stretch gradient departs earlier
    assert dp.departure_point(x, np.sqrt(dp.fabric_omega2(x, k_l, k_l / 12) / wl)) < dep_l
    # shear alone departs at ½β(qε)² ≈ 1 %; geodesic_bending pushes it to O(0.35)
    d_s = dp.departure_point(x, np.sqrt(dp.fabric_omega2(x, k_s, 0.0) / wt))
    d_g = dp.departure_point(x, np.sqrt(dp.fabric_omega2(x, k_s, A_g) / wt))
    assert d_s == pytest.approx(math.sqrt((1 / 0.99**2 - 1) * k_s / A_g), rel=0.02)
    assert 0.3 < d_g < 0.5 and d_g > 10 * d_s


def test_departure_point_helper():
    x = np.linspace(0.0, 1.0, 11)
    assert dp.departure_point(x, 1 + 0.02 * x) == pytest.approx(0.5)
    assert dp.departure_point(x, np.ones_like(x)) == math.inf
