"""The rule of the search beyond the vocabulary: the corrected level, the share of the excess,
the gate, and a round's judgement (with the finer mesh's rule of :mod:`.finer_mesh`).

Multiple testing. The library offers m features at once, and its best-scored are the ones
tested, so each feature is tested at the level (1 − 0.999)/m (Bonferroni): the chance that any
of the m is called significant on data that need none stays ≤ 0.001, the level at which the
diagnosis makes every other claim. Bonferroni rather than Šidák: the features' sensitivities are
correlated (a ± pair exactly opposite), where Šidák's product rule assumes independence and
Bonferroni's sum bound holds whatever the dependence; Holm's later steps do not apply, only the
best is tested in a round. A later round tests the m − 1 features left.

The share. A feature must also remove at least :data:`SHARE_NEEDED` of the excess it is asked
to explain, Δχ² ≥ ¼ (χ² − ν) of the model it is added to (the named effects' former second
part, :mod:`..significance`). With 10⁴–10⁵ field rows the corrected Wald and F tests pass a
feature that takes up a twentieth or a two-hundredth of a lattice's discreteness error (the
default specimen at 0.01 mm noise, and a 100 × 50 mm ±40° specimen with 10⁵ rows, both with
only named effects hidden: docs/speed.md's family, 2026-12-06); such a feature does not say
what the model misses. The features found on the held-out calibration sets removed 83 % of
the excess or more, and all twelve are still found with the share (docs/lattice_effects.md).

The gate. An adequate final model may still miss one direction: the adequacy test spreads its
power over every residual, a feature's test over the one direction its sensitivity points in.
So an adequate model is searched too when the best feature's linearised χ² reduction (its score
from the exact sensitivities, one run) reaches :data:`GATE_SHARE` of the reduction the corrected
rule needs (:func:`needed_reduction`) and exceeds the h/2 check's discretisation χ² (a reduction
the mesh error alone could carry is no evidence). The gate only decides whether to refit: a
feature is still found only by the corrected rule on its refit, so the gate cannot raise the
false-alarm rate above that of a forced search; it saves the refits where no feature comes near.

The finer mesh. In the first round a feature must also stand on the h/2 check's residuals
(:mod:`.finer_mesh`), and one whose evidence moved there is judged again one mesh finer
(:mod:`.refine`): a coarse mesh's error is systematic, and a feature can take it up.
"""

from __future__ import annotations

from scipy import stats

from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.beyond import finer_mesh as fm
from fabricsurf.inverse.diagnosis.ranking import rank_round, scores
from fabricsurf.inverse.fitting.result import FitResult


def family_alpha(m: int) -> float:
    """The level each of ``m`` features is tested at (Bonferroni, module docstring)."""
    return (1.0 - sg.LEVEL) / max(m, 1)


GATE_SHARE = 0.25
"""The share of the needed Δχ² a feature's linearised reduction must reach to open the gate
(module docstring). The refit's reduction may exceed the linearised one (the fitted moduli move
too); a quarter leaves room for a factor 4, twice the largest factor measured on the
calibration sets (1.9, docs/lattice_effects.md, "The gate")."""


def f_needed(p: int, n: int, m: int) -> float:
    """The F one feature's refit must exceed on a model of ``p`` moduli and ``n`` residuals,
    with ``m`` features tested (the corrected level)."""
    return float(stats.f.ppf(1.0 - family_alpha(m), 1, max(n - p - 1, 1)))


def needed_reduction(chi2: float, p: int, n: int, m: int) -> float:
    """The Δχ² a one-modulus feature's refit must remove from a model of χ² ``chi2`` with ``p``
    moduli and ``n`` residuals to pass the corrected F-test of :func:`judge` (s² bounded by the
    base model's χ²/ν, so a slight overestimate: the gate errs towards refitting less)."""
    return f_needed(p, n, m) * max(1.0, chi2 / max(n - p - 1, 1))


