"""yarn_slip (fabricsurf/model/slip.py) against its lattice generator: slipping fibre springs of
the Hencky lattice (fabricsurf/network/engine.py), docs/woven_fabric.md "The large-shear range".

The continuum term and the lattice agree exactly on affine placements (node energy = density ×
node area, to round-off) and so on the force curve of a strip pulled along its fibres, which is
affine; on the bias test the slipping lattice follows the sticking one until its fibre tensions
reach the slip tension and then falls below it: the effect the term stands for.
"""

from types import SimpleNamespace

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.inverse.diagnosis.report import look_alikes
from fabricsurf.model import kinematics as kn
from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.slip import YarnSlip
from fabricsurf.model.terms import EFFECTS, CrossoverFriction, FibreStretch, Shear
from fabricsurf.network.engine import SpringNetwork
from fabricsurf.network.equilibrium import Dirichlet, solve_steps
from fabricsurf.network.hencky import hencky_lattice
from fabricsurf.network.hencky_moduli import continuum_from_lattice, lattice_from_continuum

pytestmark = pytest.mark.serial(
    "numpy lattices and one cell's density: nothing parallel "
    "(the term's forms run on 2 ranks in every diagnosis test)"
)

K_L, K_S, TAU_F = 2.0, 0.3, 0.05  # post-slip fibre stiffness, shear, friction (N/mm)
T_S, EPS_S = 0.4, 0.01  # slip tension (N/mm) and slip strain


def _densities(Fs: list, angles, model) -> np.ndarray:
    """Rows (γ, W, ∂W/∂F[0, 0]) of ``model``'s UFL densities at the homogeneous gradients
    ``Fs`` (one compiled expression, F a constant)."""
    msh = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    Fc = fem.Constant(msh, np.zeros((2, 2)))
    Fv = ufl.variable(Fc)
    kin = Kinematics(Fv, None, *kn.fibre_directions(*angles))
    W = sum(t.density(kin, t.values()) for t in model)
    expr = fem.Expression(
        ufl.as_vector([kin.gamma, W, ufl.diff(W, Fv)[0, 0]]), np.array([[1 / 3, 1 / 3]])
    )
    out = []
    for F in Fs:
        Fc.value[:] = F
        out.append(expr.eval(np.array([0], dtype=np.int32))[0])
    return np.array(out)


def test_term_is_registered_and_checks_its_options():
    assert EFFECTS["yarn_slip"] is YarnSlip and YarnSlip.parameters() == ["T_s"]
    with pytest.raises(ValueError, match=r"yarn_slip.*T_s"):
        YarnSlip(T_s=-1.0)
    with pytest.raises(ValueError, match=r"yarn_slip.*eps_s"):
        YarnSlip(T_s=1.0, eps_s=0.0)


def test_one_force_curve_is_declared_unable_to_tell_yarn_slip_from_grip_slip():
    """The diagnosis output names the look-alike and the data that would separate them, for
    force curves of one size only; a field, or a second size, lifts the statement."""

    def exp(field, length=230.0):
        return SimpleNamespace(has_field=field, length=length, width=115.0)

    out = look_alikes(["shear", "yarn_slip", "yarn_slip"], [exp(False)])
    assert [q["effect"] for q in out] == ["yarn_slip"]
    assert "grips" in out[0]["reason"] and len(out[0]["identified_by"]) == 3
    assert look_alikes(["yarn_slip"], [exp(True)]) == []
    assert look_alikes(["yarn_slip"], [exp(False), exp(False, 450.0)]) == []


def test_slipping_springs_gradient_and_hessian_are_exact():
    """Finite differences of the energy and of the gradient (central, step 1e-6) on springs
    in every regime: sticking, slipping in tension and in compression."""
    X = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.2]])
    net = SpringNetwork(
        X,
        [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]],
        k_ext=[1.0, 2.0, 0.5, 1.5, 0.3],
        f_slip=[0.2, 0.5, 0.1, 0.3, 0.4],
        eps_slip=0.02,
    )
    x = X + np.array([[0.0, 0.0], [0.08, 0.01], [0.0, 0.002], [-0.03, -0.05]])
    ls = (net.lengths(x) - net.l0) / net.l0
    assert ls.max() > 2 * 0.02 and ls.min() < -2 * 0.02 and np.abs(ls).min() < 0.02
    g, H, h = net.gradient(x).ravel(), net.hessian(x).toarray(), 1e-6
    for i in range(x.size):
        dx = np.zeros(x.size)
        dx[i] = h
        e = (
            net.energy((x.ravel() + dx).reshape(-1, 2))
            - net.energy((x.ravel() - dx).reshape(-1, 2))
        ) / (2 * h)
        gh = (
            net.gradient((x.ravel() + dx).reshape(-1, 2)).ravel()
            - net.gradient((x.ravel() - dx).reshape(-1, 2)).ravel()
        ) / (2 * h)
        assert abs(e - g[i]) < 1e-7 and np.abs(gh - H[:, i]).max() < 1e-6


