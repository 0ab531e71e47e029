"""Hencky fabric lattice: identification and convergence to the continuum; bi-pantographic cell.

Rates are printed (``pytest -s``) and asserted with a stated margin.
"""

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model import kinematics as kn
from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.terms import CrossoverFriction, FibreStretch, Shear, ShearLocking
from fabricsurf.network.equilibrium import Dirichlet, solve_steps
from fabricsurf.network.hencky import fibre_directions, hencky_lattice, spanning_spacing
from fabricsurf.network.hencky_moduli import continuum_from_lattice, lattice_from_continuum
from fabricsurf.network.micromacro import grid_fields

K_L, K_S, A_G = 1.0, 0.3, 0.5  # N/mm, N/mm, N mm
K4, K6 = 0.4, 0.2  # shear_locking moduli, N/mm
TAU_F, GAMMA_F = 0.05, 0.03  # crossover_friction: saturated stress (N/mm), shape angle (rad)

# ------------------------------------------------------------ smooth periodic placement
P = 10.0  # period (mm) in both skew fibre coordinates (s, t), X = s L + t M
F0 = np.array([[1.05, 0.08], [-0.03, 0.97]])
MODES = [
    ((1, 0), (0.30, 0.10), 0.4),
    ((0, 1), (-0.10, 0.25), -0.7),
    ((1, 1), (0.12, -0.15), 1.1),
    ((1, -2), (0.05, 0.06), 0.2),
]


def placement(s, t, L, M):
    """r and its fibre derivatives r_L, r_M, r_LL, r_MM at fibre coordinates (s, t)."""
    k = 2 * np.pi / P
    X = s[:, None] * L + t[:, None] * M
    r, rl, rm = X @ F0.T, np.tile(F0 @ L, (len(s), 1)), np.tile(F0 @ M, (len(s), 1))
    rll, rmm = np.zeros_like(r), np.zeros_like(r)
    for (p, q), c, th in MODES:
        ph = k * (p * s + q * t) + th
        c = np.asarray(c)
        r += np.cos(ph)[:, None] * c
        rl -= (k * p * np.sin(ph))[:, None] * c
        rm -= (k * q * np.sin(ph))[:, None] * c
        rll -= ((k * p) ** 2 * np.cos(ph))[:, None] * c
        rmm -= ((k * q) ** 2 * np.cos(ph))[:, None] * c
    return r, rl, rm, rll, rmm


def continuum_density(rl, rm, rll, rmm, lattice_limit, L, M):
    """fibre_stretch + shear + shear_locking + geodesic_bending (docs/theory.md), γ = θ0 − θ; with
    ``lattice_limit`` the bending terms carry the 1/lam^2, 1/mu^2 factors of the lattice's
    exact limit."""
    lam, mu = np.linalg.norm(rl, axis=1), np.linalg.norm(rm, axis=1)
    ul, um = rl / lam[:, None], rm / mu[:, None]
    p, q = np.stack([-ul[:, 1], ul[:, 0]], 1), np.stack([-um[:, 1], um[:, 0]], 1)
    gam = np.arccos(L @ M) - np.arccos(np.einsum("ij,ij->i", ul, um))
    bl, bm = np.einsum("ij,ij->i", p, rll), np.einsum("ij,ij->i", q, rmm)
    if lattice_limit:
        bl, bm = bl / lam, bm / mu
    return (
        0.5 * K_L * ((lam - 1) ** 2 + (mu - 1) ** 2)
        + 0.5 * K_S * gam**2
        + 0.25 * K4 * gam**4
        + K6 / 6 * gam**6
        + 0.5 * A_G * (bl**2 + bm**2)
    )


def continuum_mean(lattice_limit, L, M, nq=256):
    s, t = np.meshgrid(np.arange(nq) * P / nq, np.arange(nq) * P / nq, indexing="ij")
    _, rl, rm, rll, rmm = placement(s.ravel(), t.ravel(), L, M)
    return continuum_density(rl, rm, rll, rmm, lattice_limit, L, M).mean()