def gate(
    fs, cur: FitResult, free: list[int], cand: dict, chi2_h: float | None
) -> tuple[dict, tuple]:
    """The gate of the module docstring at the fit ``cur``: the best feature's linearised
    reduction against :data:`GATE_SHARE` of :func:`needed_reduction` and ``chi2_h``. Also
    returns the residuals and sensitivities it took (the first round ranks on them)."""
    fs.set_values(cur.values)
    r, Jr = fs.residuals(fs.run(sens=True))
    sc = scores(r, Jr, cur.values, free, cand)
    best = max(cand, key=lambda c: sc[c][0])
    needed = needed_reduction(cur.chi2, len(free), cur.misfit["n"], len(cand))
    reach = max(GATE_SHARE * needed, chi2_h or 0.0)
    return {
        "feature": best,
        "linearised_delta_chi2": sc[best][0],
        "needed_delta_chi2": needed,
        "gate_share": GATE_SHARE,
        "discretisation_chi2": chi2_h,
        "open": bool(sc[best][0] >= reach),
    }, (r, Jr)


SHARE_NEEDED = sg.FRACTION_OF_EXCESS
"""The share of the excess a feature's refit must remove (module docstring, "The share")."""


def judge(row: dict, chi2: float, p: int, n: int, m: int) -> dict:
    """The significance rule of :mod:`.significance` at the corrected level, and the share of
    the excess of :data:`SHARE_NEEDED`, for a refitted candidate ``row`` (one modulus) of a
    model with χ² ``chi2`` and ``p`` moduli; its parts."""
    alpha = family_alpha(m)
    F = sg.f_statistic(chi2, p, row["refit_chi2"], p + 1, n)
    F_needed = f_needed(p, n, m)
    share = sg.share_of_excess(chi2, p, row["refit_chi2"], n)
    ok = chi2 > row["refit_chi2"] and row["wald_p"] < alpha and F > F_needed
    return {
        "significant_uncorrected": row["significant"],
        "significant": bool(ok and share >= SHARE_NEEDED),
        "delta_chi2": chi2 - row["refit_chi2"],
        "wald_p_needed": alpha,
        "f_statistic": F,
        "f_needed": F_needed,
        "share_of_excess": share,
        "share_needed": SHARE_NEEDED,
    }


def judge_round(
    fs, cur: FitResult, free: list[int], cand: dict, confirm: int, rj=None, d=None, m=None
):
    """One round: the named effects' scores and refits of the features whose linearised
    reduction reaches :data:`GATE_SHARE` of the need (the gate's reasoning, for each feature:
    a refit has never removed four times its linearised reduction), then the corrected rule,
    and, given the h/2 check's residual difference ``d`` (with ``rj``), the finer mesh's rule
    (:mod:`.finer_mesh`). ``m``: the family's size, when ``cand`` holds fewer (a feature
    judged again: it was still chosen among them)."""
    n, m = cur.misfit["n"], m or len(cand)
    floor = GATE_SHARE * needed_reduction(cur.chi2, len(free), n, m)
    rows, refits = rank_round(fs, cur, free, cand, confirm, taken=rj, floor=floor)
    finer = (
        None
        if d is None or rj is None
        else fm.finer_reductions(rj[0], d, rj[1], cur.values, free, cand)
    )
    for q in rows:
        if q.get("refit_chi2") is not None:
            q.update(judge(q, cur.chi2, len(free), n, m))
            if finer is not None:
                q.update(fm.stands_on_finer_mesh(q, finer[q["effect"]]))
                q["significant_on_this_mesh"] = q["significant"]
                q["significant"] = q["significant"] and q["stands_on_finer_mesh"]
    rows.sort(
        key=lambda q: (
            0 if q.get("refit_chi2") is not None else 1,
            q.get("refit_chi2") or 0.0,
            -q["score"],
        )
    )
    return rows, refits
