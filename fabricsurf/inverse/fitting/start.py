"""Scale-aware starting values for fits over moduli that span orders of magnitude.

Real fabrics have fibres a thousand times stiffer than their shear (k_l ~ 10⁴ N/mm beside
k_s ~ 10 N/mm). Levenberg–Marquardt in log-moduli moves a modulus by a bounded factor per
iteration and, started at 1:1, settles in the wrong valley (soft fibres, huge bending). Cheap
remedies:

* :func:`scan_terms`: for each free term in turn, move its moduli by decades (up while that
  improves, else down, at most four decades) and keep the best; with measured reactions of
  displacement-controlled tests, every trial is first given the best common factor of all
  moduli (:func:`common_factor`: a common factor leaves the displacements unchanged and scales
  the reactions, so it is found in closed form).
* :func:`linearised_start`: a candidate effect added to a fitted model starts at the linearised
  refit (one Gauss–Newton step from the fitted model, computed from the exact sensitivities
  of the ranking run) when the linearisation holds there: one run on the fit's mesh, which
  is also the refit's first run (returned with its sensitivities), gives χ², and the start is
  taken if χ² fell by at least :data:`RHO_MIN` of the decrease the linearisation predicted
  (the trust-region test of Moré 1978). The refit then starts where its first iteration
  would have gone.
* :func:`candidate_start`: otherwise (the linearisation does not hold: a strongly nonlinear
  effect, docs/diagnosis.md) the best of the linearised estimate, a log grid around the
  candidate's natural scale (the fitted first-gradient moduli, times (width/10)² for a
  second-gradient term) and a value so small that the start is the fitted model itself: the
  refit does not creep up from zero, and is never worse than the model it extends.

The scan and the grid rank their trials on a scout mesh :data:`SCOUT_FACTOR` times coarser
than the fit's (:meth:`~.forward.ForwardSet.coarse`: same forms, a quarter of the unknowns in
2D): they choose a start among values decades apart, which a coarse mesh usually ranks as well,
and the fit itself then runs on the fine mesh (the candidate's trials shared among the ranks
when the scout is solved rank-local: :func:`.local.spread`). Where the scout ranks wrongly (a
forming run on a scout coarser than the die's lip, whose punch force is off by more than the
data's noise, ranks soft yarns first), the fit keeps the given start if that fits better on
the fine mesh (fit._scan_checked). The grid's chosen start is checked on
the fine mesh against the fitted model itself, which keeps the guarantee above; the check is
the refit's first run (docs/diagnosis.md gives the costs of the scout and the fine mesh;
docs/speed.md what the linearised start saves).
"""

from __future__ import annotations

import numpy as np

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.experiments import get_test
from fabricsurf.inverse.forward import ranks
from fabricsurf.inverse.forward.misfit import scales

MAX_DECADES = 4
RHO_MIN = 0.25
"""The linearised start is taken when its χ² decrease on the fit's mesh is at least this
fraction of the predicted one (module docstring); 0.25 is the usual trust-region threshold of
a step that is kept. In the benchmark family the ratio was 0.8–1.1."""
SCOUT_FACTOR = 2.0
"""Scout mesh size over the fit's (module docstring)."""


def scout(fm):
    """The coarse copy of ``fm`` on which starting values are ranked (module docstring)."""
    return fm.coarse(SCOUT_FACTOR)


def _preds(fm):
    p = fm.run()
    return p if isinstance(p, list) else [p]


def common_factor(fm, preds) -> float:
    """Best common factor of all moduli for the reactions (1 if not applicable)."""
    exps = fm.experiments
    if not all(
        e.has_force
        and get_test(e.test).path_unit == "length"
        and get_test(e.test).reaction_scales_with_moduli
        for e in exps
    ):
        return 1.0
    num = den = 0.0
    for e, p in zip(exps, preds):
        s2 = scales(e)[1] ** 2
        num += float(p.force @ e.force) / s2
        den += float(p.force @ p.force) / s2
    c = num / den if den > 0 else 1.0
    return c if np.isfinite(c) and c > 0 else 1.0


