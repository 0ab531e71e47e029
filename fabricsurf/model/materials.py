"""Ready-made materials: term sets that are not part of the effect vocabulary (docs/theory.md).

The homogenised bi-pantographic fabric (Barchiesi et al. 2020, eq. 2), per fibre family
α ∈ {L, M}, with c = cos γ::

    W = Σ_α { K_S [acos(1 − 2ρ_α²c²) − π + 2γ]²
              + a_θ(ρ_α) (∂θ_α/∂α)² + a_ρ(ρ_α) (∂ρ_α/∂α)² },
    a_θ = K_E K_F (ρ²c² − 1) / (ρ²c²(K_E − 8K_F c²) − K_E),
    a_ρ = K_E K_F ρ²c² / ((1 − ρ²c²)(8K_F + ρ²(K_E − 8K_F c²))).

In this package's kinematics ρ_L = λ, ∂ρ_L/∂L = ``kin.dlam_dL``, ∂θ_L/∂L =
``kin.geodesic_l / kin.lam`` (the same for M). The energy is defined for ρc < 1 only (fully
opened rhombi); the docs (docs/bipantographic.md) give the reading of the printed equation,
its checks, the domain and how the solver respects it, the interior penalty that follows the
stretch (cell by cell, :class:`PantographBending` ``penalty_stretch``), the regularisation
beyond a limit stretch, and the units (mm, N: K_S in N/mm, K_E and K_F in N·mm, γ in rad; all
fem.Constants of the form that uses them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.term_constants import Params, TermConstants
from fabricsurf.model.terms import Term

TABLE3_MACRO = {"K_S": 0.034, "K_E": 330.0, "K_F": 900.0}
"""Barchiesi et al. 2020 Table 3, macro model, in N/mm, N·mm, N·mm."""


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

    def density(self, kin: Kinematics, p: Params):
        g = p["gamma"]
        c = ufl.cos(g)
        return p["K_S"] * (_pivot(kin.lam, c, g) ** 2 + _pivot(kin.mu, c, g) ** 2)


@dataclass
class PantographBending(Term):
    """K_E K_F Σ_α [a_θ(ρ_α)(∂θ_α/∂α)² + a_ρ(ρ_α)(∂ρ_α/∂α)²]: geodesic bending and stretch
    gradient of the pantographic beams (Barchiesi et al. 2020, eq. 2, second and third lines).

    ``penalty_stretch`` ρ_p (dimensionless, ρ_p cos γ < 1) is not a modulus: it is the stretch
    at which the interior-penalty scale S = a_θ(ρ_p) + a_ρ(ρ_p) is taken (docs/bipantographic.md,
    "Interior penalty"). In a form, ρ_p lives in a cellwise-constant (DG0) field of that form
    (``constants["penalty_stretch"]``): ``set(penalty_stretch=...)`` makes it uniform in every
    form, a caller that follows the local stretch writes one form's cell by cell
    (:meth:`set_penalty_stretch`); neither recompiles. Either way the term's own
    ``penalty_stretch`` is the value last written: uniform, that value; cell by cell, the
    largest (over all ranks), so the term, its copy or pickle, and a form built from it
    afterwards never carry a smaller ρ_p (a weaker penalty) than the form written.
    """

    K_E: float = TABLE3_MACRO["K_E"]
    K_F: float = TABLE3_MACRO["K_F"]
    gamma: float = math.pi / 6
    penalty_stretch: float = 1.0
    name: ClassVar[str] = "bipantographic_bending"
    order: ClassVar[int] = 2
    units: ClassVar[dict[str, str]] = {
        "K_E": "N·mm",
        "K_F": "N·mm",
        "gamma": "rad",
        "penalty_stretch": "1",
    }

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_below_limit(self.name, "penalty_stretch", self.penalty_stretch, self.gamma)

    def parameter_on(self, msh, name: str) -> fem.Constant | fem.Function:
        """As :meth:`Term.parameter_on`; ρ_p in a DG0 field (uniform until set cell by cell)."""
        if name != "penalty_stretch":
            return super().parameter_on(msh, name)
        f = fem.Function(fem.FunctionSpace(msh, ("DG", 0)), name="penalty_stretch")
        f.x.array[:] = self.penalty_stretch
        return f

    def set_penalty_stretch(self, constants: TermConstants, values: np.ndarray) -> None:
        """Set ρ_p cell by cell in one form (``constants``: this term's in that form):
        ``values`` in the order of the local cells of its mesh, ghosts included; each must
        lie inside the energy's domain. Collective on that mesh: the term's own
        ``penalty_stretch`` becomes the largest value over all ranks (class docstring)."""
        values = np.asarray(values, dtype=float)
        f = constants["penalty_stretch"]
        comm = f.function_space.mesh.comm
        ok = bool((values * math.cos(self.gamma) < 1.0).all())
        if not comm.allreduce(ok, op=MPI.LAND):
            raise ValueError(
                f"term '{self.name}': penalty_stretch must satisfy "
                f"penalty_stretch·cos γ < 1 in every cell"
            )
        f.x.array[f.function_space.dofmap.list.array] = values
        f.x.scatter_forward()
        largest = comm.allreduce(float(np.max(values, initial=-np.inf)), op=MPI.MAX)
        if math.isfinite(largest):
            self.penalty_stretch = largest

    def _coeffs(self, rho, p: Params):
        return _coefficients(rho, p["K_E"], p["K_F"], ufl.cos(p["gamma"]))

    def _stretch(self, rho, p: Params):
        """The stretch at which the coefficients are evaluated (ρ itself; capped when
        regularised)."""
        return rho

    def density(self, kin: Kinematics, p: Params):
        W = 0
        for rho, geo, drho in (
            (kin.lam, kin.geodesic_l, kin.dlam_dL),
            (kin.mu, kin.geodesic_m, kin.dmu_dM),
        ):
            a_theta, a_rho = self._coeffs(self._stretch(rho, p), p)
            W += a_theta * (geo / rho) ** 2 + a_rho * drho**2
        return W

    def stiffness_scale(self, p: Params):
        """a_θ + a_ρ at ρ = ``penalty_stretch`` (the penalty scale S of energy.py)."""
        a_theta, a_rho = self._coeffs(self._stretch(p["penalty_stretch"], p), p)
        return a_theta + a_rho

    def reference_moduli(self) -> tuple[float, float]:
        """(a_θ, a_ρ) at ρ = 1 as floats (N·mm)."""
        return _coefficients(1.0, self.K_E, self.K_F, math.cos(self.gamma))

    def set(self, **values: float) -> None:
        if "penalty_stretch" in values:
            _check_below_limit(
                self.name,
                "penalty_stretch",
                values["penalty_stretch"],
                values.get("gamma", self.gamma),
            )
        super().set(**values)


def _check_below_limit(name: str, key: str, rho: float, gamma: float) -> None:
    if not float(rho) * math.cos(gamma) < 1.0:
        raise ValueError(
            f"term '{name}': {key} = {rho} must satisfy {key}·cos γ < 1 "
            f"(< {1 / math.cos(gamma):.4f} for γ = {gamma:.4f})"
        )


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
    second-order Taylor expansion (docs/bipantographic.md, "Regularisation")."""

    limit_stretch: float = 1.12
    units: ClassVar[dict[str, str]] = {"K_S": "N/mm", "gamma": "rad", "limit_stretch": "1"}

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_below_limit(self.name, "limit_stretch", self.limit_stretch, self.gamma)

    def density(self, kin: Kinematics, p: Params):
        r, K, g = p["limit_stretch"], p["K_S"], p["gamma"]
        return _pivot_extension(kin.lam, r, K, g) + _pivot_extension(kin.mu, r, K, g)


@dataclass
class RegularisedPantographBending(PantographBending):
    """:class:`PantographBending` with a_θ, a_ρ frozen at their values at ``limit_stretch``
    beyond it (docs/bipantographic.md, "Regularisation")."""

    limit_stretch: float = 1.12
    units: ClassVar[dict[str, str]] = {**PantographBending.units, "limit_stretch": "1"}

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_below_limit(self.name, "limit_stretch", self.limit_stretch, self.gamma)

    def _stretch(self, rho, p: Params):
        return ufl.min_value(rho, p["limit_stretch"])


def bipantographic(
    K_S: float = TABLE3_MACRO["K_S"],
    K_E: float = TABLE3_MACRO["K_E"],
    K_F: float = TABLE3_MACRO["K_F"],
    gamma: float = math.pi / 6,
    penalty_stretch: float = 1.0,
    limit_stretch: float | None = None,
) -> list[Term]:
    """The homogenised bi-pantographic energy (Barchiesi et al. 2020, eq. 2) as a model.

    Defaults: Barchiesi et al. 2020 Table 3 (macro model), K_S = 0.034 N/mm, K_E = 330 N·mm,
    K_F = 900 N·mm, γ = π/6. ``penalty_stretch``: the stretch at which the interior-penalty
    scale is taken (raise it with the largest stretch of the solution, see the module
    docstring). ``limit_stretch`` ρ_r (None: eq. 2 as printed): continue the energy beyond ρ_r
    (ρ_r cos γ < 1) by a stiff quadratic, defined for every stretch ("Regularisation").
    """
    if limit_stretch is None:
        return [
            PantographPivot(K_S=K_S, gamma=gamma),
            PantographBending(K_E=K_E, K_F=K_F, gamma=gamma, penalty_stretch=penalty_stretch),
        ]
    return [
        RegularisedPantographPivot(K_S=K_S, gamma=gamma, limit_stretch=limit_stretch),
        RegularisedPantographBending(
            K_E=K_E,
            K_F=K_F,
            gamma=gamma,
            penalty_stretch=penalty_stretch,
            limit_stretch=limit_stretch,
        ),
    ]
