"""Energy terms: the public vocabulary of physical effects (docs/theory.md, Steigmann & dell'Isola
2015 eq. 60).

Each term is a small dataclass with validated moduli and a ``density(kin, p)`` method giving its
strain energy per unit reference area, with ``p[name]`` the value of each modulus: the UFL
objects of the form being built (:meth:`Term.constants`), or the floats of :meth:`Term.values`.
A model is a list of terms::

    model = [FibreStretch(k_l=30.0), Shear(k_s=0.5), GeodesicBending(A_g=40.0)]

Units (lengths in mm, forces in N): first-gradient moduli are energy per area, N/mm;
second-gradient moduli are energy per area times length², N·mm.

The base class :class:`Term` is in ``term.py`` (with how a form owns a term's constants and
:meth:`Term.set`); ``yarn_slip`` is in ``slip.py`` and registered in :data:`EFFECTS` here like
every other effect; a user's own effects join them through ``registry.py`` and
``user_effects.py`` (docs/usage.md, "Adding your own effect").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import ufl

from fabricsurf.defaults import FRICTION_ANGLE
from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.registry import EffectRegistry
from fabricsurf.model.slip import YarnSlip
from fabricsurf.model.term import Term
from fabricsurf.model.term_constants import Params


@dataclass
class FibreStretch(Term):
    """½k_l(λ−1)² + ½k_m(μ−1)²: fibre extension (crimp/decrimp).

    With ``inextensible=True`` the fibres do not stretch at all: λ = μ = 1 is a constraint
    whose multipliers are the fibre tensions T_l, T_m (N/mm), and k_l, k_m are the
    augmentation stiffnesses of the augmented Lagrangian that enforces it (numerical, not
    material, constants: any value works, larger ones need fewer multiplier updates).
    """

    k_l: float = 1.0
    k_m: float = 1.0
    inextensible: bool = False
    name: ClassVar[str] = "fibre_stretch"
    fibre: ClassVar[bool] = True
    units: ClassVar[dict[str, str]] = {"k_l": "N/mm", "k_m": "N/mm"}
    options: ClassVar[tuple[str, ...]] = ("inextensible",)

    def density(self, kin: Kinematics, p: Params):
        if self.inextensible:
            return 0.0
        return 0.5 * p["k_l"] * (kin.lam - 1) ** 2 + 0.5 * p["k_m"] * (kin.mu - 1) ** 2

    def tensions(self, kin: Kinematics, p: Params) -> dict:
        """Fibre tensions ∂W/∂λ, ∂W/∂μ per unit reference width (N/mm) of the elastic fibres
        (those of inextensible ones are the multipliers of :meth:`constraints`)."""
        if self.inextensible:
            return {}
        return {"tension_l": p["k_l"] * (kin.lam - 1), "tension_m": p["k_m"] * (kin.mu - 1)}

    def constraints(self, kin: Kinematics, p: Params) -> list[tuple[str, object, object]]:
        if not self.inextensible:
            return []
        return [("tension_l", kin.lam - 1, p["k_l"]), ("tension_m", kin.mu - 1, p["k_m"])]


@dataclass
class Shear(Term):
    """½k_s γ²: in-plane shear resistance between the fibre families (pivots)."""

    k_s: float = 1.0
    name: ClassVar[str] = "shear"
    units: ClassVar[dict[str, str]] = {"k_s": "N/mm"}

    def density(self, kin: Kinematics, p: Params):
        return 0.5 * p["k_s"] * kin.gamma**2


@dataclass
class ShearLocking(Term):
    """¼k₄γ⁴ + ⅙k₆γ⁶: shear stiffening as the yarns jam towards the locking angle.

    The polynomial beyond the quadratic of :class:`Shear` (woven fabrics lock at ~40–55°,
    Cao et al. 2008); linear in its moduli, so the exact sensitivities of the fit still hold.
    """

    k4: float = 1.0
    k6: float = 1.0
    name: ClassVar[str] = "shear_locking"
    units: ClassVar[dict[str, str]] = {"k4": "N/mm", "k6": "N/mm"}

    def density(self, kin: Kinematics, p: Params):
        g2 = kin.gamma**2
        return (0.25 * p["k4"] + p["k6"] / 6.0 * g2) * g2**2

    def locking_angle(self, k_s: float) -> float | None:
        """γ (rad) at which the locking moment k₄γ³ + k₆γ⁵ equals the linear k_s γ of
        :class:`Shear` (the shear stiffness has doubled); None without locking moduli."""
        k4, k6 = self.k4, self.k6
        if k4 <= 0 and k6 <= 0:
            return None
        if k6 <= 0:
            return math.sqrt(k_s / k4)
        return math.sqrt((-k4 + math.sqrt(k4**2 + 4 * k6 * k_s)) / (2 * k6))  # γ² of the root


@dataclass
class CrossoverFriction(Term):
    """τ_f γ_f ln cosh(γ/γ_f): inter-yarn friction at the crossovers, as an elastic equivalent.

    Its shear stress τ_f tanh(γ/γ_f) rises over the first γ_f of shear and then stays at τ_f
    (N/mm): the resistance the yarns' contact at every crossover puts up before they turn
    (Kawabata 1980; the initial knee of woven-fabric shear curves, Cao et al. 2008). Elastic,
    so it holds for monotonic loading only: the friction it stands for dissipates on
    unloading. Linear in τ_f; the shape angle γ_f (rad) is a fixed option, not a fitted modulus.
    """

    tau_f: float = 1.0
    gamma_f: float = FRICTION_ANGLE
    name: ClassVar[str] = "crossover_friction"
    units: ClassVar[dict[str, str]] = {"tau_f": "N/mm"}
    options: ClassVar[tuple[str, ...]] = ("gamma_f",)
    monotonic_only: ClassVar[bool] = True

    def __post_init__(self) -> None:
        super().__post_init__()
        g = self.gamma_f
        if not (isinstance(g, (int, float)) and math.isfinite(g) and 0.0 < g <= math.pi / 4):
            raise ValueError(
                f"term '{self.name}': shape angle gamma_f = {g!r} must be a number "
                "in (0, π/4] rad (the friction is mobilised within 45°)"
            )

    def density(self, kin: Kinematics, p: Params):
        g = kin.gamma
        # ln cosh x = x + ln(1 + e^(-2x)) - ln 2 for x = |γ|/γ_f ≥ 0: no overflow at any γ.
        # |γ| as a conditional, whose derivative ±1 is defined at γ = 0 (that of abs is not).
        x = ufl.conditional(ufl.ge(g, 0.0), g, -g) / self.gamma_f
        return p["tau_f"] * self.gamma_f * (x + ufl.ln(1 + ufl.exp(-2 * x)) - math.log(2))


@dataclass
class GeodesicBending(Term):
    """½A_g[(λ²η_l)² + (μ²η_m)²]: in-plane (geodesic) fibre bending.

    Steigmann & dell'Isola 2015 §1, eqs. 23 and 58.
    """

    A_g: float = 1.0
    name: ClassVar[str] = "geodesic_bending"
    order: ClassVar[int] = 2
    units: ClassVar[dict[str, str]] = {"A_g": "N·mm"}

    def density(self, kin: Kinematics, p: Params):
        return 0.5 * p["A_g"] * (kin.geodesic_l**2 + kin.geodesic_m**2)


@dataclass
class StretchGradient(Term):
    """½A_s[(∂_Lλ)² + (∂_Mμ)²]: tangential stretch gradients along the fibres.

    Steigmann & dell'Isola 2015 §3, eq. 58.
    """

    A_s: float = 1.0
    name: ClassVar[str] = "stretch_gradient"
    order: ClassVar[int] = 2
    units: ClassVar[dict[str, str]] = {"A_s": "N·mm"}

    def density(self, kin: Kinematics, p: Params):
        return 0.5 * p["A_s"] * (kin.dlam_dL**2 + kin.dmu_dM**2)


@dataclass
class ShearGradient(Term):
    """½A_Γ|Γ|²: cross derivatives / shear-angle gradient (Steigmann & dell'Isola 2015 eq. 60)."""

    A_Gamma: float = 1.0
    name: ClassVar[str] = "shear_gradient"
    order: ClassVar[int] = 2
    units: ClassVar[dict[str, str]] = {"A_Gamma": "N·mm"}

    def density(self, kin: Kinematics, p: Params):
        G = kin.Gamma
        return 0.5 * p["A_Gamma"] * ufl.dot(G, G)


@dataclass
class NormalBending(Term):
    """½k_b(K_L² + K_M²): out-of-plane fibre bending; 3D only.

    Steigmann & dell'Isola 2015 eqs. 60 and 61.
    """

    k_b: float = 1.0
    name: ClassVar[str] = "normal_bending"
    order: ClassVar[int] = 2
    in_plane: ClassVar[bool] = False
    units: ClassVar[dict[str, str]] = {"k_b": "N·mm"}

    def density(self, kin: Kinematics, p: Params):
        return 0.5 * p["k_b"] * (kin.K_L**2 + kin.K_M**2)


@dataclass
class Twist(Term):
    """½k_t T²: fibre twist (Steigmann & dell'Isola 2015 eqs. 60, 61; k̄ there); 3D only."""

    k_t: float = 1.0
    name: ClassVar[str] = "twist"
    order: ClassVar[int] = 2
    in_plane: ClassVar[bool] = False
    units: ClassVar[dict[str, str]] = {"k_t": "N·mm"}

    def density(self, kin: Kinematics, p: Params):
        return 0.5 * p["k_t"] * kin.T**2


EFFECTS = EffectRegistry(
    (
        FibreStretch,
        Shear,
        ShearLocking,
        CrossoverFriction,
        GeodesicBending,
        StretchGradient,
        ShearGradient,
        NormalBending,
        Twist,
        YarnSlip,
    )
)
"""The vocabulary of effects, by exact name (docs/theory.md): a mapping name → Term class, the
built-ins and then the effects a user registered in this process
(:func:`fabricsurf.model.user_effects.register_effect`, ``--effects FILE.py``)."""


def in_plane_invisible() -> tuple[str, ...]:
    """The effects of :data:`EFFECTS` that planar (2D) data cannot see (``Term.in_plane``
    False: they act on out-of-plane placements only)."""
    return tuple(n for n, cls in EFFECTS.items() if not cls.in_plane)


def make_term(name: str, **params: float) -> Term:
    """The term called ``name`` with the given moduli; unknown names list the valid ones."""
    cls = EFFECTS.lookup(name)
    unknown = set(params) - set(cls.parameters())
    if unknown:
        raise ValueError(
            f"term '{name}' has no parameter(s) {sorted(unknown)}; it has {cls.parameters()}"
        )
    return cls(**params)


def parse_terms(spec: str, params: dict[str, dict[str, float]] | None = None) -> list[Term]:
    """A model from a comma-separated list of effect names, e.g. ``"fibre_stretch,shear"``."""
    names = [s.strip() for s in spec.split(",") if s.strip()]
    if not names:
        raise ValueError(f"empty term list '{spec}'; valid terms are: {', '.join(EFFECTS)}")
    params = params or {}
    return [make_term(n, **params.get(n, {})) for n in names]
