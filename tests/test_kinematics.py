"""Kinematic quantities of closed-form placements equal their exact values
(docs/verification.md).

The placements are UFL expressions of the reference coordinates, so F = ∇r and H = ∇∇r are
exact and every kinematic function is tested without discretisation error.
"""

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.model import kinematics as kn
from fabricsurf.model.kinematics import Kinematics, fibre_directions

TOL = 1e-11
REF_POINTS = np.array([[0.2, 0.3], [0.6, 0.1], [0.25, 0.5]])  # reference-cell points


@pytest.fixture(scope="module")
def msh():
    return dmesh.create_rectangle(MPI.COMM_WORLD, [np.zeros(2), np.array([2.0, 1.5])], [3, 2])


def evaluate(msh, expr):
    """Values of a scalar/vector UFL expression at REF_POINTS in every local cell, plus the
    physical coordinates of those points."""
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    vals = fem.Expression(expr, REF_POINTS).eval(cells)
    xs = fem.Expression(ufl.SpatialCoordinate(msh), REF_POINTS).eval(cells)
    shape = ufl.shape(expr)
    return vals.reshape(len(cells) * len(REF_POINTS), *shape), xs.reshape(-1, 2)


def kin_of(msh, r_fn, angles):
    x = ufl.SpatialCoordinate(msh)
    r = r_fn(x)
    L, M = fibre_directions(*angles)
    return Kinematics(ufl.grad(r), ufl.grad(ufl.grad(r)), L, M)


def check(msh, expr, exact_fn):
    vals, xs = evaluate(msh, expr)
    exact = np.array([exact_fn(*p) for p in xs]).reshape(vals.shape)
    assert np.max(np.abs(vals - exact), initial=0.0) < TOL


def test_homogeneous_stretch_along_fibres(msh):
    a, b = 1.3, 0.8
    k = kin_of(msh, lambda x: ufl.as_vector((a * x[0], b * x[1])), (0.0, 90.0))
    check(msh, k.lam, lambda x, y: a)
    check(msh, k.mu, lambda x, y: b)
    check(msh, k.gamma, lambda x, y: 0.0)
    check(msh, k.J, lambda x, y: a * b)
    for q in (k.geodesic_l, k.geodesic_m, k.dlam_dL, k.dmu_dM):
        check(msh, q, lambda x, y: 0.0)


def test_homogeneous_stretch_bias_fibres(msh):
    """Stretch a along x with fibres at ±45°: λ = μ = √((a²+1)/2), sin γ = (a²−1)/(a²+1), J = a."""
    a = 1.4
    k = kin_of(msh, lambda x: ufl.as_vector((a * x[0], x[1])), (45.0, -45.0))
    check(msh, k.lam, lambda x, y: np.sqrt((a**2 + 1) / 2))
    check(msh, k.mu, lambda x, y: np.sqrt((a**2 + 1) / 2))
    check(msh, k.gamma, lambda x, y: np.arcsin((a**2 - 1) / (a**2 + 1)))
    check(msh, k.J, lambda x, y: a)


def test_simple_shear(msh):
    """r = (x + s y, y): λ = 1, μ = √(1+s²), γ = atan s, J = 1."""
    s = 0.7
    k = kin_of(msh, lambda x: ufl.as_vector((x[0] + s * x[1], x[1])), (0.0, 90.0))
    check(msh, k.lam, lambda x, y: 1.0)
    check(msh, k.mu, lambda x, y: np.sqrt(1 + s**2))
    check(msh, k.gamma, lambda x, y: np.arctan(s))
    check(msh, k.J, lambda x, y: 1.0)


