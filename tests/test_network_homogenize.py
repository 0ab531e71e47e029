"""Numerical homogenisation of the bi-pantographic beam (fabricsurf.network.homogenize).

Hand values used below (linearised chain, derived in the module docstring):
K_S = 1 / (96 [c^2 / (4 k_e) + eps^2 s^2 / (24 k_r1)]) (pivots in series with the side
extension), a_theta(1) = k_r2 B / (k_r2 + B) with B = k_r1 + k_e eps^2 / 18.
"""

import numpy as np
import pytest

from fabricsurf.network.bipantographic import EPS_B, TABLE3, bipantographic_lattice
from fabricsurf.network.equilibrium import newton
from fabricsurf.network.homogenize import (
    a_rho_from_chain,
    a_theta_from_chain,
    a_theta_series,
    coefficients,
    identify_macro,
    k_s_from_chain,
    k_s_series,
    moduli_from_coefficients,
    pantographic_chain,
    uniform_density,
)

EPS = EPS_B
K_E, K_R1, K_R2 = TABLE3["k_e"], TABLE3["k_r1"], TABLE3["k_r2"]


@pytest.fixture(scope="module")
def chain():
    return pantographic_chain(40)


def test_k_s_series_and_pivot_count(chain):
    """Uniform stretch: the chain equals the series formula; with (nearly) inextensible
    sides it is the pivot count k_r1 / eps^2 (4 pivots per beam per cell area 2 eps^2)."""
    assert k_s_from_chain(chain) == pytest.approx(k_s_series(K_E, K_R1, EPS), rel=1e-4)
    stiff = pantographic_chain(24, k_e=1e5)
    assert k_s_from_chain(stiff) == pytest.approx(K_R1 / EPS**2, rel=1e-3)


def test_chain_equals_2d_lattice_under_affine_axis_placement():
    """Axis nodes of the 2D lattice on an affine map: beams stay straight, bars carry no
    moment, so the energy is the sum over rhombi of the chain's uniform energy eps^2 W_u."""
    lat = bipantographic_lattice(3, 2)
    F = np.array([[1.03, 0.02], [0.01, 0.98]])
    x0 = lat.net.X @ F.T
    axis = lat.grid[lat.grid >= 0]
    fixed = np.zeros_like(x0, bool)
    fixed[axis] = True
    x, info = newton(lat.net, x0, fixed.ravel(), rtol=1e-12, atol=1e-12)
    assert info.converged
    ch = pantographic_chain(24)
    n_rhombi = 2 * 3 * 2  # per fibre family: two half diagonals per cell
    rho_l, rho_m = np.linalg.norm(F @ lat.L), np.linalg.norm(F @ lat.M)
    expected = n_rhombi * EPS**2 * (uniform_density(ch, rho_l) + uniform_density(ch, rho_m))
    assert lat.net.energy(x) == pytest.approx(expected, rel=1e-8)


def test_a_theta_hand_formula_and_curvature_convergence(chain):
    """a_theta(kappa) = a_theta(1) + O((kappa eps)^2): halving kappa eps quarters the error,
    and the limit is the series formula (bars in series with the side-node shift)."""
    hand = a_theta_series(K_E, K_R1, K_R2, EPS)
    a = [a_theta_from_chain(chain, h / EPS) for h in (0.2, 0.1, 0.05)]
    e1, e2 = a[0] - a[1], a[1] - a[2]
    assert abs(e1 / a[1]) < 1e-3
    assert e1 / e2 == pytest.approx(4.0, rel=0.05)
    assert (4 * a[2] - a[1]) / 3 == pytest.approx(hand, rel=1e-5)  # O((kappa eps)^4) left


def test_chain_length_independence():
    """End effects decay by ~0.3 per rhombus, so beyond the 10-rhombus margin the window
    sees none: 24 and 48 rhombi give the same moduli."""
    short, long_ = pantographic_chain(24), pantographic_chain(48)
    assert a_theta_from_chain(short, 0.1 / EPS) == pytest.approx(
        a_theta_from_chain(long_, 0.1 / EPS), rel=1e-9
    )
    assert k_s_from_chain(short) == pytest.approx(k_s_from_chain(long_), rel=1e-9)


def test_stiff_sides_give_bars_only_bending():
    """k_e -> infinity: rigid rhombi turn as a whole at each axis node, so both bars there
    turn by kappa eps: energy 2 * k_r2 (kappa eps)^2 / 2 per node area eps^2, a_theta = k_r2."""
    ch = pantographic_chain(24, k_e=1e5)
    assert a_theta_from_chain(ch, 0.02 / EPS) == pytest.approx(K_R2, rel=1e-3)


def test_soft_pivots_reproduce_eq2_with_asymptotic_moduli():
    """k_r1 -> 0 (the eps -> 0 scaling of [B (2)], pivots drop out of the second-gradient
    terms): the chain's a_theta(rho), a_rho(1) are eq. (2) with K_E = k_e eps^2,
    K_F = k_r2, including the rho-dependence of a_theta."""
    ch = pantographic_chain(80, k_r1=1e-4)
    ke, kf = K_E * EPS**2, K_R2
    for rho in (0.97, 1.0, 1.05):
        a = [a_theta_from_chain(ch, h / (EPS * rho), rho) for h in (0.1, 0.05)]
        assert (4 * a[1] - a[0]) / 3 == pytest.approx(coefficients(rho, ke, kf)[0], rel=2e-3)
    a = [a_rho_from_chain(ch, wl) for wl in (24, 48)]
    assert (4 * a[1] - a[0]) / 3 == pytest.approx(coefficients(1.0, ke, kf)[1], rel=5e-3)


def test_inversion_roundtrip_and_feasibility():
    """(K_E, K_F) -> (a_theta(1), a_rho(1)) -> (K_E, K_F); infeasible pairs give NaN."""
    at, ar = coefficients(1.0, 330.0, 900.0)
    assert (at, ar) == pytest.approx((17.97, 418.3), abs=0.05)
    assert moduli_from_coefficients(at, ar) == pytest.approx((330.0, 900.0), rel=1e-12)
    assert np.isnan(moduli_from_coefficients(10.0, 29.0)[0])  # a_rho < 3 a_theta
    assert np.isnan(moduli_from_coefficients(1.0, 28.0)[1])  # a_rho > 27 a_theta


def test_table3_micro_identification():
    """Table 3 micro parameters: K_S and a_theta(1) are about half of Table 3 macro, and
    a_rho(1) < 3 a_theta(1), so no eq. (2) material (K_E, K_F > 0) matches the lattice."""
    r = identify_macro()
    assert r["K_S"] == pytest.approx(k_s_series(K_E, K_R1, EPS), rel=1e-4)
    assert r["a_theta"] == pytest.approx(a_theta_series(K_E, K_R1, K_R2, EPS), rel=1e-5)
    assert 0 < r["a_rho"] < 1.0
    assert not r["feasible"] and np.isnan(r["K_E"])
    assert not r["feasible"]