def lattice_mean(n, angles):
    """Lattice energy of one period (the skew cell P L x P M) per reference area."""
    eps = P / n
    k = lattice_from_continuum(K_L, K_S, A_G, eps, angles, k4=K4, k6=K6)
    L, M = fibre_directions(angles)
    half = (P / 2 + 8 * eps) * (np.abs(L) + np.abs(M))  # half-extent covering the period
    lat = hencky_lattice(2 * half[0], 2 * half[1], eps, angles, origin=tuple(half), **k)
    net = lat.net
    s, t = np.linalg.solve(np.column_stack([L, M]), (net.X - half).T)
    x = placement(s, t, L, M)[0]
    ee, er = net.spring_energies(x)
    # one period of anchors (first node of extensional springs, vertex of rotational springs)
    lo, hi = -P / 2 - 1e-9, P / 2 - eps / 2

    def window(nodes):
        return (s[nodes] >= lo) & (s[nodes] < hi) & (t[nodes] >= lo) & (t[nodes] < hi)

    area = P**2 * abs(L[0] * M[1] - L[1] * M[0])
    return (ee[window(net.ext[:, 0])].sum() + er[window(net.rot[:, 1])].sum()) / area, L, M


def rates(hs, errs):
    return np.diff(np.log(errs)) / np.diff(np.log(hs))


@pytest.mark.parametrize("angles", [(45.0, -45.0), (40.0, -40.0)])
def test_energy_density_of_smooth_placements_converges_as_eps_squared(angles):
    """Orthogonal (±45°) and skew (±40°, node area eps² sin 80°) lattices, with locking."""
    ns = [8, 16, 32, 64]
    vals = [lattice_mean(n, angles) for n in ns]
    L, M = vals[0][1], vals[0][2]
    w_lim, w_con = continuum_mean(True, L, M), continuum_mean(False, L, M)
    err = np.abs([v[0] - w_lim for v in vals])
    r = rates(P / np.array(ns), err)
    print(
        f"\n{angles}: energy density: lattice {[f'{v[0]:.6e}' for v in vals]}, limit "
        f"{w_lim:.6e}, continuum terms {w_con:.6e}\n  errors {err}, rates {r}"
    )
    assert np.all(r > 1.8), f"lattice energy density must converge as eps^2 (rates {r})"
    assert err[-1] / w_lim < 2e-3, "relative error at eps = P/64"
    # caveat of the bending identification: O(lam - 1), not O(eps)
    assert abs(w_lim - w_con) / w_con < 0.05


