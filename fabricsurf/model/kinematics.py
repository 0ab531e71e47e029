"""Kinematics of a fabric surface with two families of straight fibres (docs/theory.md, Steigmann &
dell'Isola 2015 §2-3).

The placement is r: Ω ⊂ R² → R^d (d = 2 or 3), F = ∇r (d×2) and H = ∇∇r (d×2×2), with
H[i, a, b] = ∂²r_i/∂X_a∂X_b. L and M are the constant unit reference fibre directions; they
need not be orthogonal (braids at ±30°, bias cuts at ±40°): θ0 = ∠(L, M) is the reference
angle between the fibres, θ = ∠(l, m) the current one, and the shear angle is γ = θ0 − θ
(Steigmann & dell'Isola 2015 eq. 8 for θ0 = 90°, where sin γ = l·m). Every function takes UFL
expressions (UFL or fem.Constant vectors for L, M) and returns UFL expressions; equation
numbers refer to Steigmann & dell'Isola 2015.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem


def value_dim(F: ufl.core.expr.Expr) -> int:
    """Dimension d of the space the surface lives in (rows of F)."""
    return ufl.shape(F)[0]


def lam(F, L):
    """Fibre stretch λ = |FL| (eq. 5)."""
    return ufl.sqrt(ufl.dot(F * L, F * L))


def mu(F, M):
    """Fibre stretch μ = |FM| (eq. 5)."""
    return ufl.sqrt(ufl.dot(F * M, F * M))


def l_dir(F, L):
    """Deformed unit tangent l = FL/λ of the L fibres (eq. 5)."""
    return F * L / lam(F, L)


def m_dir(F, M):
    """Deformed unit tangent m = FM/μ of the M fibres (eq. 5)."""
    return F * M / mu(F, M)


def cos_theta(F, L, M):
    """cos θ = l·m, θ the current angle between the fibres."""
    return ufl.dot(F * L, F * M) / (lam(F, L) * mu(F, M))


def theta0(L, M):
    """Reference angle θ0 = acos(L·M) between the fibre families (π/2 when orthogonal)."""
    return ufl.acos(ufl.dot(L, M))


def gamma(F, L, M):
    """Shear angle γ = θ0 − θ = acos(L·M) − acos(l·m): the closing of the fibre angle.

    Zero in the reference state; for orthogonal fibres γ = asin(l·m) (eq. 8). The derivative
    dγ = d(l·m)/sin θ is regular until the fibres become parallel.
    """
    return theta0(L, M) - ufl.acos(cos_theta(F, L, M))


def sin_gamma(F, L, M):
    """sin γ (= l·m for orthogonal reference fibres, eq. 8)."""
    return ufl.sin(gamma(F, L, M))


def J(F, L, M):
    """Areal stretch J = λ μ sin θ / sin θ0 (eq. 15 for θ0 = 90°; = det F in 2D)."""
    sin_t = ufl.sqrt(1 - cos_theta(F, L, M) ** 2)
    sin_t0 = ufl.sqrt(1 - ufl.dot(L, M) ** 2)
    return lam(F, L) * mu(F, M) * sin_t / sin_t0


def normal(F, L, M):
    """Unit normal n = FL×FM/|FL×FM| (eq. 16); in 2D the out-of-plane e_3 is implied (None)."""
    if value_dim(F) == 2:
        return None
    c = ufl.cross(F * L, F * M)
    return c / ufl.sqrt(ufl.dot(c, c))


def rotate_in_plane(v, n):
    """n × v: v rotated by +90° in the tangent plane (eq. 21); in 2D (n None) (-v_y, v_x)."""
    if n is None:
        return ufl.as_vector((-v[1], v[0]))
    return ufl.cross(n, v)


def second_derivative(H, A, B):
    """r_AB = H[A, B] = ∇∇r contracted with the reference directions A and B."""
    i, a, b = ufl.indices(3)
    return ufl.as_vector(H[i, a, b] * A[a] * B[b], i)


def tangential(v, n):
    """P v with P = I − n⊗n (identity in 2D)."""
    if n is None:
        return v
    return v - ufl.dot(v, n) * n


def K_L(H, n, L):
    """Normal curvature K_L = n·r_LL = λ²κ_l (eq. 61)."""
    return ufl.dot(n, second_derivative(H, L, L))


def K_M(H, n, M):
    """Normal curvature K_M = n·r_MM = μ²κ_m (eq. 61)."""
    return ufl.dot(n, second_derivative(H, M, M))


def T(H, n, L, M):
    """Twist T = n·r_LM = λμτ (eq. 61)."""
    return ufl.dot(n, second_derivative(H, L, M))


def g_l(H, n, L):
    """In-plane second-gradient vector g_l = P r_LL = λ²η_l p + (∂_L λ) l (eqs. 41, 58)."""
    return tangential(second_derivative(H, L, L), n)


def g_m(H, n, M):
    """In-plane second-gradient vector g_m = P r_MM = μ²η_m q + (∂_M μ) m (eqs. 41, 58)."""
    return tangential(second_derivative(H, M, M), n)


def Gamma(H, n, L, M):
    """Cross second-gradient vector Γ = P r_LM (eqs. 42, 59)."""
    return tangential(second_derivative(H, L, M), n)


def geodesic_l(F, H, n, L):
    """λ²η_l = g_l·p with p = n×l: geodesic-curvature part of g_l (eq. 58)."""
    return ufl.dot(second_derivative(H, L, L), rotate_in_plane(l_dir(F, L), n))


def geodesic_m(F, H, n, M):
    """μ²η_m = g_m·q with q = n×m (eq. 58)."""
    return ufl.dot(second_derivative(H, M, M), rotate_in_plane(m_dir(F, M), n))


def dlam_dL(F, H, L):
    """Stretch gradient ∂_L λ = L·∇λ = g_l·l (eq. 58)."""
    return ufl.dot(second_derivative(H, L, L), l_dir(F, L))


def dmu_dM(F, H, M):
    """Stretch gradient ∂_M μ = M·∇μ = g_m·m (eq. 58)."""
    return ufl.dot(second_derivative(H, M, M), m_dir(F, M))


@dataclass(frozen=True)
class Kinematics:
    """The kinematic quantities of one placement, as read by the energy terms' `density(kin)`.

    F = ∇r (d×2), H = ∇∇r (d×2×2, may be None for first-gradient use), L, M unit reference
    fibre directions (UFL or fem.Constant 2-vectors, not necessarily orthogonal).
    """

    F: ufl.core.expr.Expr
    H: ufl.core.expr.Expr | None
    L: ufl.core.expr.Expr
    M: ufl.core.expr.Expr

    @property
    def d(self) -> int:
        return value_dim(self.F)

    @property
    def lam(self):
        return lam(self.F, self.L)

    @property
    def mu(self):
        return mu(self.F, self.M)

    @property
    def gamma(self):
        return gamma(self.F, self.L, self.M)

    @property
    def J(self):
        return J(self.F, self.L, self.M)

    @property
    def n(self):
        return normal(self.F, self.L, self.M)

    def require_3d(self, what: str) -> None:
        if self.d != 3:
            raise ValueError(f"{what} needs a placement in 3D (d = 3), got d = {self.d}")

    @property
    def K_L(self):
        self.require_3d("K_L")
        return K_L(self.H, self.n, self.L)

    @property
    def K_M(self):
        self.require_3d("K_M")
        return K_M(self.H, self.n, self.M)

    @property
    def T(self):
        self.require_3d("T")
        return T(self.H, self.n, self.L, self.M)

    @property
    def g_l(self):
        return g_l(self.H, self.n, self.L)

    @property
    def g_m(self):
        return g_m(self.H, self.n, self.M)

    @property
    def Gamma(self):
        return Gamma(self.H, self.n, self.L, self.M)

    @property
    def geodesic_l(self):
        return geodesic_l(self.F, self.H, self.n, self.L)

    @property
    def geodesic_m(self):
        return geodesic_m(self.F, self.H, self.n, self.M)

    @property
    def dlam_dL(self):
        return dlam_dL(self.F, self.H, self.L)

    @property
    def dmu_dM(self):
        return dmu_dM(self.F, self.H, self.M)


MIN_SIN_THETA0 = 1e-6
"""Fibre families with |sin θ0| below this are rejected as parallel."""


def _finite_angle(family: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v):
        raise ValueError(
            f"fibre angle of family {family} = {value!r} is not a finite number "
            "(degrees from the x axis)"
        )
    return v


def fibre_vectors(
    angle_L_deg: float, angle_M_deg: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Unit reference fibre directions (numpy 2-vectors) at the given angles from the x axis.

    M defaults to L rotated by −90°. Any two distinct directions are accepted; parallel
    families (no shear angle) and non-finite angles are rejected.
    """
    if angle_M_deg is None:
        angle_M_deg = _finite_angle("L", angle_L_deg) - 90.0
    angle_L_deg, angle_M_deg = _finite_angle("L", angle_L_deg), _finite_angle("M", angle_M_deg)
    a, b = math.radians(angle_L_deg), math.radians(angle_M_deg)
    if abs(math.sin(a - b)) < MIN_SIN_THETA0:
        raise ValueError(
            f"fibre angles {angle_L_deg}° and {angle_M_deg}° give parallel fibre families: "
            "the two families must cross at a non-zero angle to define the shear angle"
        )
    return np.array([math.cos(a), math.sin(a)]), np.array([math.cos(b), math.sin(b)])


def fibre_directions(angle_L_deg: float, angle_M_deg: float | None = None, msh=None):
    """Unit reference fibre directions L, M at the given angles (degrees) from the x axis.

    Without ``msh``: UFL constant vectors (the angles are compiled into the forms). With a
    mesh: fem.Constant 2-vectors on it, so problems with different fibre angles share one
    compiled form; assign ``L.value[:] = ...`` (see :func:`fibre_vectors`) to change them
    in place. M defaults to L rotated by −90°; the families need not be orthogonal.
    """
    L, M = fibre_vectors(angle_L_deg, angle_M_deg)
    if msh is not None:
        return fem.Constant(msh, L), fem.Constant(msh, M)
    return ufl.as_vector(tuple(L)), ufl.as_vector(tuple(M))