def _chi2(fm, vals: np.ndarray, scale: bool) -> tuple[float, np.ndarray]:
    """χ² at ``vals`` (after the common factor when ``scale``) and the values used."""
    fm.set_values(vals)
    try:
        preds = _preds(fm)
    except LoadStepError:
        return np.inf, vals
    c = common_factor(fm, preds) if scale else 1.0
    if c != 1.0:
        for p in preds:
            if p.force is not None:
                p.force = p.force * c
    r, _ = fm.residuals(preds if hasattr(fm, "models") else preds[0])
    chi2 = float(r @ r) if np.isfinite(r).all() else np.inf
    return chi2, vals * c


def held_terms(fm, free: list[int]) -> list[str]:
    """The free terms that every experiment of ``fm`` declares weakly seen (its plug-in's
    ``weak_terms``, e.g. a cantilever's membrane): the scan keeps their given moduli."""
    exps = fm.experiments
    names = {fm.params[i][0].name for i in free}
    return sorted(n for n in names if exps and all(n in get_test(e.test).weak_terms for e in exps))


def scan_terms(fm, free: list[int], vals: np.ndarray) -> np.ndarray:
    """Coordinate scan of each free term's moduli by decades, on the scout mesh (module
    docstring); the moduli of :func:`held_terms` are not scanned."""
    held = held_terms(fm, free)
    free = [i for i in free if fm.params[i][0].name not in held]
    fm = scout(fm)
    fixed_nonzero = any(vals[i] != 0 for i in range(len(vals)) if i not in free)
    scale = not fixed_nonzero
    best, vals = _chi2(fm, vals, scale)
    groups: dict[str, list[int]] = {}
    for i in free:
        groups.setdefault(fm.params[i][0].name, []).append(i)
    for idx in groups.values():
        for factor in (10.0, 0.1):
            moved = False
            for _ in range(MAX_DECADES):
                trial = vals.copy()
                trial[idx] *= factor
                chi2, used = _chi2(fm, trial, scale)
                if chi2 >= best:
                    break
                best, vals, moved = chi2, used, True
            if moved:
                break
        fm.set_values(vals)
    return vals


def natural_scale(fm, cur: np.ndarray, free: list[int], idx: list[int]) -> float:
    """The candidate's natural magnitude (module docstring)."""
    first = [cur[i] for i in free if fm.params[i][0].order == 1 and cur[i] > 0]
    s = float(np.exp(np.mean(np.log(first)))) if first else float(np.max(cur[free]))
    if fm.params[idx[0]][0].order == 2:
        w = min(e.width for e in fm.experiments)
        s *= (w / 10.0) ** 2
    return s


def _run(fm, vals: np.ndarray, sens: list[int]) -> tuple[float, object]:
    """(χ², the run) at ``vals`` on ``fm``'s own mesh, with sensitivities for ``sens`` (the
    run a fit from ``vals`` starts with); χ² = inf if the run fails."""
    fm.set_values(vals)
    try:
        pred = fm.run(sens=sens)
    except LoadStepError:
        return np.inf, None
    r, _ = fm.residuals(pred)
    return (float(r @ r) if np.isfinite(r).all() else np.inf), pred


def linearised_start(
    fm,
    free: list[int],
    idx: list[int],
    gn: np.ndarray,
    predicted: float,
    chi2_cur: float,
    warm: np.ndarray | None = None,
) -> tuple[np.ndarray | None, object, str]:
    """The linearised refit ``gn`` (of predicted χ² ``predicted``) as the start of the
    candidate's moduli ``idx`` added to the fitted model (of χ² ``chi2_cur``) if the
    linearisation holds there (module docstring); with ``warm`` (the moduli a coarser mesh
    found), that too, if better. Returns (start, its run with sensitivities for
    ``free + idx``, a note); start None: neither holds (the note says why), rank the grid."""
    sens = list(free) + list(idx)
    if not np.all(gn[idx] > 0):  # the linearisation does not want the candidate: no start
        chi2, pred = np.inf, None
    else:
        chi2, pred = _run(fm, gn, sens)
    gain = chi2_cur - predicted
    rho = (chi2_cur - chi2) / gain if gain > 0 else -np.inf
    best = (chi2, gn, pred) if chi2 < chi2_cur and rho >= RHO_MIN else (chi2_cur, None, None)
    note = (
        f"chi2 {chi2:.6g} against {predicted:.6g} predicted from {chi2_cur:.6g}: "
        f"{rho:.2f} of the predicted decrease (at least {RHO_MIN} needed)"
        if np.all(gn[idx] > 0)
        else "its modulus is not positive"
    )
    if warm is not None:
        warm = warm.copy()  # a modulus the coarser mesh left at zero: just above it
        warm[idx] = np.maximum(warm[idx], 1e-9 * np.max(warm[idx]))
        chi2_w, pred_w = _run(fm, warm, sens)
        if chi2_w < best[0]:
            best = (chi2_w, warm, pred_w)
            note += f"; the coarser mesh's moduli: chi2 {chi2_w:.6g}"
    fm.set_values(gn if best[1] is None else best[1])
    return best[1], best[2], note