@pytest.mark.parametrize("angles", [(40.0, -40.0), (30.0, -30.0)])
def test_large_homogeneous_shear_matches_continuum_shear_and_locking(angles):
    """Affine placement with γ = 0.75 rad (±40°), 0.59 rad (±30°): the energy of each
    interior node (its L and M springs, four quadrant springs) equals the density of
    fibre_stretch + shear + shear_locking + crossover_friction (the UFL terms, γ = θ0 − θ)
    times the node area eps² sin θ0, exactly."""
    eps, F = 0.5, np.array([[1.5, 0.0], [0.0, 0.6]])  # pure shear plus fibre stretch
    k = lattice_from_continuum(
        K_L, K_S, A_G, eps, angles, k4=K4, k6=K6, tau_f=TAU_F, gamma_f=GAMMA_F
    )
    back = continuum_from_lattice(spacing=eps, angles_deg=angles, **k)
    assert np.allclose(
        [back[n] for n in ("k_l", "k_s", "A_g", "k4", "k6", "tau_f", "gamma_f")],
        [K_L, K_S, A_G, K4, K6, TAU_F, GAMMA_F],
        rtol=1e-14,
    ), "identification round trip"
    lat = hencky_lattice(8.0, 6.0, eps, angles, **k)
    net = lat.net
    ee, er = net.spring_energies(net.X @ F.T)
    inner = _interior(lat.grid)
    node_energy = (
        np.bincount(net.ext[:, 0], ee, net.n_nodes) + np.bincount(net.rot[:, 1], er, net.n_nodes)
    )[inner]

    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    x = ufl.SpatialCoordinate(msh)
    kin = Kinematics(ufl.grad(ufl.as_matrix(F.tolist()) * x), None, *kn.fibre_directions(*angles))
    model = [
        FibreStretch(k_l=K_L, k_m=K_L),
        Shear(k_s=K_S),
        ShearLocking(k4=K4, k6=K6),
        CrossoverFriction(tau_f=TAU_F, gamma_f=GAMMA_F),
    ]
    W = sum(t.density(kin, t.values()) for t in model)
    dens = fem.Expression(ufl.as_vector([kin.gamma, W]), np.array([[1 / 3, 1 / 3]]))
    gam, w = dens.eval(np.arange(msh.topology.index_map(2).size_local, dtype=np.int32))[0]
    s0 = np.sin(np.radians(angles[0] - angles[1]))
    assert abs(gam) > 0.5, f"large shear wanted, gamma = {gam}"
    assert len(inner) > 50
    assert np.allclose(node_energy, w * eps**2 * s0, rtol=1e-12, atol=0)
    # the quartic and sextic springs carry a sizeable part of it
    assert 0.25 * K4 * gam**4 + K6 / 6 * gam**6 > 0.1 * 0.5 * K_S * gam**2


# ------------------------------------------------- transverse-shear strip (0/90 fibres)
LX, WY, ELL = 20.0, 8.0, 2.0  # strip length, width, boundary-layer length sqrt(A/k_s) (mm)


def strip_solution(x, delta, ks=1.0):
    """Continuum v(x) of A v'''' = k_s v'', v(0)=v'(0)=0, v(LX)=delta, v'(LX)=0, and force."""
    A = ks * ELL**2

    def basis(z, d):
        c, s = np.cosh(z / ELL), np.sinh(z / ELL)
        return [np.ones_like(z), z, c, s] if d == 0 else [0 * z, 1 + 0 * z, s / ELL, c / ELL]

    Mtx = np.array(
        [
            basis(np.array(0.0), 0),
            basis(np.array(0.0), 1),
            basis(np.array(LX), 0),
            basis(np.array(LX), 1),
        ],
        float,
    )
    c = np.linalg.solve(Mtx, [0, 0, delta, 0])
    v = sum(ci * bi for ci, bi in zip(c, basis(x, 0), strict=True))
    force = WY * ks * c[1]  # k_s v' - A v''' = k_s c1 (the cosh/sinh parts cancel)
    return v, force, A


def strip_error(eps, table1, delta=1e-3, ks=1.0):
    """Max nodal error of v over the strip, relative to delta.

    The long edges (two node rows each) carry the exact continuum v: with free long edges
    the 2D continuum solution is not the 1D one (shear traction on y = 0, W). At the ends,
    either the exact v on the two held layers (``table1=False``: O(eps^2) consistency) or
    the Table-1 clamps v = 0 / v = delta on both layers (``table1=True``).
    """
    _, _, A = strip_solution(np.array(0.0), delta, ks)
    lat = hencky_lattice(LX, WY, eps, angles_deg=(0, 90), k_e=10.0, k_sh=ks * eps**2, k_b=A)
    X = lat.net.X
    v = strip_solution(X[:, 0], delta, ks)[0]
    ends = (X[:, 0] <= eps * 1.01) | (X[:, 0] >= LX - eps * 1.01)
    held = ends | (X[:, 1] <= eps * 1.01) | (X[:, 1] >= WY - eps * 1.01)
    vb = np.where(ends & table1, np.where(X[:, 0] > LX / 2, delta, 0.0), v)
    nodes = np.nonzero(held)[0]
    res = solve_steps(lat.net, [Dirichlet(nodes, np.stack([0 * vb, vb], 1)[nodes])], n_steps=1)
    return np.abs(res[-1].x[:, 1] - X[:, 1] - v).max() / delta


