"""Statistical uncertainty of fitted moduli under correlated residuals (docs/uncertainty.md).

The residuals are grouped into blocks, regions of the specimen × load steps (each step's force
its own block), and the covariance of the moduli is the cluster-robust sandwich
    C = G/(G − P) · B M B,   B = (JᵀJ)⁺,   M = Σ_g (J_gᵀ r_g)(J_gᵀ r_g)ᵀ
(Liang & Zeger 1986; Cameron & Miller 2015) with the exact sensitivities J = dr/dp of the fit,
G blocks and P fitted moduli: residuals may be correlated inside a block (DIC subsets, a
model-form error that is smooth in space), not between blocks. Intervals use Student's t with
G − P degrees of freedom. When the data state their noise level, no standard deviation is taken
below that of the classical (JᵀJ)⁻¹: the sandwich estimate is itself noisy with few blocks and
biased low (Bell & McCaffrey 2002), the stated noise a floor. The design effect
deff = tr(C_naive⁻¹ C)/P (Kish 1965), C_naive = s²(JᵀJ)⁻¹ with s² = χ²/ν, gives the effective
number of independent residuals n/deff. Everything is p × p or G × p (G blocks): the block
scores are sums over each block's rows (O(N) memory for N residuals, :mod:`~.linalg`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.forward.load_path import Prediction

GRID = 4
"""Regions per side of the specimen: each region × load step is one block."""


def experiment_blocks(exp, pred, grid: int = GRID) -> np.ndarray:
    """Block label of every residual of :func:`~.misfit.residuals` (same order): the field
    residuals by region (grid × grid over the points' bounding box) and step, each step's
    force residual a block of its own, the shear angles (a formed part) by region and step as
    the field."""
    c = pred.u.shape[1]
    inside = np.isfinite(pred.u).all(axis=1)
    parts = []
    if exp.has_field:
        lab = _region_steps(exp, exp.X[:, :2], exp.field_step, grid)
        parts.append(np.repeat(lab[inside], c))
    if exp.has_force:
        parts.append(len(exp.steps) * grid * grid + np.arange(len(exp.steps)))
    if exp.has_shear:
        lab = _region_steps(exp, exp.shear_X, exp.shear_step, grid)
        parts.append(len(exp.steps) * (grid * grid + 1) + lab[np.isfinite(pred.shear)])
    return np.concatenate(parts) if parts else np.zeros(0, int)


def _region_steps(exp, X: np.ndarray, steps: np.ndarray, grid: int) -> np.ndarray:
    """(step, region) labels of points X at ``steps``: grid × grid over their bounding box."""
    lo, span = X.min(axis=0), np.maximum(np.ptp(X, axis=0), 1e-300)
    cell = np.minimum(((X - lo) / span * grid).astype(int), grid - 1)
    step = np.searchsorted(exp.steps, steps)
    return (step * grid + cell[:, 0]) * grid + cell[:, 1]


def blocks(fm, preds, grid: int = GRID) -> np.ndarray | None:
    """Block labels of a ForwardModel's or ForwardSet's stacked residuals (distinct across
    experiments); None for a model without experiments and predictions (then the classical
    covariance)."""
    exps = getattr(fm, "experiments", None)
    preds = preds if isinstance(preds, list) else [preds]
    if exps is None or not all(isinstance(p, Prediction) for p in preds):
        return None
    out, offset = [], 0
    for exp, pred in zip(exps, preds):
        lab = experiment_blocks(exp, pred, grid)
        out.append(lab + offset)
        offset += (2 * len(exp.steps) + 1) * grid * grid + len(exp.steps)
    return np.concatenate(out)


@dataclass
class Statistical:
    """Covariance of the fitted moduli (in the moduli, not their logarithms) and its basis."""

    cov: np.ndarray
    cov_naive: np.ndarray
    n_blocks: int
    dof: int
    design_effect: float
    n_effective: float

    def t95(self) -> float:
        """The two-sided 95 % quantile of Student's t with the blocks' degrees of freedom."""
        return float(stats.t.ppf(0.975, max(self.dof, 1)))

    def as_dict(self, n: int) -> dict:
        return {
            "method": "cluster-robust sandwich over regions x load steps",
            "blocks": self.n_blocks,
            "dof": self.dof,
            "t95": self.t95(),
            "design_effect": self.design_effect,
            "n": n,
            "n_effective": self.n_effective,
        }


def _meat(J: np.ndarray, r: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, int]:
    """Σ_g (J_gᵀ r_g)(J_gᵀ r_g)ᵀ and the number of blocks G."""
    uniq, inv = np.unique(labels, return_inverse=True)
    scores = la.block_sums(J * r[:, None], inv, len(uniq))
    return la.finite(scores.T @ scores, "uncertainty: the sandwich's block scores"), len(uniq)


def sandwich(
    J: np.ndarray, r: np.ndarray, labels: np.ndarray | None, noise_known: bool = True
) -> Statistical:
    """The cluster-robust covariance of the module docstring (``labels``: one block label per
    residual; None: the classical covariance, scaled by χ²/ν when the noise is not known)."""
    n, P = J.shape
    B = la.gram_pinv(J, "uncertainty: (JᵀJ)⁺")
    chi2 = float(r @ r)
    s2 = chi2 / max(n - P, 1)
    naive = B * (1.0 if noise_known else s2)
    if labels is None or P == 0:
        return Statistical(naive, naive, n, max(n - P, 1), 1.0, float(n))
    M, G = _meat(J, r, labels)
    C = G / max(G - P, 1) * B @ M @ B
    if noise_known:  # the stated noise as a floor of every standard deviation
        d, d0 = np.sqrt(np.maximum(np.diag(C), 0)), np.sqrt(np.maximum(np.diag(B), 0))
        scale = np.where(d > 0, np.maximum(d, d0) / np.where(d > 0, d, 1.0), 1.0)
        C = C * np.outer(scale, scale)
    deff = design_effect(B * s2, C)
    return Statistical(C, naive, G, max(G - P, 1), deff, n / max(deff, 1.0))


def design_effect(C_naive: np.ndarray, C: np.ndarray) -> float:
    """tr(C_naive⁺ C)/P: the average variance inflation over the fitted directions."""
    P = len(C)
    if P == 0:
        return 1.0
    return float(np.trace(la.pinv(C_naive, "uncertainty: the design effect") @ C) / P)


def wald(values: np.ndarray, cov: np.ndarray, dof: int) -> tuple[float, float]:
    """(F, p): the Wald statistic F = vᵀC⁻¹v/k of added moduli v ≥ 0 against zero and its
    one-sided p-value (F(k, dof); for k = 1 the one-sided t-test, the moduli being ≥ 0)."""
    v = np.atleast_1d(values)
    k = len(v)
    F = float(v @ la.pinv(np.atleast_2d(cov), "Wald test: the covariance") @ v / k)
    if k == 1:
        sd = float(np.sqrt(max(cov.ravel()[0], 1e-300)))
        return F, float(stats.t.sf(v[0] / sd, max(dof, 1)))
    return F, float(stats.f.sf(F, k, max(dof, 1)))
