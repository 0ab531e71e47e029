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
the data, :func:`too_coarse`) cannot show that a model explains the data. Measured at the
issue-12 size with h = 6 mm: the fitted model's χ²_h/ν = 25.6 (h against h/2), larger than its
χ²/ν = 4.4, and the uncapped rule called it adequate.

*Significant* (nested models, k added moduli): both
1. an F-test at the 0.999 level against the residual variance actually left,
   F = (Δχ²/k) / s² with s² = max(1, χ²_new/ν_new) (the noise, inflated by the model-form error
   still present — with known noise and an adequate refit this is the χ²_k test Δχ² > 10.83);
2. the effect removes at least a quarter of the baseline's excess misfit,
   Δχ² ≥ ¼ (χ²_base − ν_base). Model-form error (a lattice against a continuum, grips of finite
   depth, large shear) leaves spatially correlated residuals: many points, few independent
   ones. Any extra modulus then fits a little of that error, and the F-test, which assumes
   independent residuals, calls it significant. An effect that is really missing removes most
   of the excess; one that only absorbs model-form error removes a small part.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

LEVEL = 0.999
CHI2_CRIT = float(stats.chi2.ppf(LEVEL, 1))
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


def adequate(chi2: float, n: int, p: int, chi2_h: float = 0.0, noise_known: bool = True
             ) -> bool:
    """The model explains the data at the noise level (module docstring; the discretisation
    credit ``chi2_h`` capped at the tolerance band). Without a stated noise level the scale
    was guessed (1 % of the largest value), so this is only indicative."""
    nu, bound = max(n - p, 1), adequacy_bound(n, p)
    credit = min(chi2_h, (bound - 1.0) * nu)
    return bool((chi2 - credit) / nu <= bound) if noise_known else \
        bool(reduced(chi2, n, p) <= bound)


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
    return bool(f_statistic(chi2_base, p_base, chi2_new, p_new, n)
                > stats.f.ppf(LEVEL, k, nu_new))


def significant(chi2_base: float, p_base: int, chi2_new: float, p_new: int, n: int) -> bool:
    """The two-part rule of the module docstring."""
    if chi2_base - chi2_new <= 0:
        return False
    return (f_test(chi2_base, p_base, chi2_new, p_new, n)
            and share_of_excess(chi2_base, p_base, chi2_new, n) >= FRACTION_OF_EXCESS)