def test_strip_shear_bending_converges_to_continuum():
    epss = np.array([0.5, 0.25, 0.125])
    e_man = np.array([strip_error(e, False) for e in epss])
    e_t1 = np.array([strip_error(e, True) for e in epss])
    r_man, r_t1 = rates(epss, e_man), rates(epss, e_t1)
    print(
        f"\nstrip: exact boundary layers: errors {e_man}, rates {r_man}"
        f"\n       Table-1 clamp layers:  errors {e_t1}, rates {r_t1}"
    )
    assert np.all(r_man > 1.7), "interior response with exact boundary data must be O(eps^2)"
    assert np.all(r_t1 > 0.8), "two held layers = gradient clamp up to an O(eps) offset"


# ------------------------------------------------------------------------------ misc
def test_hencky_clamps_hold_two_layers():
    lat = hencky_lattice(17.0, 8.5, 17 / 10 * np.sqrt(2), k_e=1, k_sh=1, k_b=1)
    xs = np.unique(np.round(lat.net.X[lat.clamp, 0], 9))
    assert len(xs) == 2 and xs[0] == 0.0, "clamp = columns x=0 and x=eps/sqrt(2)"
    xs = np.unique(np.round(lat.net.X[lat.grip, 0], 9))
    assert len(xs) == 2 and xs[-1] == 17.0


@pytest.mark.parametrize("angles", [(45.0, -45.0), (40.0, -40.0), (0.0, 90.0)])
def test_spanning_spacing_puts_the_grip_layer_on_the_specimen_end(angles):
    """187 mm at eps = 2.5 mm is no whole number of column steps: the outermost layer stops up
    to one step w short of the end. The spanning spacing is within half a step of the request
    and puts it on the end."""
    w = 2.5 * max(abs(np.cos(np.radians(a))) for a in angles)
    short = 187.0 - hencky_lattice(187.0, 20.0, 2.5, angles).net.X[:, 0].max()
    eps = spanning_spacing(187.0, 2.5, angles)
    lat = hencky_lattice(187.0, 20.0, eps, angles)
    assert 0.0 < short < w and abs(eps / 2.5 - 1.0) * 187.0 <= w / 2.0
    assert np.isclose(lat.net.X[:, 0].max(), 187.0, rtol=1e-12, atol=0.0)
    assert np.isclose(lat.net.X[lat.grip, 0].min(), 187.0 - eps * w / 2.5, rtol=1e-12)


def test_lattice_data_refuses_a_lattice_short_of_the_grip():
    """At 30/-60 degrees the node x-coordinates are not evenly stepped: at 12.3 x 7 mm the
    spanning spacing still leaves the last node 0.1 mm short of the end, and the generator
    refuses rather than write data whose grip is not where the experiment says."""
    exp = sy.template(12.3, 7.0, [0.1], np.zeros((0, 2)), angles=(30.0, -60.0))
    with pytest.raises(ValueError, match=r"spans x = 0\.\.[0-9.]+ mm, not the specimen's 0\.\.12"):
        sy.lattice_data(exp, 1.0, k_l=1.0, k_s=1.0, A_g=0.0)


