"""When is a model adequate, and when does an added effect matter? (docs/diagnosis.md)

Residuals are divided by the noise level, so at the truth χ² ≈ ν = n − p.

*Adequate*: the misfit left is what noise and the forward model's own discretisation error
explain: (χ² − χ²_h)/ν ≤ max(1 + 3√(2/ν), 1.1²), with χ²_h the squared difference, in noise
units, between the predictions at h and at h/2 (0 when not measured). The 3σ band of χ²/ν keeps
the false-alarm rate of "inadequate" at the 0.1 % level for Gaussian noise of exactly the stated
level; the floor 1.1² (an RMS misfit of 1.1 noise levels) is there because a stated noise level
is itself an estimate, good to about 10 %: with thousands of data the 3σ band alone would call a
model inadequate for a systematic error of a tenth of the noise. The credit χ²_h is capped at the
band itself, (bound − 1)ν: a mesh whose own error is larger than that (the mesh is too coarse for
the data, :func:`too_coarse`) cannot show that a model explains the data. (docs/diagnosis.md
gives a stiff-fibre case where the uncapped rule called a model adequate.)

*Significant* (nested models, k added moduli ≥ 0): a Wald test on the same residual model as
the moduli's intervals (:mod:`~.uncertainty`): the added moduli against zero with the refit's
cluster-robust covariance, one-sided (Student's t with the blocks' degrees of freedom for
k = 1, F(k, G − P) otherwise) at the 0.999 level, a decrease of χ², and the F-test of part 1
below at the same level. Correlated residuals (DIC subsets, model-form error smooth in space)
widen the covariance instead of passing as many independent data, so the rule needs no allowance
for them (docs/uncertainty.md measures that the former "quarter of the excess" part adds nothing
to it). The F-test guards the χ² side: a refit whose covariance is nearly singular (a modulus
that reaches a range where its term does nothing, e.g. a yarn-slip tension no yarn reaches) can
pass the Wald test by an arbitrarily large F while removing no misfit (docs/diagnosis.md).

Without a refit's covariance (a caller with χ² only) the former two-part rule applies:
1. an F-test at the 0.999 level against the residual variance actually left,
   F = (Δχ²/k) / s² with s² = max(1, χ²_new/ν_new);
2. the effect removes at least a quarter of the baseline's excess misfit,
   Δχ² ≥ ¼ (χ²_base − ν_base): the F-test assumes independent residuals and calls an extra
   modulus that absorbs a little model-form error significant; this part stops that.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from fabricsurf.inverse.fitting.stiff_limit import STIFF_CAP

LEVEL = 0.999
FRACTION_OF_EXCESS = 0.25


def reduced(chi2: float, n: int, p: int) -> float:
    return chi2 / max(n - p, 1)


ADEQUATE_MISFIT = 1.1


def adequacy_bound(n: int, p: int) -> float:
    """max(1 + 3√(2/ν), 1.1²): the largest χ²/ν still at the noise level (module docstring)."""
    return max(1.0 + 3.0 * np.sqrt(2.0 / max(n - p, 1)), ADEQUATE_MISFIT**2)


def too_coarse(chi2_h: float, n: int, p: int) -> bool:
    """The forward model's own discretisation error exceeds the noise tolerance band."""
    return bool(chi2_h > (adequacy_bound(n, p) - 1.0) * max(n - p, 1))


def adequate(chi2: float, n: int, p: int, chi2_h: float = 0.0, noise_known: bool = True) -> bool:
    """The model explains the data at the noise level (module docstring; the discretisation
    credit ``chi2_h`` capped at the tolerance band). Without a stated noise level the scale
    was guessed (1 % of the largest value), so this is only indicative."""
    nu, bound = max(n - p, 1), adequacy_bound(n, p)
    credit = min(chi2_h, (bound - 1.0) * nu)
    return (
        bool((chi2 - credit) / nu <= bound) if noise_known else bool(reduced(chi2, n, p) <= bound)
    )


