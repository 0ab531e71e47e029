"""Ready-made materials: term sets that are not part of the effect vocabulary (docs/theory.md).

Homogenised bi-pantographic fabric (Barchiesi et al. 2020, §2, eq. 2)
------------------------------------------------------
Seed 000 writes the deformation energy of the homogenised bi-pantographic fabric (Barchiesi et
al., its ref. [29]) per fibre family α ∈ {L, M} as (the text extraction of eq. 2 is garbled:
the fraction ``ρ²/(1/(2cos²γ))`` is ``2ρ²cos²γ``, and the last line is printed twice)::

    W = Σ_α { K_S [acos(1 − 2ρ_α²c²) − π + 2γ]²
              + K_E K_F [ (ρ_α²c² − 1) / (ρ_α²c²(K_E − 8K_F c²) − K_E) (∂θ_α/∂α)²
                        + ρ_α²c² / ((1 − ρ_α²c²)(8K_F + ρ_α²(K_E − 8K_F c²))) (∂ρ_α/∂α)² ] }

with c = cos γ, γ = π/6 the angle between the rhombus sides of a pantographic beam and its axis
(side length ε/√3, so a straight beam segment of length ε at ρ = 1). ∂χ/∂α = ρ_α(cos θ_α,
sin θ_α) defines the stretch ρ_α and the direction θ_α of the deformed fibre (Barchiesi et
al. 2020, eq. 1; the paper's x, y are the fibre directions, here L, M). In the kinematics of
this package (docs/theory.md): ρ_L = λ, ∂ρ_L/∂L = l·r_LL = ``kin.dlam_dL``, and since
r_LL = (∂_Lρ) l + ρ(∂_Lθ) p, ∂θ_L/∂L = p·r_LL/λ = ``kin.geodesic_l / kin.lam``; the same for M
with μ, ``geodesic_m``, ``dmu_dM``.

Checks of the reading: the first bracket vanishes at ρ = 1 when γ = π/6
(acos(1 − 3/2) = 2π/3 = π − 2γ); with θ the current side-to-axis angle, ρ = cos θ / cos γ, and
acos(1 − 2ρ²c²) − π + 2γ = 2(γ − θ): the change of the pivot angle at the rhombus side nodes,
so K_S is the pivot (k_r1) stiffness per unit area. Both second-gradient coefficients are
positive for 0 < ρc < 1 with the Table 3 moduli (K_E − 8K_F c² = −5070 N·mm < 0 and
8K_F + ρ²(K_E − 8K_F c²) > 0 for ρ < 1.19), and at ρ = 1 they are 17.97 N·mm (geodesic
bending) and 418.3 N·mm (stretch gradient).

Implementation notes
--------------------
* acos(1 − 2x²) = 2 asin(x) for x ∈ [0, 1]; the asin form is used because its UFL derivative
  (2/√(1 − x²)) has no 0/0 at x = 0, which the derivative of the acos form has.
* Domain: ρc < 1 is the geometric limit of a pantographic beam (fully opened rhombi:
  ρ_max = 1/cos γ = 1.155); the energy is not defined beyond (asin gives NaN), and the
  stretch-gradient coefficient a_ρ grows as 1/(1 − ρ²c²). A Newton iterate that crosses the
  limit gives a non-finite residual, which the solver reports to SNES as a domain error; with
  the backtracking line search (``fabricsurf.discretise.solver.DOMAIN_AWARE``) the step is
  shortened instead of failing (discretise/solver.py). A converged state has a finite
  residual: every quadrature point is inside the domain.
* Does the solution reach the limit? Measured in the bias test (Table 3, 187 × 119 mm, ±45°,
  benchmarks/bipantographic_range.py, 20 steps to ū = 50 mm): the largest stretch sits at the
  grip corners (y = 0 or 119 mm, 1.7–12 mm from the grip, closer on finer meshes) and grows
  smoothly with ū: ρc = 0.880, 0.894, 0.919, 0.941, 0.960, 0.978 at ū = 5, 10, 20, 30, 40,
  50 mm (level 2, position clamps). At ū = 50 mm: position clamps ρc = 0.984, 0.978, 0.977
  on levels 1, 2, 4; gradient clamps 0.966, 0.963 on levels 2, 4. The continuum solution
  does not reach the limit up to ū = 50 mm, and refinement does not push it there. The
  failures of earlier versions (Newton stalling near ū = 19.8 mm) were not the limit
  (ρc = 0.92 there) but the interior penalty (next item).
* Interior penalty. The C0-IP scale S of the second-gradient term (energy.py) is the sum of the
  two coefficients at ρ = ``penalty_stretch`` (default 1: ≈ 436 N·mm for Table 3). Because
  a_ρ grows as 1/(1 − ρ²c²) (×2.7 at ρ = 1.065, ×6.3 at 1.1, ×13 at 1.12), a penalty frozen at
  ρ = 1 stops dominating the consistency term where the stretch concentrates, and the
  discrete energy loses coercivity: measured on level 2 (position clamps) the smallest
  eigenvalue of the exact Hessian falls from 1.0e-3 (ū = 19 mm) to 5.2e-4 (19.9 mm), its
  eigenvector at the free edge, and Newton fails at 19.96 mm whatever the line search;
  with α = 32 instead of 8 the same run reaches 41.96 mm, and with S following the largest
  stretch (``fabricsurf.studies.bipantographic_range.PenaltyFollower``, ρ_p = max ρ + 0.03
  after each step, at most halfway from max ρ to the limit) it reaches 50 mm in 3–4 Newton
  iterations per step. A fixed ceiling (ρ_p c ≤ 0.97) is not enough: where the corner stretch
  passes it (position clamps, level 8, ρc = 0.971 at ū = 45 mm) Newton stalls again.
  ``penalty_stretch`` is a fem.Constant: following the stretch never recompiles.
* Regularisation (``bipantographic(limit_stretch=ρ_r)``, ρ_r c < 1): beyond ρ_r the pivot
  energy K_S g(ρ)² is replaced by its second-order Taylor polynomial at ρ_r and a_θ, a_ρ are
  frozen at their values there, so the energy is C² at ρ_r and defined for every stretch. It
  models what the micro model does past the fully opened rhombus: the rhombus sides, rigid in
  eq. (2), are extensible springs (k_e), so the beam keeps stretching against a stiff but
  finite stiffness W''(ρ_r) instead of a wall. Not needed in the bias test up to 50 mm (the
  limit is not reached); it changes nothing where ρ < ρ_r everywhere. Measured effect with
  ρ_r = 1.1 (ρ_r c = 0.953; level 2, position clamps, 20 steps): grip force unchanged to
  ū = 20 mm, −0.9 % at 30, −4.2 % at 40, −13.4 % at 50 mm (8.75 against 10.10 N), γ_B
  52.4° against 53.5° at 50 mm; the corner stretch rises to ρc = 0.994.
* Units (mm, N): K_S in N/mm (Table 3: 34 N/m = 0.034 N/mm), K_E and K_F in N·mm (Table 3:
  0.33 J = 330 N·mm, 0.9 J = 900 N·mm), γ in rad. All are fem.Constants once bound, so
  changing them does not recompile.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import ufl

from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.terms import Term

TABLE3_MACRO = {"K_S": 0.034, "K_E": 330.0, "K_F": 900.0}
"""Seed 000 Table 3, macro model, in N/mm, N·mm, N·mm."""


def _pivot(rho, c, gamma):
    """acos(1 − 2ρ²c²) − π + 2γ, written as 2 asin(ρc) − π + 2γ."""
    return 2 * ufl.asin(rho * c) - math.pi + 2 * gamma


def _coefficients(rho, K_E, K_F, c):
    """The two second-gradient coefficients of eq. 2 (N·mm): (bending, stretch gradient)."""
    x = rho**2 * c**2
    D = K_E - 8 * K_F * c**2
    a_theta = K_E * K_F * (x - 1) / (x * D - K_E)
    a_rho = K_E * K_F * x / ((1 - x) * (8 * K_F + rho**2 * D))
    return a_theta, a_rho


@dataclass
class PantographPivot(Term):
    """K_S Σ_α [acos(1 − 2ρ_α² cos²γ) − π + 2γ]²: pivot rotation of the pantographic
    rhombi as the beams stretch (Barchiesi et al. 2020, eq. 2, first line)."""

    K_S: float = TABLE3_MACRO["K_S"]
    gamma: float = math.pi / 6
    name: ClassVar[str] = "bipantographic_pivot"
    order: ClassVar[int] = 1
    units: ClassVar[dict[str, str]] = {"K_S": "N/mm", "gamma": "rad"}

    def density(self, kin: Kinematics):
        g = self.p("gamma")
        c = ufl.cos(g)
        return self.p("K_S") * (_pivot(kin.lam, c, g) ** 2 + _pivot(kin.mu, c, g) ** 2)


@dataclass
class PantographBending(Term):
    """K_E K_F Σ_α [a_θ(ρ_α)(∂θ_α/∂α)² + a_ρ(ρ_α)(∂ρ_α/∂α)²]: geodesic bending and stretch
    gradient of the pantographic beams (Barchiesi et al. 2020, eq. 2, second and third lines).

    ``penalty_stretch`` ρ_p (dimensionless, ρ_p cos γ < 1) is not a modulus: it is the stretch
    at which the interior-penalty scale S = a_θ(ρ_p) + a_ρ(ρ_p) is taken (module docstring,
    "Interior penalty"); changing it does not recompile.
    """

    K_E: float = TABLE3_MACRO["K_E"]
    K_F: float = TABLE3_MACRO["K_F"]
    gamma: float = math.pi / 6
    penalty_stretch: float = 1.0
    name: ClassVar[str] = "bipantographic_bending"
    order: ClassVar[int] = 2
    units: ClassVar[dict[str, str]] = {"K_E": "N·mm", "K_F": "N·mm", "gamma": "rad",
                                       "penalty_stretch": "1"}

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_below_limit(self.name, "penalty_stretch", self.penalty_stretch, self.gamma)

    def _coeffs(self, rho):
        return _coefficients(rho, self.p("K_E"), self.p("K_F"), ufl.cos(self.p("gamma")))

    def _stretch(self, rho):
        """The stretch at which the coefficients are evaluated (ρ itself; capped when
        regularised)."""
        return rho

    def density(self, kin: Kinematics):
        W = 0
        for rho, geo, drho in ((kin.lam, kin.geodesic_l, kin.dlam_dL),
                               (kin.mu, kin.geodesic_m, kin.dmu_dM)):
            a_theta, a_rho = self._coeffs(self._stretch(rho))
            W += a_theta * (geo / rho) ** 2 + a_rho * drho**2
        return W

    def stiffness_scale(self):
        """a_θ + a_ρ at ρ = ``penalty_stretch`` (the penalty scale S of energy.py)."""
        a_theta, a_rho = self._coeffs(self._stretch(self.p("penalty_stretch")))
        return a_theta + a_rho

    def reference_moduli(self) -> tuple[float, float]:
        """(a_θ, a_ρ) at ρ = 1 as floats (N·mm)."""
        return _coefficients(1.0, self.K_E, self.K_F, math.cos(self.gamma))

    def set(self, **values: float) -> None:
        if "penalty_stretch" in values:
            _check_below_limit(self.name, "penalty_stretch", values["penalty_stretch"],
                               values.get("gamma", self.gamma))
        super().set(**values)


def _check_below_limit(name: str, key: str, rho: float, gamma: float) -> None:
    if not float(rho) * math.cos(gamma) < 1.0:
        raise ValueError(f"term '{name}': {key} = {rho} must satisfy {key}·cos γ < 1 "
                         f"(< {1 / math.cos(gamma):.4f} for γ = {gamma:.4f})")


def _pivot_extension(rho, rho_r, K_S, gamma):
    """Second-order Taylor continuation of K_S g(ρ)² beyond ρ_r (g = 2 asin(ρc) − π + 2γ):
    W(ρ̂) + W'(ρ_r) δ + ½W''(ρ_r) δ², ρ̂ = min(ρ, ρ_r), δ = max(ρ − ρ_r, 0); C² at ρ_r."""
    c = ufl.cos(gamma)
    g = _pivot(rho_r, c, gamma)
    s = ufl.sqrt(1 - rho_r**2 * c**2)
    g1, g2 = 2 * c / s, 2 * c**3 * rho_r / s**3
    d = ufl.max_value(rho - rho_r, 0.0)
    inner = _pivot(ufl.min_value(rho, rho_r), c, gamma)
    return K_S * (inner**2 + 2 * g * g1 * d + (g1**2 + g * g2) * d**2)