@pytest.mark.parametrize("angles", [(45.0, -45.0), (30.0, -60.0), (0.0, 90.0)])
def test_affine_placement_is_equilibrium_and_micromacro_is_exact(angles):
    lat = hencky_lattice(12.0, 7.0, 1.0, angles_deg=angles, k_e=2, k_sh=0.7, k_b=0.4)
    F = np.array([[1.15, 0.2], [-0.05, 0.92]])
    x = lat.net.X @ F.T
    g = lat.net.gradient(x)
    # interior nodes (all 4 fibre neighbours and 8 diagonal ones present) are in equilibrium
    full = _interior(lat.grid)
    assert np.abs(g[full]).max() < 1e-10, "affine placements are lattice equilibria"
    f = grid_fields(lat.grid, lat.net.X, x, lat.spacing)
    lam, mu = np.linalg.norm(F @ lat.L), np.linalg.norm(F @ lat.M)
    gam = np.arcsin((F @ lat.L) @ (F @ lat.M) / (lam * mu))
    # (corner nodes without a neighbour along a or b give NaN)
    for key, val in [("rho_x", lam), ("rho_y", mu)]:
        v = f[key][lat.grid >= 0]
        assert np.isnan(v).sum() <= 4 and np.allclose(v[~np.isnan(v)], val), "eq. (4) of [B]"
    ok = ~np.isnan(f["shear"])
    assert ok.sum() > 0.8 * (lat.grid >= 0).sum()
    assert np.allclose(f["shear"][ok], gam), "eq. (5) of [B] gives the shear angle gamma"


@pytest.mark.parametrize("angles", [(40.0, -40.0), (30.0, -30.0)])
def test_affine_placement_of_skew_lattice_is_equilibrium(angles):
    """Skew lattices (braid, bias cut) with locking springs: affine placements are equilibria
    of the interior nodes, as for orthogonal fibres."""
    k = lattice_from_continuum(K_L, K_S, A_G, 1.0, angles, k4=K4, k6=K6)
    lat = hencky_lattice(12.0, 7.0, 1.0, angles_deg=angles, **k)
    x = lat.net.X @ np.array([[1.15, 0.2], [-0.05, 0.92]]).T
    assert np.abs(lat.net.gradient(x)[_interior(lat.grid)]).max() < 1e-10


def _interior(grid):
    pad = np.pad(grid, 2, constant_values=-1)
    na, nb = grid.shape
    ok = grid >= 0
    for da in range(-2, 3):
        for db in range(-2, 3):
            ok &= pad[2 + da : na + 2 + da, 2 + db : nb + 2 + db] >= 0
    return grid[ok]


# ------------------------------------------------------------- bi-pantographic lattice
def test_bipantographic_cell_counts_and_reference_state():
    from fabricsurf.network.bipantographic import bipantographic_lattice

    lat = bipantographic_lattice()  # 11 x 7 cells, eps = 12.02 mm, Table 3
    net = lat.net
    assert net.n_nodes == 12 * 8 + 9 * 77, "[B (18)]: (N+1)(M+1) + 9NM nodes"
    assert len(net.ext) == 16 * 77 and len(net.rot) == 12 * 77 + 4 * 10 * 6, "[B (20)]"
    assert np.allclose(net.l0, 12.02 / np.sqrt(3)) and np.allclose(net.lengths(net.X), net.l0)
    piv = net.phi0[lat.spring_sets["pivot"]]
    assert np.allclose(np.abs(piv), np.pi / 3), "pivot rest angles +-pi/3"
    assert np.abs(net.gradient(net.X)).max() < 1e-10, "reference state is stress free"
    assert np.allclose(net.X.max(0), [11 * np.sqrt(2) * 12.02, 7 * np.sqrt(2) * 12.02])


def test_bipantographic_bias_extension_runs_and_is_symmetric():
    from fabricsurf.network.bipantographic import bipantographic_lattice

    lat = bipantographic_lattice()
    res = solve_steps(lat.net, lat.bias_bcs(20.0), n_steps=4, reaction_sets={"g": lat.grip})
    F = np.array([r.reactions["g"] for r in res])
    assert np.all(np.diff(F[:, 0]) > 0) and np.all(np.abs(F[:, 1]) < 1e-8 * F[-1, 0])
    f = grid_fields(lat.grid, lat.net.X, res[-1].x, lat.spacing)
    ok = ~np.isnan(f["rho_x"])
    assert ok.sum() > 100 and np.nanmax(np.abs(f["shear"])) > 0.05, "bias test shears the beams"
    print(f"\nbi-pantographic grip force (N) at u = {[20 * r.t for r in res]} mm: {F[:, 0]}")
