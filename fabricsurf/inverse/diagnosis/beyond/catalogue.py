"""The catalogue of features beyond the vocabulary, each with why a fabric could have it
(:mod:`.features` leaves out those a named effect duplicates)."""

from __future__ import annotations

from fabricsurf.inverse.diagnosis.beyond.spec import FeatureSpec


def _pair(name: str, formula: str, expr: str, plus: str, minus: str, **kw) -> list[FeatureSpec]:
    """A sign-indefinite form as its + and − features (each with k ≥ 0)."""
    return [
        FeatureSpec(f"{name}_plus", formula, expr, plus, sign=1, **kw),
        FeatureSpec(f"{name}_minus", formula, expr, minus, sign=-1, **kw),
    ]


_UFL = ("import ufl",)
_GRAD = ("from fabricsurf.inverse.diagnosis.beyond.spec import shear_angle_gradient",)
_SQ = "((kin.lam - 1) + (kin.mu - 1))"

SPECS: tuple[FeatureSpec, ...] = (
    *_pair(
        "shear_tension",
        "γ²((λ−1)+(μ−1))",
        f"kin.gamma**2 * {_SQ}",
        "shear stiffens under fibre tension (tension presses the yarns together at the "
        "crossovers: the shear-tension coupling of biaxial bias tests)",
        "shear softens under fibre tension (tension straightens the crimp that resists "
        "the yarns' rotation at the crossovers)",
    ),
    *_pair(
        "crimp_interchange",
        "(λ−1)(μ−1)",
        "(kin.lam - 1) * (kin.mu - 1)",
        "crimp interchange: straightening one family's crimp deepens the other's, so "
        "stretching one family shortens the other (a Poisson effect between the families)",
        "the families stretch together: stretching one opens the weave for the other "
        "(biaxial stiffening of a loose weave)",
        coef="1.0",
        coef_text="",
    ),
    FeatureSpec(
        "compression_stiff",
        "[min(λ−1,0)² + min(μ−1,0)²]",
        "ufl.min_value(kin.lam - 1, 0.0)**2 + ufl.min_value(kin.mu - 1, 0.0)**2",
        "the yarns jam in compression: stiffer in compression than in tension",
        imports=_UFL,
    ),
    FeatureSpec(
        "tension_stiff",
        "[max(λ−1,0)² + max(μ−1,0)²]",
        "ufl.max_value(kin.lam - 1, 0.0)**2 + ufl.max_value(kin.mu - 1, 0.0)**2",
        "the yarns are softer in compression than in tension: they buckle out of their "
        "crimp (fibre_stretch then carries the compressive stiffness alone)",
        imports=_UFL,
    ),
    *_pair(
        "shear_cubic",
        "γ³",
        "kin.gamma**3",
        "positive shear is stiffer than negative (twills; stitched non-crimp fabrics whose "
        "stitches run along one diagonal): an odd term in γ",
        "positive shear is softer than negative (an odd term in γ, the other way)",
        coef="1 / 3",
        coef_text="⅓",
    ),
    *_pair(
        "shear_stretch_skew",
        "γ((λ−1)−(μ−1))",
        "kin.gamma * ((kin.lam - 1) - (kin.mu - 1))",
        "shear coupled to the difference of the two stretches: allowed when the weave "
        "lacks the L↔M mirror symmetry (twills, unbalanced weaves)",
        "the same coupling of the other sign",
        coef="1.0",
        coef_text="",
    ),
    FeatureSpec(
        "stretch_quartic",
        "[(λ−1)⁴ + (μ−1)⁴]",
        "(kin.lam - 1)**4 + (kin.mu - 1)**4",
        "nonlinear fibre stiffening as the crimp is pulled out (decrimping)",
        coef="0.25",
        coef_text="¼",
    ),
    FeatureSpec(
        "shear_angle_gradient",
        "[(∂_Lγ)² + (∂_Mγ)²]",
        "shear_angle_gradient(kin, kin.L)**2 + shear_angle_gradient(kin, kin.M)**2",
        "the shear angle cannot change abruptly along a yarn: neighbouring crossovers "
        "are tied by the yarn across them (a boundary layer of shear)",
        unit="N·mm",
        order=2,
        imports=_GRAD,
    ),
    FeatureSpec(
        "shear_quartic",
        "γ⁴",
        "kin.gamma**4",
        "shear stiffening towards locking",
        coef="0.25",
        coef_text="¼",
    ),
    *_pair(
        "fibre_imbalance",
        "[(λ−1)² − (μ−1)²]",
        "(kin.lam - 1)**2 - (kin.mu - 1)**2",
        "warp stiffer than weft (an unbalanced weave)",
        "weft stiffer than warp",
    ),
    FeatureSpec(
        "shear_bending",
        "γ²(K_L² + K_M²)",
        "kin.gamma**2 * (kin.K_L**2 + kin.K_M**2)",
        "bending stiffens as the fabric shears (the yarns compact)",
        unit="N·mm",
        order=2,
        in_plane=False,
    ),
    *_pair(
        "curvature_coupling",
        "K_L·K_M",
        "kin.K_L * kin.K_M",
        "bending one family bends the other the same way (a synclastic preference)",
        "bending one family bends the other the other way (anticlastic, a saddle)",
        coef="1.0",
        coef_text="",
        unit="N·mm",
        order=2,
        in_plane=False,
    ),
)
"""Every feature considered, before the check against the vocabulary (:func:`library`)."""
