"""Ready-made materials: term sets that are not part of the effect vocabulary (DESIGN §3).

Homogenised bi-pantographic fabric (seed 000 §2, eq. 2)
------------------------------------------------------
Seed 000 writes the deformation energy of the homogenised bi-pantographic fabric (Barchiesi et
al., its ref. [29]) per fibre family α ∈ {L, M} as (the text extraction of eq. 2 is garbled:
the fraction ``ρ²/(1/(2cos²γ))`` is ``2ρ²cos²γ``, and the last line is printed twice)::

    W = Σ_α { K_S [acos(1 − 2ρ_α²c²) − π + 2γ]²
              + K_E K_F [ (ρ_α²c² − 1) / (ρ_α²c²(K_E − 8K_F c²) − K_E) (∂θ_α/∂α)²
                        + ρ_α²c² / ((1 − ρ_α²c²)(8K_F + ρ_α²(K_E − 8K_F c²))) (∂ρ_α/∂α)² ] }

with c = cos γ, γ = π/6 the angle between the rhombus sides of a pantographic beam and its axis
(side length ε/√3, so a straight beam segment of length ε at ρ = 1). ∂χ/∂α = ρ_α(cos θ_α,
sin θ_α) defines the stretch ρ_α and the direction θ_α of the deformed fibre (seed 000 eq. 1;
the seed's x, y are the fibre directions, here L, M). In the kinematics of this package
(DESIGN §2): ρ_L = λ, ∂ρ_L/∂L = l·r_LL = ``kin.dlam_dL``, and since
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
* Guards: none. ρc < 1 is the geometric limit of a pantographic beam (fully opened rhombi:
  ρ_max = 1/cos γ = 1.155); the energy is not defined beyond, and the stretch-gradient
  coefficient diverges there, which is the physics of the homogenised model (the micro model
  has extensible rhombus sides instead). A Newton iterate that crosses the limit gives NaN,
  which the solver reports as divergence and the load stepper cuts the step (DESIGN §4).
  In the bias test (demos/demo_bias_extension.py, h = 4 mm) the largest fibre stretch at the
  lattice nodes is 1.062 at ū = 28 mm, but Newton fails near ū ≈ 28.9 mm (h = 8 mm): the limit
  is approached locally (presumably at the clamp corners; not localised further), so the demo
  compares up to ū = 15 % of the length.
* Units (mm, N): K_S in N/mm (Table 3: 34 N/m = 0.034 N/mm), K_E and K_F in N·mm (Table 3:
  0.33 J = 330 N·mm, 0.9 J = 900 N·mm), γ in rad. All are fem.Constants once bound, so
  changing them does not recompile.
* The interior-penalty scale S of the second-gradient term (energy.py) is the sum of its two
  coefficients at ρ = 1 (≈ 436 N·mm for Table 3), not K_E + K_F, so the penalty keeps the same
  ratio to the physical stiffness as for the vocabulary terms.
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
    rhombi as the beams stretch (seed 000 eq. 2, first line)."""

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
    gradient of the pantographic beams (seed 000 eq. 2, second and third lines)."""

    K_E: float = TABLE3_MACRO["K_E"]
    K_F: float = TABLE3_MACRO["K_F"]
    gamma: float = math.pi / 6
    name: ClassVar[str] = "bipantographic_bending"
    order: ClassVar[int] = 2
    units: ClassVar[dict[str, str]] = {"K_E": "N·mm", "K_F": "N·mm", "gamma": "rad"}

    def _coeffs(self, rho):
        return _coefficients(rho, self.p("K_E"), self.p("K_F"), ufl.cos(self.p("gamma")))

    def density(self, kin: Kinematics):
        W = 0
        for rho, geo, drho in ((kin.lam, kin.geodesic_l, kin.dlam_dL),
                               (kin.mu, kin.geodesic_m, kin.dmu_dM)):
            a_theta, a_rho = self._coeffs(rho)
            W += a_theta * (geo / rho) ** 2 + a_rho * drho**2
        return W

    def stiffness_scale(self):
        """Sum of the two coefficients at ρ = 1 (the penalty scale S of energy.py)."""
        a_theta, a_rho = self._coeffs(1.0)
        return a_theta + a_rho

    def reference_moduli(self) -> tuple[float, float]:
        """(a_θ, a_ρ) at ρ = 1 as floats (N·mm)."""
        return _coefficients(1.0, self.K_E, self.K_F, math.cos(self.gamma))


def bipantographic(K_S: float = TABLE3_MACRO["K_S"], K_E: float = TABLE3_MACRO["K_E"],
                   K_F: float = TABLE3_MACRO["K_F"], gamma: float = math.pi / 6) -> list[Term]:
    """The homogenised bi-pantographic energy of seed 000 eq. (2) as a model (list of terms).

    Defaults: seed 000 Table 3 (macro model), K_S = 0.034 N/mm, K_E = 330 N·mm,
    K_F = 900 N·mm, γ = π/6.
    """
    return [PantographPivot(K_S=K_S, gamma=gamma), PantographBending(K_E=K_E, K_F=K_F, gamma=gamma)]


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