def test_in_plane_bending_and_stretch_gradient(msh):
    """Ring map r = (R+y)(sin(x/R), cos(x/R)): λ²η_l = p·r_LL = −(R+y)/R², ∂_Lλ = 0;
    r = (x + c x²/2, y): ∂_Lλ = c, λ²η_l = 0."""
    R = 3.0
    ring = kin_of(
        msh,
        lambda x: (R + x[1]) * ufl.as_vector((ufl.sin(x[0] / R), ufl.cos(x[0] / R))),
        (0.0, 90.0),
    )
    check(msh, ring.lam, lambda x, y: (R + y) / R)
    check(msh, ring.geodesic_l, lambda x, y: -(R + y) / R**2)
    check(msh, ring.dlam_dL, lambda x, y: 0.0)
    check(msh, ring.geodesic_m, lambda x, y: 0.0)
    c = 0.4
    grad = kin_of(msh, lambda x: ufl.as_vector((x[0] + 0.5 * c * x[0] ** 2, x[1])), (0.0, 90.0))
    check(msh, grad.dlam_dL, lambda x, y: c)
    check(msh, grad.geodesic_l, lambda x, y: 0.0)
    check(msh, ufl.dot(grad.g_l, grad.g_l), lambda x, y: c**2)


def cylinder(R):
    return lambda x: ufl.as_vector((R * ufl.sin(x[0] / R), x[1], R * (1 - ufl.cos(x[0] / R))))


def test_cylinder_fibres_along_axes(msh):
    """Cylinder of radius R, L around it: K_L = 1/R, K_M = T = 0, g = Γ = 0, n exact."""
    R = 2.5
    k = kin_of(msh, cylinder(R), (0.0, 90.0))
    check(msh, k.lam, lambda x, y: 1.0)
    check(msh, k.K_L, lambda x, y: 1 / R)
    check(msh, k.K_M, lambda x, y: 0.0)
    check(msh, k.T, lambda x, y: 0.0)
    check(msh, k.n, lambda x, y: [-np.sin(x / R), 0.0, np.cos(x / R)])
    for v in (k.g_l, k.g_m, k.Gamma):
        check(msh, v, lambda x, y: [0.0, 0.0, 0.0])


def test_cylinder_bias_fibres(msh):
    """Fibres at ±45° on the cylinder: r_LL = r_MM = r_LM = r_xx/2. M is L rotated by −90°, so
    n = FL×FM/|FL×FM| = −r_x×r_y/|r_x×r_y| (eq. 16) and K_L = K_M = T = −1/(2R)."""
    R = 2.5
    k = kin_of(msh, cylinder(R), (45.0, -45.0))
    check(msh, k.K_L, lambda x, y: -1 / (2 * R))
    check(msh, k.K_M, lambda x, y: -1 / (2 * R))
    check(msh, k.T, lambda x, y: -1 / (2 * R))
    check(msh, k.gamma, lambda x, y: 0.0)


def test_hyperbolic_paraboloid(msh):
    """r = a θ1θ2 + b θ1 + c θ2 (Steigmann & dell'Isola 2015 eqs. 98-102): λl = aθ2 + b, μm = aθ1 +
    c,
    r_LL = r_MM = 0 so K_L = K_M = 0 and g_l = g_m = 0; Γ + T n = a; λμ sin γ from eq. 100."""
    a, b, c = np.array([0.2, -0.1, 0.5]), np.array([1.1, 0.1, 0.0]), np.array([0.05, 0.9, 0.1])
    k = kin_of(
        msh,
        lambda x: (
            ufl.as_vector(a) * x[0] * x[1] + ufl.as_vector(b) * x[0] + ufl.as_vector(c) * x[1]
        ),
        (0.0, 90.0),
    )
    check(msh, k.lam, lambda x, y: np.linalg.norm(a * y + b))
    check(msh, k.mu, lambda x, y: np.linalg.norm(a * x + c))
    check(
        msh,
        k.lam * k.mu * kn.sin_gamma(k.F, k.L, k.M),
        lambda x, y: a @ a * x * y + a @ b * x + a @ c * y + b @ c,
    )
    check(msh, k.K_L, lambda x, y: 0.0)
    check(msh, k.K_M, lambda x, y: 0.0)
    for v in (k.g_l, k.g_m):
        check(msh, v, lambda x, y: [0.0, 0.0, 0.0])
    check(msh, k.Gamma + k.T * k.n, lambda x, y: a)

    def n_exact(x, y):
        v = np.cross(a * y + b, a * x + c)
        return v / np.linalg.norm(v)

    check(msh, k.T, lambda x, y: a @ n_exact(x, y))


