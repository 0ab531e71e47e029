"""Spring-network engine [B §3]: derivatives, invariance, analytic forces, Newton."""

import numpy as np
import pytest

from fabricsurf.network.engine import SpringNetwork
from fabricsurf.network.equilibrium import (
    ConvergenceError,
    Dirichlet,
    newton,
    reaction,
    solve_steps,
)


def random_network(seed=0, n=12, locking=False):
    """Random pre-stressed network; ``locking`` adds quartic, sextic and saturating (friction)
    rotational terms."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(0, 10, (n, 2))
    ext = np.array([(i, (i + 1) % n) for i in range(n)] + [(i, (i + 5) % n) for i in range(n)])
    rot = np.array(
        [(i, (i + 1) % n, (i + 2) % n) for i in range(n)]
        + [(i, (i + 3) % n, (i + 7) % n) for i in range(n)]
    )
    k4, k6, mf = rng.uniform(1, 3, (3, len(rot))) if locking else (0.0, 0.0, 0.0)
    net = SpringNetwork(
        X,
        ext,
        rng.uniform(1, 3, len(ext)),
        rot=rot,
        k_rot=rng.uniform(1, 3, len(rot)),
        k_rot4=k4,
        k_rot6=k6,
        m_fric=mf,
        phi_f=0.3,
    )
    # rest state different from reference: springs are pre-stressed
    net.l0 *= rng.uniform(0.8, 1.2, len(ext))
    net.phi0 = rng.uniform(-np.pi, np.pi, len(rot))
    x = X + rng.normal(0, 0.5, X.shape)
    return net, x


@pytest.mark.parametrize("locking", [False, True])
def test_gradient_matches_finite_differences(locking):
    net, x = random_network(locking=locking)
    g = net.gradient(x).ravel()
    h = 1e-6
    fd = np.empty_like(g)
    q = x.ravel()
    for a in range(len(q)):
        e = np.zeros_like(q)
        e[a] = h
        fd[a] = (net.energy(q + e) - net.energy(q - e)) / (2 * h)
    err = np.abs(fd - g).max() / np.abs(g).max()
    assert err < 1e-7, f"analytic gradient differs from central FD by {err:.2e} (relative)"


@pytest.mark.parametrize("locking", [False, True])
def test_hessian_matches_finite_differences(locking):
    net, x = random_network(seed=1, locking=locking)
    H = net.hessian(x).toarray()
    assert np.allclose(H, H.T, atol=1e-12), "Hessian must be symmetric"
    q = x.ravel()
    h = 1e-6
    fd = np.empty_like(H)
    for a in range(len(q)):
        e = np.zeros_like(q)
        e[a] = h
        fd[:, a] = (net.gradient(q + e).ravel() - net.gradient(q - e).ravel()) / (2 * h)
    err = np.abs(fd - H).max() / np.abs(H).max()
    assert err < 1e-6, f"sparse Hessian differs from FD of the gradient by {err:.2e} (relative)"


def test_angles_are_wrap_safe():
    # rest turning angle pi - 0.01, current turning angle -(pi - 0.01): the atan2 branch
    # cut lies between them; the deviation must be +0.02, not -2 pi + 0.02.
    X = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.01]])
    net = SpringNetwork(X, np.zeros((0, 2)), 1.0, rot=[[0, 1, 2]], k_rot=1.0)
    y = X.copy()
    y[2, 1] = -0.01
    d = net.angle_deviations(y)[0]
    assert abs(d - 0.02) < 1e-4, f"deviation across the atan2 cut must be ~0.02, got {d}"


@pytest.mark.parametrize("seed", [0, 3])
def test_rigid_motions_give_zero_force(seed):
    net, _ = random_network(seed)
    net.l0 = net.lengths(net.X)
    net.phi0 = net.turning_angles(net.X)
    c, s = np.cos(2.5), np.sin(2.5)  # a large rotation, past the atan2 cut for some arms
    x = net.X @ np.array([[c, s], [-s, c]]) + np.array([3.0, -7.0])
    f = np.abs(net.gradient(x)).max()
    assert f < 1e-10, f"rigid motion of the rest state must give zero force, got {f:.2e} N"
    assert net.energy(x) < 1e-20


def test_nonlinear_rotational_spring_energy_is_the_polynomial():
    """One spring turned by d: E = ½k d² + ¼k₄ d⁴ + ⅙k₆ d⁶, moment E' = k d + k₄ d³ + k₆ d⁵
    (lever arm 1 mm: the force on the free node is E' in N)."""
    k, k4, k6, d = 2.0, 3.0, 5.0, 0.6
    X = np.array([[-1.0, 0.0], [0.0, 0.0], [1.0, 0.0]])
    net = SpringNetwork(X, np.zeros((0, 2)), 1.0, rot=[[0, 1, 2]], k_rot=k, k_rot4=k4, k_rot6=k6)
    x = X.copy()
    x[2] = [np.cos(d), np.sin(d)]
    assert abs(net.energy(x) - (k * d**2 / 2 + k4 * d**4 / 4 + k6 * d**6 / 6)) < 1e-14
    f = net.gradient(x)[2]  # dE/dx_k = E'(d) (perpendicular to the arm, |arm| = 1)
    assert np.allclose(
        f, (k * d + k4 * d**3 + k6 * d**5) * np.array([-np.sin(d), np.cos(d)]), rtol=1e-13, atol=0
    )


def test_friction_spring_energy_and_moment_saturate():
    """One friction spring turned by d: E = m φ ln cosh(d/φ), moment E' = m tanh(d/φ), which
    is m (to 1e-12) once d ≫ φ and whose slope at d = 0 is m/φ."""
    m, phi = 2.0, 0.02
    X = np.array([[-1.0, 0.0], [0.0, 0.0], [1.0, 0.0]])
    net = SpringNetwork(X, np.zeros((0, 2)), 1.0, rot=[[0, 1, 2]], m_fric=m, phi_f=phi)
    for d in (0.01, 0.6):
        x = X.copy()
        x[2] = [np.cos(d), np.sin(d)]
        assert abs(net.energy(x) - m * phi * np.log(np.cosh(d / phi))) < 1e-13
        f = net.gradient(x)[2]
        assert np.allclose(
            f, m * np.tanh(d / phi) * np.array([-np.sin(d), np.cos(d)]), rtol=1e-13, atol=0
        )
    assert abs(np.linalg.norm(f) - m) < 1e-12
    H = net.hessian(X).toarray()  # at d = 0: k_eff = m/φ on the free node's normal direction
    assert abs(H[5, 5] - m / phi) < 1e-9 * m / phi


def chain(n=11, length=10.0):
    X = np.stack([np.linspace(0, length, n), np.zeros(n)], axis=1)
    ext = np.array([(i, i + 1) for i in range(n - 1)])
    rot = np.array([(i, i + 1, i + 2) for i in range(n - 2)])
    return SpringNetwork(X, ext, 2.0, rot=rot, k_rot=0.5)


def test_homogeneous_stretch_gives_analytic_force():
    # square grid, springs along x and y with k; stretch lam along x: force = rows * k * (lam-1) h
    nx, ny, h, k = 6, 4, 2.0, 3.0
    X = np.array([(i * h, j * h) for j in range(ny) for i in range(nx)], float)
    nid = np.arange(nx * ny).reshape(ny, nx)
    ext = np.concatenate(
        [
            np.stack([nid[:, :-1].ravel(), nid[:, 1:].ravel()], 1),
            np.stack([nid[:-1].ravel(), nid[1:].ravel()], 1),
        ]
    )
    # shear springs (right, node, up) keep the grid from being a mechanism; no shear here
    rot = np.stack([nid[:-1, 1:].ravel(), nid[:-1, :-1].ravel(), nid[1:, :-1].ravel()], 1)
    net = SpringNetwork(X, ext, k, rot=rot, k_rot=5.0)
    lam = 1.3
    bcs = [Dirichlet(nid[:, 0], [0.0, 0.0]), Dirichlet(nid[:, -1], [(lam - 1) * (nx - 1) * h, 0.0])]
    res = solve_steps(net, bcs, n_steps=2, reaction_sets={"grip": nid[:, -1]})
    F = res[-1].reactions["grip"]
    assert np.allclose(res[-1].x[:, 0], lam * X[:, 0]), "stretch must be homogeneous"
    assert abs(F[0] - ny * k * (lam - 1) * h) < 1e-8, f"grip force {F[0]} != analytic"
    assert abs(F[1]) < 1e-8


def test_newton_bends_chain_and_reaction_balances():
    net = chain()
    bcs = [Dirichlet(np.array([0, 1])), Dirichlet(np.array([9, 10]), [-2.0, 3.0])]
    res = solve_steps(net, bcs, n_steps=4, reaction_sets={"a": [0, 1], "b": [9, 10]})
    last = res[-1]
    assert all(r.iterations < 15 for r in res)
    # equilibrium: reactions at both ends balance (no external load elsewhere)
    assert np.allclose(last.reactions["a"], -last.reactions["b"], atol=1e-8)
    free = np.arange(2, 9)
    assert np.abs(net.gradient(last.x)[free]).max() < 1e-8
    assert np.allclose(reaction(net, last.x, [9, 10]), last.reactions["b"])


def test_newton_from_equilibrium_takes_no_iteration():
    net = chain()
    fixed = np.zeros(net.n_dofs, bool)
    fixed[:4] = True
    _, info = newton(net, net.X, fixed)
    assert info.converged and info.iterations == 0


def test_step_cutting_raises_clear_error():
    net = chain()
    # a large transverse pull (finite rotation of the chain) cannot converge in 2 iterations,
    # even from the tangent predictor, at any step above min_step
    bcs = [Dirichlet(np.array([0, 1])), Dirichlet(np.array([9, 10]), [0.0, 30.0])]
    with pytest.raises(ConvergenceError, match="min_step"):
        solve_steps(net, bcs, n_steps=1, min_step=0.2, newton_kw={"maxit": 2})


def test_stops_land_exactly_and_match_states_solved_from_rest():
    """The energy has no history: the state a continuation passes through at a stop equals the
    state solved from rest at that load (to Newton's tolerance), and every stop is a step end."""
    net = chain()
    end = np.array([-2.0, 3.0])
    stops = [0.3, 0.55, 0.8]
    bcs = [Dirichlet(np.array([0, 1])), Dirichlet(np.array([9, 10]), end)]
    res = solve_steps(net, bcs, n_steps=2, stops=stops, reaction_sets={"b": [9, 10]})
    at = {round(r.t, 12): r for r in res}
    assert set(stops) | {1.0} <= set(at)
    for s in stops:
        alone = [Dirichlet(np.array([0, 1])), Dirichlet(np.array([9, 10]), s * end)]
        ref = solve_steps(net, alone, n_steps=4, reaction_sets={"b": [9, 10]})[-1]
        assert np.abs(at[s].x - ref.x).max() < 1e-8
        assert np.allclose(at[s].reactions["b"], ref.reactions["b"], atol=1e-8)
