"""Ties: candidate effects the data cannot tell apart (docs/diagnosis.md, "Ties").

The refits of two candidates a and b (the same fitted model plus one effect each) are not
nested, so the F and Wald tests that decide whether an effect is significant cannot choose
between them. Their χ² difference is compared with its own resolution instead, in the manner
of Vuong's (1989) test for non-nested models. With r_a, r_b the two refits' residuals (noise
units) and δ = r_b − r_a the difference of their predictions,

    Δχ² = χ²_b − χ²_a = Σ δ_i (2 r_a,i + δ_i),   Var(Δχ² | design) = 4 Var(Σ δ_i e_i)

with e the noise: the variance is taken given the design (the two fitted predictions fixed,
the noise random), estimated over the blocks (regions × load steps) that carry the moduli's
covariance (:mod:`~.uncertainty`), D_g = Σ_{i∈g} δ_i r_a,i, σ² = G/(G − 1) Σ_g D_g², and, when
the data state their noise level, not below |δ|² (the white-noise value; as the moduli's
intervals, the stated noise is a floor). Then

    z = (Δχ² − (k_a − k_b) ln n) / (2σ)

(Schwarz's correction for unequal numbers of moduli, 0 here) is referred to Student's t with
G − 1 degrees of freedom. Vuong's own variance, the sample variance of the per-datum
log-likelihood differences ½(r_b,i² − r_a,i²), counts how unevenly the two models misfit over
the specimen as if it were noise: with 39 blocks it called a misfit of 0.97 against one of 1.49
(Δχ² = 385, |δ| = 18.8) a tie, p = 0.002 (docs/diagnosis.md). A model-form error that both
refits share (residuals several noise levels, correlated) widens σ through r_a, as it widens
the moduli's intervals: the data then separate only what stands out of it.
The ordering a before b was chosen by χ², so the test is two-sided; the data choose a over b
only if they reject "equally close" at the level :data:`~.significance.LEVEL` that every other
claim of the diagnosis is made at. Otherwise the verdict is the set: a tie. The other refits
compared are every refitted candidate, significant or not: one whose own modulus fails the
Wald test but fits as well (or better: z < 0, a tie too) is not excluded by the data.

What it means: with white noise Δχ² has the standard deviation 2|δ| and, if one of the two
is true, the mean ±|δ|², so the data separate them only when |δ|/2 exceeds the critical z. The
numbers reported show it: both χ², Δχ², its resolution 2σ, z, p, |δ| and the cosine of the two
candidates' sensitivities projected off the fitted moduli (near-collinear effects, cos → 1,
are what make |δ| small).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.uncertainty import statistical as unc


@dataclass
class Tie:
    """The tied candidates (``members``: the verdict, the best refit, first), the comparison of
    the best with every other significant refitted candidate (``comparisons``) and the refits
    themselves (for :mod:`~.discrimination`; not in the JSON)."""

    members: list[str]
    comparisons: list[dict]
    refits: dict[str, FitResult] = field(default_factory=dict)

    @property
    def tied(self) -> bool:
        return len(self.members) > 1

    def others(self) -> list[str]:
        return self.members[1:]

    def as_dict(self) -> dict:
        return {
            "level": sg.LEVEL,
            "test": "Vuong (non-nested), clustered over regions x load steps, two-sided",
            "comparisons": self.comparisons,
        }


def vuong(
    r_a: np.ndarray,
    r_b: np.ndarray,
    labels: np.ndarray | None,
    k_a: int = 1,
    k_b: int = 1,
    noise_known: bool = True,
) -> dict:
    """Vuong's z of model a against b (positive: a closer) on residuals in noise units, with
    the variance of Δχ² = χ²_b − χ²_a given the design, clustered over ``labels`` (None: every
    datum its own block), the stated noise as its floor; the two-sided p-value and the
    resolution of Δχ² (module docstring)."""
    delta = r_b - r_a
    if labels is None:
        labels = np.arange(len(delta))
    _, inv = np.unique(labels, return_inverse=True)
    D = np.bincount(inv, weights=delta * r_a)
    G = len(D)
    var = G / max(G - 1, 1) * float(D @ D)
    if noise_known:
        var = max(var, float(delta @ delta))
    resolution = 2.0 * float(np.sqrt(var))
    dchi2 = float(r_b @ r_b - r_a @ r_a)
    stat = dchi2 - (k_a - k_b) * np.log(len(delta))
    z = stat / resolution if resolution > 0 else 0.0
    p = float(2.0 * stats.t.sf(abs(z), max(G - 1, 1)))
    return {"delta_chi2": dchi2, "resolution": resolution, "z": z, "p": p, "blocks": G}


def projected_cosine(
    ra: FitResult, rb: FitResult, base: list[int], ia: list[int], ib: list[int]
) -> float:
    """cos between the candidates' sensitivities (dr/dp summed over each one's moduli, from its
    refit's Jacobian) projected off the fitted moduli ``base`` (from refit a's)."""

    def column(rf: FitResult, idx: list[int]) -> np.ndarray:
        return rf.J[:, [rf.free.index(i) for i in idx]].sum(axis=1)

    Q = la.thin_q(
        ra.J[:, [ra.free.index(i) for i in base]], "ties: the fitted moduli's sensitivities"
    )
    sa, sb = column(ra, ia), column(rb, ib)
    sa, sb = sa - Q @ (Q.T @ sa), sb - Q @ (Q.T @ sb)
    na, nb = np.linalg.norm(sa), np.linalg.norm(sb)
    return float(sa @ sb / (na * nb)) if na > 0 and nb > 0 else 1.0


def compare(
    fs, ra: FitResult, rb: FitResult, base: list[int], ia: list[int], ib: list[int]
) -> dict:
    """Refit a (the better) against refit b: Vuong's test, |δ| and the projected cosine."""
    labels = unc.blocks(fs, ra.prediction)
    out = vuong(ra.r, rb.r, labels, len(ia), len(ib), fs.noise_known)
    return out | {
        "chi2": [ra.chi2, rb.chi2],
        "misfit": [ra.misfit["combined"], rb.misfit["combined"]],
        "prediction_difference": float(np.linalg.norm(ra.r - rb.r)),
        "cosine": projected_cosine(ra, rb, base, ia, ib),
        "tied": out["p"] > 1.0 - sg.LEVEL or out["z"] < 0,
    }


def find_tie(
    fs, rows: list[dict], refits: dict[str, FitResult], base: list[int], cand: dict[str, list[int]]
) -> Tie:
    """The best significant refit of a round (``rows`` sorted best first, one significant) and
    every other refitted candidate the data cannot tell from it (module docstring). A refit
    whose own modulus is not significant still ties when it fits as well: the data cannot
    then claim the verdict over it (a lattice with geodesic bending hidden, docs/diagnosis.md:
    its refit was the best by χ², its Wald test failed, two others passed)."""
    tried = [q for q in rows if q["effect"] in refits]
    best = next(q["effect"] for q in tried if q["significant"])
    members, comparisons = [best], []
    for q in tried:
        c = q["effect"]
        if c == best:
            continue
        row = {"effects": [best, c], "significant": bool(q["significant"])} | compare(
            fs, refits[best], refits[c], base, cand[best], cand[c]
        )
        comparisons.append(row)
        if row["tied"]:
            members.append(c)
    return Tie(members, comparisons, {c: refits[c] for c in members})
