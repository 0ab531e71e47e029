"""One round of the stepwise diagnosis (:mod:`~.diagnose`, steps 2 and 3 of its docstring):
score every candidate effect by the χ² reduction that linearising about the current fit
predicts (:func:`scores`), then confirm the best-scored ones by nested refits, each started from
the linearised refit (:func:`gauss_newton_start`) where the linearisation holds, else from the
best of the current optimum, the linearised refit and a grid of the candidate's modulus
(:mod:`~.start`; such a fallback is logged), and tested for significance
(:mod:`~.significance`): the rows of the round's ranking, best first. Whether to add the best,
and when to stop, is :func:`~.diagnose.diagnose`'s.
"""

from __future__ import annotations

import logging

import numpy as np

from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.fitting.start import (
    grid_chi2s,
    grid_pick,
    grid_start,
    grid_trials,
    linearised_start,
    scout,
)
from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.forward import profile, ranks, warm_start
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.inverse.uncertainty import statistical as unc
from fabricsurf.log import rank0

logger = logging.getLogger(__name__)


def scores(
    r: np.ndarray, Jr: np.ndarray, vals: np.ndarray, base: list[int], cand: dict[str, list[int]]
) -> dict[str, tuple[float, float]]:
    """Linearised χ² reduction and modulus estimate per candidate (module docstring)."""
    Q = la.thin_q(Jr[:, base] * vals[base], "diagnose: the candidates' scores")
    out = {}
    for name, idx in cand.items():
        s = Jr[:, idx].sum(axis=1)
        s = s - Q @ (Q.T @ s)
        ss = float(s @ s)
        est = -float(s @ r) / ss if ss > 0 else 0.0
        out[name] = (float(s @ r) ** 2 / ss if est > 0 else 0.0, est)
    return out


def gauss_newton_start(
    r: np.ndarray, Jr: np.ndarray, cur: np.ndarray, free: list[int], idx: list[int]
) -> np.ndarray:
    """The linearised refit: one Gauss–Newton step in the fitted moduli and the candidate's
    (together) from the current optimum, each modulus kept positive (at most a factor e^1.5
    down, as the fit's own step limit)."""
    A = np.column_stack([Jr[:, free], Jr[:, idx].sum(axis=1)])
    step = la.lstsq(A, -r, "diagnose: the linearised refit")
    v = cur.copy()
    v[free] = np.maximum(cur[free] + step[:-1], cur[free] * np.exp(-1.5))
    v[idx] = max(step[-1], 0.0)
    return v


def predicted_chi2(
    r: np.ndarray, Jr: np.ndarray, cur: np.ndarray, v: np.ndarray, free: list[int], idx: list[int]
) -> float:
    """χ² at the moduli ``v`` (the fitted ``free`` moved, the candidate's ``idx`` all at one
    value) as the linearisation about the current optimum ``cur`` predicts it."""
    lin = r + Jr[:, free] @ (v[free] - cur[free]) + Jr[:, idx].sum(axis=1) * v[idx[0]]
    return float(lin @ lin)


def _near(cur: FitResult, free: list[int], idx: list[int], warm) -> np.ndarray | None:
    """The fitted model with the moduli a coarser mesh found for the candidate (None: none)."""
    if warm is None or not np.any(warm[idx] > 0):
        return None
    near = cur.values.copy()
    near[free + idx] = warm[free + idx]
    return near


def _start(fs, cur: FitResult, free: list[int], idx: list[int], gn: tuple, warm) -> tuple:
    """The linearised start (:func:`~.start.linearised_start`): (start or None, its run, what
    did not hold, the grid's extra trials should it be needed)."""
    near = _near(cur, free, idx, warm)
    start, first, note = linearised_start(fs, free, idx, gn[0], gn[1], cur.chi2, near)
    return start, first, note, [gn[0]] + ([] if near is None else [near])


def _fit_from(fs, cur: FitResult, free: list[int], idx: list[int], start, first) -> FitResult:
    """The nested refit from ``start`` (``first``: its run, if made), kept for warm starts."""
    fs.set_values(start)
    res = fit(fs, free + idx, scale_start=False, space="linear", first=first)
    warm_start.latest(fs, res.values)  # the next round's ranking starts there if it is added
    fs.set_values(cur.values)
    return res


def _refit(
    fs: ForwardSet,
    cur: FitResult,
    free: list[int],
    idx: list[int],
    estimate: float,
    gn: tuple[np.ndarray, float],
    warm: np.ndarray | None = None,
) -> tuple[FitResult, str | None]:
    """Nested refit from the current optimum, the candidate at the linearised refit ``gn``
    (its moduli and predicted χ²) where the linearisation holds, else at the best start of
    the grid (:mod:`~.start`; among them, with ``warm``, the moduli a coarser mesh found for
    it). Returns the refit and, after a fallback to the grid, what did not hold."""
    start, first, note, extra = _start(fs, cur, free, idx, gn, warm)
    if start is None:
        start, first = grid_start(
            fs, cur.values, free, idx, estimate, cur.chi2, extra, sens=free + idx
        )
    else:
        note = None
    return _fit_from(fs, cur, free, idx, start, first), note