@dataclass
class RegularisedPantographPivot(PantographPivot):
    """:class:`PantographPivot` continued beyond ``limit_stretch`` ρ_r (< 1/cos γ) by its
    second-order Taylor expansion (module docstring, "Regularisation")."""

    limit_stretch: float = 1.12
    units: ClassVar[dict[str, str]] = {"K_S": "N/mm", "gamma": "rad", "limit_stretch": "1"}

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_below_limit(self.name, "limit_stretch", self.limit_stretch, self.gamma)

    def density(self, kin: Kinematics):
        r, K, g = self.p("limit_stretch"), self.p("K_S"), self.p("gamma")
        return _pivot_extension(kin.lam, r, K, g) + _pivot_extension(kin.mu, r, K, g)


@dataclass
class RegularisedPantographBending(PantographBending):
    """:class:`PantographBending` with a_θ, a_ρ frozen at their values at ``limit_stretch``
    beyond it (module docstring, "Regularisation")."""

    limit_stretch: float = 1.12
    units: ClassVar[dict[str, str]] = {**PantographBending.units, "limit_stretch": "1"}

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_below_limit(self.name, "limit_stretch", self.limit_stretch, self.gamma)

    def _stretch(self, rho):
        return ufl.min_value(rho, self.p("limit_stretch"))


