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
3. Confirm the ``confirm`` best-scored candidates by a nested refit that starts at the
   linearised refit (one Gauss–Newton step in all moduli from the ranking run's sensitivities)
   when one run on the fit's mesh shows the linearisation holds there; else (logged) at the
   best of the current optimum with the candidate near zero (so a refit is never worse than the
   model it extends), that step and a log grid of the candidate's modulus
   (:mod:`~fabricsurf.inverse.fitting.start`); the refit steps in the moduli, not their
   logarithms (:mod:`~.fit`). Steps 2 and 3 are one round (:mod:`~.ranking`).
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
from fabricsurf.inverse.diagnosis.excess import excess_location
from fabricsurf.inverse.diagnosis.nuisance import grip_profile, with_depth
from fabricsurf.inverse.diagnosis.ranking import rank_round
from fabricsurf.inverse.diagnosis.report import (
    Diagnosis,
    best_lead,
    look_alikes,
    where_unexplained,
)
from fabricsurf.inverse.diagnosis.ties import find_tie
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.plausibility import check_moduli, parse_plausible
from fabricsurf.inverse.fitting.preconditions import (
    SIGNED_REASON,
    check_unsigned,
    fit_preconditions,
    planar_candidates,
    visible_effects,
)
from fabricsurf.inverse.forward.profile import ROUND, progress, timed
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.inverse.forward.warm_start import carry
from fabricsurf.log import rank0
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
    yarn_spacing: float | None = None,
    plausible: dict | str | None = None,
    say_implausible: bool = True,
    level: int = 0,
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
    ``yarn_spacing`` (mm): the unit of the distances from the grips and zone boundaries by
    which the final model's excess is located (:func:`~.excess.excess_location`; default the
    mesh size); ``plausible``: ranges {"term.param": (low, high)} (or "term.param=low:high")
    the fitted moduli must keep, besides the rules on the yarns
    (:func:`~fabricsurf.inverse.fitting.plausibility.check_moduli`; warned unless
    ``say_implausible`` is False, as the mesh selection does for all but its last level).
    ``level``: the mesh level, for the stages of an active profile
    (:mod:`~fabricsurf.inverse.forward.profile`: its progress lines with the time left).

    Its stages and its fits' iterations are logged at PROGRESS (at DEBUG inside
    :func:`fabricsurf.log.detail`).
    """
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
    parse_plausible(plausible)
    if yarn_spacing is not None and not (np.isfinite(yarn_spacing) and yarn_spacing > 0):
        raise ValueError(f"yarn_spacing = {yarn_spacing}: a positive length in mm")
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
        with timed("baseline fit", level):
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
            rounds_left = max(max_effects - len(added), 1)
            progress(level, f"round {len(rankings) + 1}", [*ROUND * rounds_left, "h/2 check"])
            with timed(f"round {len(rankings) + 1}", level):
                rows, refits = rank_round(fs, cur, free, cand, confirm, warm=warm)
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
            with timed("h/2 check", level):
                cur.check_mesh(fs)
            chi2_h = cur.chi2_h
        ok = sg.adequate(cur.chi2, cur.misfit["n"], len(free), chi2_h or 0.0, fs.noise_known)
        meshes = fs.meshes()
        implausible = check_moduli(fs, cur, plausible, say=say_implausible)
        where = excess_location(exps, cur, yarn_spacing, [m["h"] for m in meshes])
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
            meshes=meshes,
            excess_location=where,
            implausible=implausible,
            carried=carry(fs, cur.values),
        )
