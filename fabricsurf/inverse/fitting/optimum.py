"""What a fit reports at its optimum (docs/uncertainty.md): the moduli with their statistical
covariance, the cluster-robust sandwich over blocks of residuals (:mod:`~.uncertainty`), the
model-form spread between parts of the data (:mod:`~.systematic`), and the combinations of
moduli the data do not determine (:func:`undetermined`). The search for the optimum is
:func:`~.fit.fit`'s."""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.fitting.result import FitResult, Forward
from fabricsurf.inverse.uncertainty import intervals, systematic
from fabricsurf.inverse.uncertainty import statistical as unc

RANK_TOL = intervals.RANK_TOL
"""Singular values of the scaled Jacobian below this fraction of the largest are null
directions (:func:`~.intervals.null_directions`)."""


def undetermined(names: list[str], Jt: np.ndarray) -> list[str]:
    """The null directions of the scaled Jacobian Jt = dr/d(log p) (a rank-deficient Fisher
    matrix JtᵀJt; :func:`~.intervals.scaled_jacobian`), each as its combination of log-moduli,
    e.g. "0.71 log a.k - 0.71 log b.k" (the ratio a.k/b.k is not determined; a signed modulus
    appears as itself, without "log"); :func:`~.intervals.null_directions`, O(N·p) memory for
    N residuals, never N × N."""
    signed = dict(zip(names, intervals.signed_mask(names)))
    out = []
    for v in intervals.null_directions(Jt).T:
        terms = [(c, n) for c, n in zip(v, names) if abs(c) > 0.05 * np.abs(v).max()]
        if terms[0][0] < 0:  # the first term positive
            terms = [(-c, n) for c, n in terms]
        out.append(
            " ".join(
                f"{'-' if c < 0 else '+'} {abs(c):.2g} {'' if signed[n] else 'log '}{n}"
                for c, n in terms
            ).lstrip("+ ")
        )
    return out


def optimum_result(
    fm: Forward,
    free: list[int],
    vals: np.ndarray,
    pred,
    r: np.ndarray,
    Jr: np.ndarray,
    chi2: float,
    it: int,
    runs: int,
    hist: list,
) -> FitResult:
    """The FitResult at the optimum: statistical covariance over blocks of residuals and the
    model-form spread between parts of the data (module docstring); a modulus in a null
    direction of the Fisher matrix gets an infinite standard deviation (:meth:`FitResult.lost`:
    the caller says so)."""
    labels = unc.blocks(fm, pred)
    names = list(np.array(fm.names)[free])
    stat = unc.sandwich(Jr, r, labels, fm.noise_known)
    std = np.zeros(len(vals))
    std[free] = np.sqrt(np.maximum(np.diag(stat.cov), 0.0))
    tau = systematic.model_form(Jr, r, systematic.parts(fm, pred), labels, fm.noise_known)
    res = FitResult(
        list(fm.names),
        vals,
        std,
        chi2,
        fm.misfit(pred),
        pred,
        it,
        runs,
        hist,
        undetermined(names, intervals.scaled_jacobian(Jr, vals[free], names)),
        free=list(free),
        J=Jr,
        r=r,
        statistical=stat,
        model_form=tau,
    )
    lost = res.lost()
    if lost:  # a null direction's zero variance is not a known modulus
        res.std[[k for k, n in enumerate(res.names) if n in lost]] = np.inf
    return res