def candidate_start(
    fm,
    cur: np.ndarray,
    free: list[int],
    idx: list[int],
    estimate: float,
    chi2_cur: float,
    extra: list[np.ndarray] = (),
) -> np.ndarray:
    """The best start for a candidate's moduli ``idx`` added to the fitted ``cur`` (of χ²
    ``chi2_cur`` on ``fm``'s mesh); ``extra``: further complete starting vectors (e.g. the
    linearised refit). Ranked on the scout mesh; the winner replaces the fitted model itself
    only if it is better on ``fm``'s own mesh (module docstring)."""
    return grid_start(fm, cur, free, idx, estimate, chi2_cur, extra)[0]


def grid_start(
    fm,
    cur: np.ndarray,
    free: list[int],
    idx: list[int],
    estimate: float,
    chi2_cur: float,
    extra: list[np.ndarray] = (),
    sens: list[int] | None = None,
) -> tuple[np.ndarray, object]:
    """:func:`candidate_start` and the check run on ``fm``'s mesh (with sensitivities for
    ``sens``) at the start chosen, when that is the start (None when the fitted model itself
    is: it was not run)."""
    vectors, trials = grid_trials(fm, cur, free, idx, estimate, extra)
    return grid_pick(fm, vectors, trials, grid_chi2s(fm, trials), chi2_cur, sens)


def grid_trials(
    fm,
    cur: np.ndarray,
    free: list[int],
    idx: list[int],
    estimate: float,
    extra: list[np.ndarray] = (),
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The grid of :func:`grid_start`: its plain vectors (the fitted model with the candidate
    at each trial value; the first is the fitted model itself) and every trial to rank (those
    and ``extra``, the candidate's moduli floored just above zero)."""
    s = natural_scale(fm, cur, free, idx)
    tries = [s * 1e-9] + [s * 10.0**k for k in (-6, -4, -3, -2, -1, 0, 1)]
    if estimate > 0:
        tries.append(estimate)
    vectors = []
    for t in tries:
        v = cur.copy()
        v[idx] = t
        vectors.append(v)
    trials = []
    for v in [*vectors, *extra]:
        v = v.copy()
        v[idx] = np.maximum(v[idx], s * 1e-9)
        trials.append(v)
    return vectors, trials


def grid_chi2s(fm, trials: list[np.ndarray]) -> list[float]:
    """χ² of each trial on the scout mesh of ``fm``, the trials shared among the ranks when it
    solves rank-local (:func:`~.ranks.spread`)."""
    coarse = scout(fm)
    return ranks.spread(coarse, trials, lambda v: _chi2(coarse, v, False)[0])


def grid_pick(
    fm,
    vectors: list[np.ndarray],
    trials: list[np.ndarray],
    chi2s: list[float],
    chi2_cur: float,
    sens: list[int] | None = None,
) -> tuple[np.ndarray, object]:
    """The best-ranked trial, if its check run on ``fm``'s mesh (sensitivities for ``sens``)
    beats the fitted model's χ² ``chi2_cur``, else the fitted model itself (module docstring);
    with the check run (None when the fitted model is the start)."""
    best, start = np.inf, None
    for chi2, v in zip(chi2s, trials):
        if chi2 < best:
            best, start = chi2, v
    pred = None
    if start is not None:
        chi2, pred = _run(fm, start, sens or [])
    if start is None or chi2 >= chi2_cur:
        start, pred = vectors[0], None
    fm.set_values(start)
    return start, pred
