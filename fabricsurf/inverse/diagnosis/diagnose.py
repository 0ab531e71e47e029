"""Which physical effect is missing? Stepwise diagnosis (docs/diagnosis.md).

1. Fit the baseline terms to all experiments at once (:func:`fabricsurf.inverse.fitting.fit.fit`:
   a scan by decades, then steps in the moduli themselves).
   With ``grip_depths``, the effective grip depth of the bias experiments is first profiled
   as a nuisance parameter (:mod:`~fabricsurf.inverse.diagnosis.nuisance`).
2. Rank every vocabulary effect the data can see and the model lacks with one forward run:
   the model holds all those effects (vocabulary order, so one compiled form serves every
   diagnosis), candidates at modulus 0, so the state is the current fit; tangent solves give
   dr/dp for every modulus. The score of candidate c is the χ² reduction predicted by
   linearising about the fit with c's moduli (together, ≥ 0) as an extra parameter, the fitted
   moduli free: with s⊥ = dr/dp_c projected off the fitted sensitivities,
   score = (s⊥·r)²/|s⊥|² if the estimated modulus −(s⊥·r)/|s⊥|² is positive, else 0.
3. Confirm the ``confirm`` best-scored candidates by a nested refit that starts from the best of
   the current optimum with the candidate near zero (so a refit is never worse than the model it
   extends), the linearised refit (one Gauss–Newton step in all moduli) and a log grid of the
   candidate's modulus (:mod:`~.start`); the refit steps in the moduli, not
   their logarithms (:mod:`~.fit`).
4. Add the best confirmed candidate if it is significant (:mod:`~.significance`), and repeat
   from 2 until the model is adequate, nothing is significant, or ``max_effects`` were added.

The verdict is the first effect added (None if none), with the candidates the data cannot tell
from it (a tie, :mod:`~.ties`); ``adequate`` tells whether the final model
explains the data at the noise level, allowing for the discretisation error measured at h/2.
A final model that is not adequate with nothing left to add is reported as unexplained misfit,
with the steps and regions where it remains (:func:`~.report.where_unexplained`).
"""

from __future__ import annotations

import logging

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.contract.data import check_field_moves
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.choices import check_choices, library_labels
from fabricsurf.inverse.diagnosis.nuisance import grip_profile, with_depth
from fabricsurf.inverse.diagnosis.report import (
    Diagnosis,
    best_lead,
    look_alikes,
    where_unexplained,
)
from fabricsurf.inverse.diagnosis.ties import find_tie
from fabricsurf.inverse.fitting.fit import FitResult, fit
from fabricsurf.inverse.fitting.preconditions import (
    SIGNED_REASON,
    check_unsigned,
    fit_preconditions,
    planar_candidates,
    visible_effects,
)
from fabricsurf.inverse.fitting.start import candidate_start
from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.forward import ranks
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.inverse.uncertainty import statistical as unc
from fabricsurf.log import detail, rank0
from fabricsurf.model.terms import EFFECTS, make_term

logger = logging.getLogger(__name__)


def full_model(
    baseline: list[str], params: dict | None = None, visible: list[str] | None = None
) -> list:
    """Baseline + every visible effect, in vocabulary order; the candidates at modulus 0."""
    params = params or {}
    visible = (
        visible
        if visible is not None
        else [n for n in EFFECTS if EFFECTS[n].in_plane and not EFFECTS[n].signed]
    )
    model = []
    for n in EFFECTS:
        if n not in baseline and n not in visible:
            continue
        t = make_term(n, **params.get(n, {}))
        if n not in baseline:
            t.set(**{p: 0.0 for p in t.parameters()})
        model.append(t)
    return model


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


def _rank_round(
    fs,
    cur: FitResult,
    free: list[int],
    cand: dict,
    confirm: int,
    verbose: bool | None = None,
    warm: np.ndarray | None = None,
):
    # verbose: unused, kept for beyond.py's positional call until it is converted
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


def diagnose(
    exps: Experiment | list[Experiment],
    baseline: list[str],
    h: float | list[float] | None = None,
    params: dict | None = None,
    confirm: int = 2,
    max_effects: int = 2,
    check_discretisation: bool = True,
    comm: MPI.Comm = MPI.COMM_WORLD,
    candidates: list[str] | None = None,
    fixed: list[str] | None = None,
    grip_depths: list[float] | None = None,
    warm_start: dict | None = None,
    *,
    verbose: bool | None = None,
) -> Diagnosis:
    """Fit ``baseline`` to ``exps``, then rank → confirm → add (module docstring).

    ``candidates``: the effects to consider (default: every effect the data can see);
    ``fixed``: baseline terms held at their moduli in ``params`` (known from other tests);
    ``grip_depths``: candidate grip depths (mm) of the bias experiments, profiled first
    (:mod:`~fabricsurf.inverse.diagnosis.nuisance`); the best is used. ``h``: one element size,
    or one per experiment; ``warm_start``: the final moduli {term: {param: value}} of this
    diagnosis on a coarser mesh (:mod:`~.mesh_choice`; ``params`` then hold its baseline
    optimum): the baseline fit skips its scan by decades, and every effect it added is refitted
    in each round (best-scored or not), starting also from its moduli there.

    Its stages and its fits' iterations are logged at PROGRESS. ``verbose`` is kept only for
    the callers still to convert (demos/demo_bending.py, demos/demo_woven_fabric.py): False
    logs that progress at DEBUG (:func:`fabricsurf.log.detail`); otherwise it does nothing.
    """
    with detail(verbose is False):
        return _diagnose(
            exps,
            baseline,
            h,
            params,
            confirm,
            max_effects,
            check_discretisation,
            comm,
            candidates,
            fixed,
            grip_depths,
            warm_start,
        )


