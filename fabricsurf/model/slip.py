"""Yarn slip at the crossovers: the fibre tension a woven net carries before its yarns slide
through the crossings (docs/vocabulary.md, docs/woven_fabric.md "The large-shear range").

The material points of the continuum are the crossings. When a yarn slides through its
crossings, the spacing of the crossings along that yarn changes: the continuum's fibre stretch
λ − 1 is then the slip strain, not the yarn's own (glass) stretch. The contact at each crossing
resists slip by friction up to a slip tension T_s per unit reference width; past it the yarns
slide, with the stiffness of ``fibre_stretch`` (k_l, k_m: then the hardening of the slip, as
the crossings compact) carrying the rest. The energy of the friction part is the elastic
equivalent of a rigid-plastic slip law, as ``crossover_friction`` is for the rotation at the
crossings: T_s ε_s ln cosh((λ − 1)/ε_s), tension T_s tanh((λ − 1)/ε_s), mobilised within a
slip strain ε_s (fixed option) and saturating at T_s. With it, a bias specimen whose shear
stiffens towards the geometric lock of its net (zone C at 90°) prefers to slide its yarns:
softer than the pin-jointed net past about 60°.

Linear in T_s, so the exact sensitivities and the diagnosis's linearised scores hold. It is an
effect on top of *extensible* fibres: with ``fibre_stretch`` inextensible (λ = 1 exactly) it
has no effect, and with a glass-stiff ``fibre_stretch`` it cannot soften anything (an additive
term with a non-negative modulus only stiffens), so the diagnosis finds it with the yarns'
stiffness free in the baseline (docs/woven_fabric.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import ufl

from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.term import Term
from fabricsurf.model.term_constants import Params

SLIP_STRAIN = 0.002
"""Default slip strain ε_s over which the friction of the crossings is mobilised (the Cao et al.
2008 curve is followed equally for 0.0005–0.002, worse above: docs/woven_fabric.md)."""


def _ln_cosh(x):
    """ln cosh x for a UFL x ≥ 0 written so that it does not overflow at any x."""
    return x + ufl.ln(1 + ufl.exp(-2 * x)) - math.log(2)


def _abs(e):
    """|e| as a conditional, whose derivative ±1 is defined at 0 (that of ``abs`` is 0 there,
    which would lose the friction's reference tangent T_s/ε_s)."""
    return ufl.conditional(ufl.ge(e, 0.0), e, -e)


@dataclass
class YarnSlip(Term):
    """T_s ε_s [ln cosh((λ−1)/ε_s) + ln cosh((μ−1)/ε_s)]: friction of the yarns at the crossings
    against sliding through them, as an elastic equivalent for monotonic loading.

    Fibre tension T_s tanh((λ − 1)/ε_s) (N/mm): the yarns stick up to the slip tension T_s,
    then slide, ``fibre_stretch`` carrying the hardening. Linear in T_s; the slip strain ε_s
    is a fixed option, not a fitted modulus.
    """

    T_s: float = 1.0
    eps_s: float = SLIP_STRAIN
    name: ClassVar[str] = "yarn_slip"
    units: ClassVar[dict[str, str]] = {"T_s": "N/mm"}
    options: ClassVar[tuple[str, ...]] = ("eps_s",)
    monotonic_only: ClassVar[bool] = True
    fibre: ClassVar[bool] = True
    look_alike: ClassVar[dict] = {
        "mechanism": "slip of the specimen in the grips (a crosshead displacement the fabric "
        "does not take), not in the vocabulary; nor can it tell either from the "
        "net extending along its yarns that a soft fibre_stretch stands for",
        "evidence": "Cao et al. 2008, 115 x 230 mm, the whole curve, three-zone kinematics: "
        "yarn slip (threshold + hardening) and grip slip (threshold force + "
        "compliance) fit it about equally well and give the same zone-C angle "
        "near the lock, and so do grip compliance + shear_locking and the "
        "finite-element extensible net + shear_locking "
        "(benchmarks/large_shear_mechanisms.py; the chi2 values and angles in "
        "docs/woven_fabric.md, 'The large-shear range')",
        "identified_by": [
            "a full-field measurement: grip slip moves zone A rigidly against the grip, yarn "
            "slip stretches the net along its fibres (the crossings' spacing) in zones B and C",
            "a second specimen size taken past 60 deg of zone-C shear: grip slip starts at one "
            "force whatever the size, yarn slip at one fibre tension per unit width (the two "
            "fits' forces for a 150 x 450 mm specimen differ past 60 deg only: "
            "docs/woven_fabric.md, 'The large-shear range')",
            "a picture-frame test to the same angles: no free edges and no bias-test grip; its "
            "shear force past 60 deg tells a shear law that locks from one that softens",
        ],
    }

    def __post_init__(self) -> None:
        super().__post_init__()
        e = self.eps_s
        if not (isinstance(e, (int, float)) and math.isfinite(e) and 0.0 < e <= 0.1):
            raise ValueError(
                f"term '{self.name}': slip strain eps_s = {e!r} must be a number "
                "in (0, 0.1] (the friction is mobilised within 10 % of stretch)"
            )

    def small_stretch_stiffness(self) -> float:
        """T_s/ε_s: the tangent of the tension T_s tanh((λ − 1)/ε_s) at λ = 1. Sticking yarns
        are that stiff, on top of ``fibre_stretch``, however small T_s is against k_l."""
        return self.T_s / self.eps_s

    def density(self, kin: Kinematics, p: Params):
        es = self.eps_s
        return p["T_s"] * es * (_ln_cosh(_abs(kin.lam - 1) / es) + _ln_cosh(_abs(kin.mu - 1) / es))