@pytest.mark.parametrize("angles", [(45.0, -45.0), (40.0, -40.0)])
def test_affine_node_energy_is_the_continuum_density(angles):
    """Stretch in the slipping range plus a large shear: the energy of each interior node equals
    the UFL density of fibre_stretch + shear + crossover_friction + yarn_slip times the node area
    ε² sin θ0, to round-off (the identification T_s = f_slip/(ε sin θ0) is exact)."""
    eps, F = 0.5, np.array([[1.3, 0.05], [0.0, 0.85]])
    k = lattice_from_continuum(K_L, K_S, 0.0, eps, angles, tau_f=TAU_F, T_s=T_S, eps_s=EPS_S)
    back = continuum_from_lattice(spacing=eps, angles_deg=angles, **k)
    assert np.isclose(back["T_s"], T_S, rtol=1e-14) and back["eps_s"] == EPS_S
    lat = hencky_lattice(8.0, 6.0, eps, angles, **k)
    net = lat.net
    ee, er = net.spring_energies(net.X @ F.T)
    pad = np.pad(lat.grid, 1, constant_values=-1)
    inner = lat.grid[
        (pad[2:, 1:-1] >= 0)
        & (pad[:-2, 1:-1] >= 0)
        & (pad[1:-1, 2:] >= 0)
        & (pad[1:-1, :-2] >= 0)
        & (lat.grid >= 0)
    ]
    node = (
        np.bincount(net.ext[:, 0], ee, net.n_nodes) + np.bincount(net.rot[:, 1], er, net.n_nodes)
    )[inner]
    model = [
        FibreStretch(k_l=K_L, k_m=K_L),
        Shear(k_s=K_S),
        CrossoverFriction(tau_f=TAU_F),
        YarnSlip(T_s=T_S, eps_s=EPS_S),
    ]
    gam, w, _ = _densities([F], angles, model)[0]
    lam = np.linalg.norm(F @ lat.L)
    assert abs(gam) > 0.3 and lam - 1 > 5 * EPS_S, "large shear, fibres slipping"
    assert len(inner) > 50
    assert np.allclose(
        node, w * eps**2 * np.sin(np.radians(angles[0] - angles[1])), rtol=1e-12, atol=0
    )


def test_strip_force_curve_is_the_terms_tension():
    """A 0/90 strip pulled along its L fibres (held layers at both ends, free long edges): the
    lattice's placement is affine, so its grip force is the term's tension ∂W/∂λ times the
    width its fibres carry (n rows × ε), at every displacement: through sticking (tension
    ≈ (k_l + T_s/ε_s)(λ − 1)), the slip onset and slipping (increment k_l per unit strain)."""
    eps, length, width = 1.0, 10.0, 4.0
    k = lattice_from_continuum(K_L, K_S, 0.0, eps, (0.0, 90.0), T_s=T_S, eps_s=EPS_S)
    lat = hencky_lattice(length, width, eps, (0.0, 90.0), **k)
    X = lat.net.X
    ends = np.flatnonzero((X[:, 0] < 1e-9) | (X[:, 0] > length - 1e-9))
    rows = len(np.unique(np.round(X[:, 1], 9)))
    u_end = 0.06 * length  # λ − 1 up to 0.06 = 6 ε_s
    bc = Dirichlet(ends, np.where(X[ends, :1] > 1, [u_end, 0.0], [0.0, 0.0]))
    res = solve_steps(lat.net, [bc], n_steps=12, reaction_sets={"grip": ends[X[ends, 0] > 1]})
    model = [FibreStretch(k_l=K_L, k_m=K_L), YarnSlip(T_s=T_S, eps_s=EPS_S)]
    lattice = [r.reactions["grip"][0] for r in res]
    Fs = [np.diag([1 + r.t * u_end / length, 1.0]) for r in res]
    continuum = _densities(Fs, (0.0, 90.0), model)[:, 2] * rows * eps
    assert np.allclose(lattice, continuum, rtol=1e-9, atol=1e-12)
    tension = continuum / (rows * eps)
    assert tension[-1] < T_S + K_L * 0.06 + 1e-12, "capped at T_s plus the hardening"
    assert tension[0] > 0.9 * (K_L + T_S / EPS_S) * res[0].t * 0.06, "stiff while it sticks"