def _diagnose(
    exps,
    baseline,
    h,
    params,
    confirm,
    max_effects,
    check_discretisation,
    comm,
    candidates,
    fixed,
    grip_depths,
    warm_start,
) -> Diagnosis:
    exps = exps if isinstance(exps, list) else [exps]
    visible = seen = visible_effects(exps)
    check_choices(
        list(baseline),
        candidates,
        fixed,
        params or {},
        visible,
        confirm,
        max_effects,
        library_labels(list(baseline), candidates, fixed),
    )
    check_unsigned(list(baseline) + list(candidates or []))
    planar_candidates(exps, candidates)
    fit_preconditions(
        exps,
        [make_term(n, **(params or {}).get(n, {})) for n in baseline],
        list(fixed or []),
        "diagnose",
    )
    visible = [n for n in visible if n in baseline or not EFFECTS[n].signed]
    for e in exps:  # a field that did not move is refused here too, not only when loaded
        check_field_moves(
            e,
            e.files[1]
            if len(e.files) > 1 and e.has_field
            else f"the field of experiment '{e.name}'",
        )
    fixed = list(fixed or [])
    if candidates is not None:
        visible = [n for n in visible if n in candidates or n in baseline]
    grip = (
        None
        if grip_depths is None
        else grip_profile(
            exps,
            grip_depths,
            lambda: full_model(baseline, params, visible),
            [n for n in baseline if n not in fixed],
            h,
            comm,
        )
    )
    exps = exps if grip is None else [with_depth(e, grip["best_mm"]) for e in exps]
    with ForwardSet(exps, full_model(baseline, params, visible), h=h, comm=comm) as fs:
        idx_of = {n: [i for i, (t, _) in enumerate(fs.params) if t.name == n] for n in EFFECTS}
        free = sorted(i for n in baseline if n not in fixed for i in idx_of[n])
        t0 = MPI.Wtime()
        warm = (
            None
            if warm_start is None
            else np.array([warm_start.get(t.name, {}).get(p, 0.0) for t, p in fs.params])
        )
        cur = base = fit(fs, free, space="linear", scale_start=warm is None)
        t_fit = MPI.Wtime() - t0
        terms, path, rankings, added = list(baseline), [], [], []
        tie = None
        path.append({"terms": list(terms), "misfit": cur.misfit["combined"], "chi2": cur.chi2})
        rank0(
            logger,
            comm,
            f"[diagnose] baseline {'+'.join(terms)}: misfit {cur.misfit['combined']:.4g}",
        )
        while True:
            cand = {n: idx_of[n] for n in visible if n not in terms and idx_of[n]}
            ok = sg.adequate(cur.chi2, cur.misfit["n"], len(free), noise_known=fs.noise_known)
            if not cand or (ok and rankings) or len(added) >= max_effects:
                break
            rows, refits = _rank_round(fs, cur, free, cand, confirm, warm=warm)
            rankings.append(rows)
            sig = [q for q in rows if q["significant"]]
            if ok or not sig:
                break
            c = sig[0]["effect"]
            if not added:
                tie = find_tie(fs, rows, refits, free, cand)
            cur, free = refits[c], sorted(free + cand[c])
            terms.append(c)
            added.append(c)
            path.append({"added": c, "misfit": cur.misfit["combined"], "chi2": cur.chi2})
            rank0(logger, comm, f"[diagnose] added {c}: misfit {cur.misfit['combined']:.4g}")
        fs.set_values(cur.values)
        chi2_h = None
        if check_discretisation:
            cur.check_mesh(fs)
            chi2_h = cur.chi2_h
        ok = sg.adequate(cur.chi2, cur.misfit["n"], len(free), chi2_h or 0.0, fs.noise_known)
        invisible = [
            {"effect": n, "reason": "planar (2D) data cannot see out-of-plane effects"}
            for n in EFFECTS
            if n not in seen and n not in baseline
        ]
        invisible += [
            {"effect": n, "reason": SIGNED_REASON}
            for n in seen
            if EFFECTS[n].signed and n not in baseline
        ]
        invisible += look_alikes(
            terms + [q["effect"] for r in rankings for q in r if q["significant"]], exps
        )
        return Diagnosis(
            baseline=list(baseline),
            base_fit=base,
            final_fit=cur,
            terms=terms,
            ranking=rankings[0] if rankings else [],
            rounds=rankings,
            verdict=added[0] if added else None,
            adequate=ok,
            path=path,
            not_identifiable=invisible,
            discretisation_chi2=chi2_h,
            unexplained=None
            if ok
            else where_unexplained(
                exps,
                cur,
                best_lead(rankings[-1], cur, len(free))
                if rankings and not any(q["significant"] for q in rankings[-1])
                else None,
            ),
            fit_seconds=t_fit,
            noise_known=fs.noise_known,
            grip_depth=grip,
            tie=tie,
            meshes=fs.meshes(),
        )