def _shared_refits(fs, cur, free, cand, chosen, estimates, gns, warm) -> list[tuple]:
    """:func:`_refit` of every candidate of ``chosen``, shared among the ranks in three passes:
    the linearised starts (one candidate per rank), then the grids of those whose start does
    not hold, their trials pooled and shared among all ranks (not ranked by the one rank that
    drew the candidate while the others wait), then the refits (each on the rank that made its
    start, which keeps the start's run)."""
    kept = {}

    def start(c):
        s, kept[c], note, extra = _start(fs, cur, free, cand[c], gns[c], warm)
        return s, note, extra

    starts = dict(zip(chosen, ranks.spread(fs, chosen, start)))
    grids = {
        c: grid_trials(fs, cur.values, free, cand[c], estimates[c], starts[c][2])
        for c in chosen
        if starts[c][0] is None
    }
    pooled = [v for c in grids for v in grids[c][1]]
    chi2s = iter(grid_chi2s(fs, pooled) if pooled else [])
    ranked = {c: [next(chi2s) for _ in grids[c][1]] for c in grids}

    def finish(c):
        s, note, _ = starts[c]
        first = kept.get(c)
        if s is None:
            s, first = grid_pick(fs, *grids[c], ranked[c], cur.chi2, free + cand[c])
        else:
            note = None
        return _fit_from(fs, cur, free, cand[c], s, first), note

    return ranks.spread(fs, chosen, finish)


def candidate_wald(rf: FitResult, idx: list[int]) -> tuple[float, float]:
    """The Wald test of a refit's candidate moduli ``idx`` against zero on the refit's
    correlated-residual covariance (:func:`~.uncertainty.wald`)."""
    pos = [rf.free.index(i) for i in idx]
    st = rf.statistical
    return unc.wald(rf.values[idx], st.cov[np.ix_(pos, pos)], st.dof)


def rank_round(
    fs,
    cur: FitResult,
    free: list[int],
    cand: dict,
    confirm: int,
    warm: np.ndarray | None = None,
    taken: tuple | None = None,
    floor: float = 0.0,
):
    """One round of the stepwise search (module docstring of :mod:`.diagnose`): score every
    candidate of ``cand`` ({name: indices of its moduli}) at the current fit ``cur``, refit the
    ``confirm`` best whose score reaches ``floor`` (and every one ``warm`` holds above zero) and
    judge each refit; returns (rows, refits). ``taken``: the residuals and sensitivities at
    ``cur``, when the caller has them. The search beyond the vocabulary runs its rounds with it
    too, with a floor."""
    fs.set_values(cur.values)
    with profile.stage("ranking"):
        r, Jr = taken if taken is not None else fs.residuals(fs.run(sens=True))
    sc = scores(r, Jr, cur.values, free, cand)
    order = sorted(cand, key=lambda c: -sc[c][0])
    rows, n = [], cur.misfit["n"]
    again = [] if warm is None else [c for c in order[confirm:] if np.any(warm[cand[c]] > 0)]
    best = [c for c in order[:confirm] if sc[c][0] >= floor]
    chosen = best + again  # and every effect a coarser mesh added

    gns = {}
    for c in chosen:
        gn = gauss_newton_start(r, Jr, cur.values, free, cand[c])
        gns[c] = (gn, predicted_chi2(r, Jr, cur.values, gn, free, cand[c]))
    estimates = {c: sc[c][1] for c in chosen}
    small = r.size <= ranks.SPREAD_RESIDUALS  # the refits are gathered on every rank
    if small:  # a refit whose linearised start fails ranks a grid on the scout: built here,
        scout(fs)  # on every rank, not by one rank inside the shared refits (a collective)
    with profile.stage("refits"):
        if small:
            done = _shared_refits(fs, cur, free, cand, chosen, estimates, gns, warm)
        else:
            done = [_refit(fs, cur, free, cand[c], estimates[c], gns[c], warm) for c in chosen]
    refits = {c: rf for c, (rf, _) in zip(chosen, done)}
    for c, (_, note) in zip(chosen, done):  # said here: a shared refit ran on another rank
        if note is not None:
            rank0(
                logger,
                fs.comm,
                f"  refit of {c}: the linearised start does not hold ({note}); "
                "started from the best of the grid instead",
            )
    for c in order:
        row = {
            "effect": c,
            "score": sc[c][0],
            "linearised_modulus": sc[c][1],
            "refit_misfit": None,
            "significant": None,
        }
        if c in refits:
            rf = refits[c]
            F, p = candidate_wald(rf, cand[c])
            row.update(
                refit_misfit=rf.misfit["combined"],
                refit_chi2=rf.chi2,
                refit_params=rf.params()[c],
                refit_std={k: s for k, s in rf.std_dict().items() if k.startswith(c + ".")},
                wald_F=F,
                wald_p=p,
                share_of_excess=sg.share_of_excess(cur.chi2, len(free), rf.chi2, n),
                f_test_passed=sg.f_test(cur.chi2, len(free), rf.chi2, len(free) + len(cand[c]), n),
                significant=sg.significant(
                    cur.chi2, len(free), rf.chi2, len(free) + len(cand[c]), n, wald_p=p
                ),
            )
        rows.append(row)
    rows.sort(
        key=lambda q: (1, -q["score"]) if q["refit_misfit"] is None else (0, q["refit_misfit"])
    )
    return rows, refits