def share_of_excess(chi2_base: float, p_base: int, chi2_new: float, n: int) -> float:
    """Δχ² / (χ²_base − ν_base): the part of the baseline's excess misfit an effect removes
    (inf when the baseline has no excess)."""
    excess = chi2_base - max(n - p_base, 1)
    return float((chi2_base - chi2_new) / excess) if excess > 0 else float("inf")


def f_statistic(chi2_base: float, p_base: int, chi2_new: float, p_new: int, n: int) -> float:
    """F = (Δχ²/k) / s², s² = max(1, χ²_new/ν_new): the added moduli's reduction against the
    residual variance left."""
    k = max(p_new - p_base, 1)
    return float((chi2_base - chi2_new) / k / max(1.0, chi2_new / max(n - p_new, 1)))


def f_test(chi2_base: float, p_base: int, chi2_new: float, p_new: int, n: int) -> bool:
    """Part 1 of the rule: the F-test at :data:`LEVEL` against the residual variance left."""
    k, nu_new = max(p_new - p_base, 1), max(n - p_new, 1)
    return bool(f_statistic(chi2_base, p_base, chi2_new, p_new, n) > stats.f.ppf(LEVEL, k, nu_new))


def significant(
    chi2_base: float, p_base: int, chi2_new: float, p_new: int, n: int, wald_p: float | None = None
) -> bool:
    """The rule of the module docstring; ``wald_p``: the one-sided p-value of the added moduli
    on the correlated-residual model (None: the former two-part rule)."""
    if chi2_base - chi2_new <= 0:
        return False
    if wald_p is not None:
        return bool(wald_p < 1.0 - LEVEL) and f_test(chi2_base, p_base, chi2_new, p_new, n)
    return (
        f_test(chi2_base, p_base, chi2_new, p_new, n)
        and share_of_excess(chi2_base, p_base, chi2_new, n) >= FRACTION_OF_EXCESS
    )


SLOW_FALL = 0.5
"""A fall of the h/2 check per halving slower than this is slower than the discretisation's
order explains (the meshes are not yet asymptotic)."""
STIFF_YARNS = 1e4
"""K/k_s from which fitted elastic yarns' boundary layers (about √(k_s/K) of the specimen's
width) are thinner than a percent of it: beyond any mesh the h/2 check asks for."""


def fall(levels: list[dict]) -> float | None:
    """The h/2 check's χ²_h of the last level over the one before (its fall per halving);
    None with fewer than two levels or a check that is zero or missing."""
    chi2 = [q.get("chi2_h") or 0.0 for q in levels[-2:]]
    return chi2[1] / chi2[0] if len(chi2) == 2 and min(chi2) > 0.0 else None


def stiff_yarn_note(levels: list[dict], fit) -> str | None:
    """What to do when fitted elastic yarns make the mesh too coarse: the h/2 check fell more
    slowly than the discretisation's order over the last two levels, and the fit put the free
    fibre moduli at K ≥ :data:`STIFF_YARNS` k_s (below the stiff limit, where they are held
    already). None otherwise (docs/speed.md, "Two force-only curves of different sizes")."""
    rho = fall(levels)
    if rho is None or rho <= SLOW_FALL:
        return None
    p, free = fit.params(), {fit.names[i] for i in fit.free}
    fibre, k_s = p.get("fibre_stretch", {}), p.get("shear", {}).get("k_s")
    if not fibre or not k_s or not any(f"fibre_stretch.{q}" in free for q in fibre):
        return None
    K = min(fibre.values())
    if K < STIFF_YARNS * k_s or K >= STIFF_CAP:
        return None
    return (
        f"the yarns are fitted at K = {K:.3g} N/mm against k_s = {k_s:.3g} N/mm (K/k_s = "
        f"{K / k_s:.2g}): their boundary layers are far thinner than these meshes, which is why "
        f"the h/2 check falls so slowly (x{rho:.2f} per halving); yarns this "
        "stiff are better held at a stiffness of their own: --params with fibre_stretch k_l and "
        "k_m from a tensile test (or a penalty such as 6e5 N/mm) and --fixed fibre_stretch"
    )
