"""One round of the stepwise diagnosis (:mod:`~.diagnose`, steps 2 and 3 of its docstring):
score every candidate effect by the χ² reduction that linearising about the current fit
predicts (:func:`scores`), then confirm the best-scored ones by nested refits, each started from
the best of the current optimum, the linearised refit (:func:`gauss_newton_start`) and a grid
of the candidate's modulus, and tested for significance (:mod:`~.significance`): the rows of
the round's ranking, best first. Whether to add the best, and when to stop, is
:func:`~.diagnose.diagnose`'s.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.fitting.start import candidate_start
from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.forward import ranks
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.inverse.uncertainty import statistical as unc


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


def _refit(
    fs: ForwardSet,
    cur: FitResult,
    free: list[int],
    idx: list[int],
    estimate: float,
    gn: np.ndarray,
    warm: np.ndarray | None = None,
) -> FitResult:
    """Nested refit from the current optimum, the candidate at its best start (among them,
    with ``warm``, the moduli a coarser mesh found for it)."""
    extra = [gn]
    if warm is not None and np.any(warm[idx] > 0):
        extra.append(cur.values.copy())
        extra[-1][free + idx] = warm[free + idx]
    fs.set_values(candidate_start(fs, cur.values, free, idx, estimate, cur.chi2, extra=extra))
    res = fit(fs, free + idx, scale_start=False, space="linear")
    fs.set_values(cur.values)
    return res


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
):
    """One round of the stepwise search (module docstring of :mod:`.diagnose`): score every
    candidate of ``cand`` ({name: indices of its moduli}) at the current fit ``cur``, refit the
    ``confirm`` best (and every one ``warm`` holds above zero) and judge each refit; returns
    (rows, refits). The search beyond the vocabulary runs its rounds with it too."""
    fs.set_values(cur.values)
    r, Jr = fs.residuals(fs.run(sens=True))
    sc = scores(r, Jr, cur.values, free, cand)
    order = sorted(cand, key=lambda c: -sc[c][0])
    rows, n = [], cur.misfit["n"]
    again = [] if warm is None else [c for c in order[confirm:] if np.any(warm[cand[c]] > 0)]
    chosen = order[:confirm] + again  # and every effect a coarser mesh added

    def refit(c: str) -> FitResult:
        gn = gauss_newton_start(r, Jr, cur.values, free, cand[c])
        return _refit(fs, cur, free, cand[c], sc[c][1], gn, warm)

    small = r.size <= ranks.SPREAD_RESIDUALS  # the refits are gathered on every rank
    refits = dict(zip(chosen, ranks.spread(fs, chosen, refit) if small else map(refit, chosen)))
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