def bipantographic(K_S: float = TABLE3_MACRO["K_S"], K_E: float = TABLE3_MACRO["K_E"],
                   K_F: float = TABLE3_MACRO["K_F"], gamma: float = math.pi / 6,
                   penalty_stretch: float = 1.0,
                   limit_stretch: float | None = None) -> list[Term]:
    """The homogenised bi-pantographic energy (Barchiesi et al. 2020, eq. 2) as a model.

    Defaults: Barchiesi et al. 2020 Table 3 (macro model), K_S = 0.034 N/mm, K_E = 330 N·mm,
    K_F = 900 N·mm, γ = π/6. ``penalty_stretch``: the stretch at which the interior-penalty
    scale is taken (raise it with the largest stretch of the solution, see the module
    docstring). ``limit_stretch`` ρ_r (None: eq. 2 as printed): continue the energy beyond ρ_r
    (ρ_r cos γ < 1) by a stiff quadratic, defined for every stretch ("Regularisation").
    """
    if limit_stretch is None:
        return [PantographPivot(K_S=K_S, gamma=gamma),
                PantographBending(K_E=K_E, K_F=K_F, gamma=gamma,
                                  penalty_stretch=penalty_stretch)]
    return [RegularisedPantographPivot(K_S=K_S, gamma=gamma, limit_stretch=limit_stretch),
            RegularisedPantographBending(K_E=K_E, K_F=K_F, gamma=gamma,
                                         penalty_stretch=penalty_stretch,
                                         limit_stretch=limit_stretch)]


def bipantographic_density_numpy(rho, dtheta, drho, K_S=TABLE3_MACRO["K_S"],
                                 K_E=TABLE3_MACRO["K_E"], K_F=TABLE3_MACRO["K_F"],
                                 gamma=math.pi / 6):
    """Eq. (2) for one fibre family in numpy, in the printed acos form (reference for tests)."""
    import numpy as np

    c = math.cos(gamma)
    x = np.asarray(rho) ** 2 * c**2
    D = K_E - 8 * K_F * c**2
    return (K_S * (np.arccos(1 - 2 * x) - math.pi + 2 * gamma) ** 2
            + K_E * K_F * ((x - 1) / (x * D - K_E) * np.asarray(dtheta) ** 2
                           + x / ((1 - x) * (8 * K_F + np.asarray(rho) ** 2 * D))
                           * np.asarray(drho) ** 2))