def test_2d_quantities_reject_3d_only():
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 1, 1)
    k = kin_of(msh, lambda x: x, (0.0, 90.0))
    with pytest.raises(ValueError, match="needs a placement in 3D"):
        _ = k.K_L


def test_parallel_or_non_finite_fibres_rejected():
    with pytest.raises(ValueError, match="parallel fibre families"):
        fibre_directions(30.0, 210.0)
    with pytest.raises(ValueError, match="family M = nan is not a finite number"):
        fibre_directions(30.0, float("nan"))


# ---------------------------------------------------- non-orthogonal reference fibres
def fibre_quantities(k):
    """(λ, μ, γ, J) as one UFL vector: one compiled expression per placement."""
    return ufl.as_vector([k.lam, k.mu, k.gamma, k.J])


def test_stretch_along_a_skew_fibre(msh):
    """L = e_x, M at 60°; r = (a x, y): λ = a, FM = (a/2, √3/2), θ = atan2(√3/2, a/2),
    γ = 60° − θ, and J = det F = a (λ μ sin θ = |FL × FM| = det F sin θ0 in 2D)."""
    a = 1.3
    k = kin_of(msh, lambda x: ufl.as_vector((a * x[0], x[1])), (0.0, 60.0))
    fm = np.array([a / 2, np.sqrt(3) / 2])
    check(
        msh,
        fibre_quantities(k),
        lambda x, y: [a, np.linalg.norm(fm), np.pi / 3 - np.arctan2(fm[1], fm[0]), a],
    )


def test_simple_shear_of_skew_fibres(msh):
    """L = e_x, M at 60°; r = (x + s y, y): λ = 1, FM = (1/2 + s√3/2, √3/2), γ = 60° − θ
    (positive: the fibre angle closes), J = 1. For s < 0 the angle opens: γ < 0."""
    for s in (0.7, -0.4):
        k = kin_of(msh, lambda x, s=s: ufl.as_vector((x[0] + s * x[1], x[1])), (0.0, 60.0))
        fm = np.array([0.5 + s * np.sqrt(3) / 2, np.sqrt(3) / 2])
        gam = np.pi / 3 - np.arctan2(fm[1], fm[0])
        assert np.sign(gam) == np.sign(s)
        check(msh, fibre_quantities(k), lambda x, y, fm=fm, g=gam: [1.0, np.linalg.norm(fm), g, 1])


def test_pure_shear_of_fibre_pairs_with_angles_as_constants(msh):
    """Pure shear F = diag(a, 1/a) of fibres at ±α: λ = μ = √(a² cos²α + sin²α/a²),
    l at atan(tan α/a²) from x, so γ = 2α − 2 atan(tan α/a²); J = 1. With the fibre directions
    as fem.Constants one compiled expression serves ±30° (braid) and ±40° (bias cut)."""
    a = 1.25
    L, M = fibre_directions(40.0, -40.0, msh)
    assert isinstance(L, fem.Constant) and isinstance(M, fem.Constant)
    x = ufl.SpatialCoordinate(msh)
    r = ufl.as_vector((a * x[0], x[1] / a))
    k = Kinematics(ufl.grad(r), None, L, M)
    expr = fem.Expression(fibre_quantities(k), REF_POINTS)
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    for alpha in (40.0, 30.0):
        L.value[:], M.value[:] = kn.fibre_vectors(alpha, -alpha)
        t = np.radians(alpha)
        lam = np.hypot(a * np.cos(t), np.sin(t) / a)
        exact = [lam, lam, 2 * t - 2 * np.arctan(np.tan(t) / a**2), 1.0]
        vals = expr.eval(cells).reshape(-1, 4)
        assert np.abs(vals - exact).max(initial=0.0) < TOL, f"±{alpha}°"