def _bias(k_l: float, T_s: float, d: np.ndarray) -> np.ndarray:
    """Grip force of a 46 × 92 mm bias lattice (ε = 4.6 mm) with ``shear`` + friction +
    locking springs at displacements ``d`` (mm)."""
    k = lattice_from_continuum(
        k_l, 0.02, 0.0, 4.6 * np.sqrt(2), k4=0.2, tau_f=0.0025, T_s=T_s, eps_s=EPS_S
    )
    lat = hencky_lattice(92.0, 46.0, 4.6 * np.sqrt(2), **k)
    res = solve_steps(
        lat.net, lat.bias_bcs(float(d[-1])), n_steps=len(d), reaction_sets={"grip": lat.grip}
    )
    t = np.array([r.t for r in res])
    return np.interp(d / d[-1], t, [r.reactions["grip"][0] for r in res])


def test_slip_softens_the_bias_lattice_once_the_fibres_reach_the_slip_tension():
    """The sticking net (fibre stiffness k_l + T_s/ε_s, no slip) against the slipping one
    (k_l + slip at T_s): the same force while the fibre tensions stay well below T_s (there
    tanh x = x to x²/3 < 1 %), then below it by a share that grows with the shear angle, by
    more than ten times a 1 % force error (Cao et al.'s digitising error) as zone C passes
    60° (measured: 34 % at 75°)."""
    d = np.linspace(1.0, 18.5, 8)  # zone C: 2.5° ... 75° (Cao et al. 2008 eq. 13, H − W = 46)
    stick = _bias(K_L + 0.1 / EPS_S, 0.0, d)
    slip = _bias(K_L, 0.1, d)
    ratio = slip / stick
    assert abs(ratio[0] - 1) < 0.01 and abs(ratio[1] - 1) < 0.01
    assert np.all(np.diff(ratio[1:]) < 0), "the slipping share grows with the angle"
    assert ratio[-1] < 0.9
    assert np.all(np.diff(slip) > 0), "slip caps the force's growth, it does not unload"


def test_small_stretch_stiffness_is_the_densitys_second_derivative():
    """d²W/dλ² at λ = 1 of fibre_stretch + yarn_slip, by central differences of the UFL
    tension ∂W/∂F₁₁ (0/90 fibres, F = diag(1 ± δ, 1)), is k_l + T_s/ε_s: the sticking yarns'
    stiffness that the locking ratio must use, 21 times k_l here."""
    model = [FibreStretch(k_l=K_L, k_m=K_L), YarnSlip(T_s=T_S, eps_s=EPS_S)]
    delta = 1e-5 * EPS_S
    t = _densities([np.diag([1 + delta, 1.0]), np.diag([1 - delta, 1.0])], (0.0, 90.0), model)[:, 2]
    fd = (t[0] - t[1]) / (2 * delta)
    assert sum(m.small_stretch_stiffness() for m in model) == pytest.approx(K_L + T_S / EPS_S)
    assert fd == pytest.approx(K_L + T_S / EPS_S, rel=1e-6)


def test_locking_ratio_counts_the_sticking_yarns():
    """K/k_s with yarn_slip is (k_l + T_s/ε_s)/k_s = 140 here, above the ratio from which a
    mesh not aligned with the fibres locks (LOCKING_RATIO = 100): the run must warn. Taking the
    tension T_s for a stiffness gave max(k_l, T_s)/k_s = 6.7 and no warning."""
    from fabricsurf.experiments import bias_mesh as disc

    model = [FibreStretch(k_l=K_L, k_m=K_L), Shear(k_s=K_S), YarnSlip(T_s=T_S, eps_s=EPS_S)]
    assert disc.stiffness_ratio(model) == pytest.approx((K_L + T_S / EPS_S) / K_S)
    assert disc.may_lock("gmsh", "full", disc.stiffness_ratio(model))
    assert not disc.may_lock("gmsh", "full", disc.stiffness_ratio(model[:2]))


def test_lattice_data_carries_hidden_slip():
    """Synthetic bias data (fabricsurf.inverse.synthetic.lattice_data) with a hidden slip
    tension: the same force as the sticking net (fibre stiffness k_l + T_s/ε_s) at the first
    displacement, where the fibre tensions stay far below T_s, and below it by more than 10 %
    once zone C passes 60° (the share test_slip_softens_the_bias_lattice... measures on the
    lattice directly); the field carries the slip as fibre stretch of the crossings' spacing."""
    from fabricsurf.inverse.synthetic import generate as sy

    d = [1.0, 18.5]  # zone C at about 2.5° and 75° (H − W = 46 mm)

    def data(k_l, T_s):
        exp = sy.template(92.0, 46.0, d, np.zeros((0, 2)), name="slip")
        kw = dict(k4=0.2, tau_f=0.0025, T_s=T_s, eps_s=EPS_S)
        return sy.lattice_data(exp, 4.6 * np.sqrt(2), k_l=k_l, k_s=0.02, A_g=0.0, **kw)

    slip, stick = data(K_L, 0.1), data(K_L + 0.1 / EPS_S, 0.0)
    ratio = slip.force / stick.force
    assert abs(ratio[0] - 1) < 0.01
    assert ratio[1] < 0.9
