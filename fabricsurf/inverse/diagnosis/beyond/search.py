"""The search beyond the vocabulary (the package's docstring): the named effects' rounds over
the feature library, each feature tested at the Bonferroni-corrected level.

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
"""

from __future__ import annotations

import logging
import time

from mpi4py import MPI
from scipy import stats

from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.beyond import features as ft
from fabricsurf.inverse.diagnosis.beyond.record import _found, _outcome
from fabricsurf.inverse.diagnosis.nuisance import with_depth
from fabricsurf.inverse.diagnosis.ranking import rank_round, scores
from fabricsurf.inverse.diagnosis.report import Diagnosis
from fabricsurf.inverse.diagnosis.ties import find_tie
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.preconditions import visible_effects
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.log import rank0
from fabricsurf.model.terms import EFFECTS, make_term

logger = logging.getLogger(__name__)


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


COARSE = (
    "the mesh is too coarse for these data (refine h first: a feature would take up "
    "the discretisation error)"
)


def _gate_text(door: dict) -> str:
    """The gate's numbers as a clause."""
    h = door["discretisation_chi2"]
    return (
        f"the best feature {door['feature']} removes Δχ² = "
        f"{door['linearised_delta_chi2']:.3g} linearised; the corrected rule needs "
        f"{door['needed_delta_chi2']:.3g}" + (f", the h/2 check's χ² is {h:.3g}" if h else "")
    )


def _shut(door: dict) -> str:
    """Why the gate stayed shut."""
    h = door["discretisation_chi2"]
    if (
        h is not None
        and door["linearised_delta_chi2"] >= door["gate_share"] * door["needed_delta_chi2"]
    ):
        return "no feature's reduction stands above the mesh's own error"
    return "no feature comes near the rule"


def _final_model(d: Diagnosis) -> tuple[list, list[str]]:
    """The diagnosis's final terms at their moduli (vocabulary order) and the free moduli."""
    f, params = d.final_fit, d.final_fit.params()
    model = [make_term(n, **params[n]) for n in EFFECTS if n in d.terms]
    return model, [f.names[k] for k in f.free]


def _round(fs, cur: FitResult, free: list[int], cand: dict, confirm: int, rj=None):
    """One round: the named effects' scores and refits of the features whose linearised
    reduction reaches :data:`GATE_SHARE` of the need (the gate's reasoning, for each feature:
    a refit has never removed four times its linearised reduction), then the corrected rule."""
    n, m = cur.misfit["n"], len(cand)
    floor = GATE_SHARE * needed_reduction(cur.chi2, len(free), n, m)
    rows, refits = rank_round(fs, cur, free, cand, confirm, taken=rj, floor=floor)
    for q in rows:
        if q.get("refit_chi2") is not None:
            q.update(judge(q, cur.chi2, len(free), n, m))
    rows.sort(
        key=lambda q: (
            0 if q.get("refit_chi2") is not None else 1,
            q.get("refit_chi2") or 0.0,
            -q["score"],
        )
    )
    return rows, refits


def search_beyond(
    diagnosis: Diagnosis,
    exps: Experiment | list[Experiment],
    *,
    confirm: int = 2,
    max_features: int = 1,
    force: bool = False,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> dict:
    """Search the feature library for what the diagnosis's final model misses (module
    docstring). ``exps``: the experiments the diagnosis was given; ``force``: search even when
    the final model is adequate (calibration on null data). Returns a JSON-able record:
    ``outcome`` (the sentence), ``found`` (per feature added: formula, share of the excess,
    modulus with its 95 % interval, tie, map, Term source), ``rounds`` (every feature's score
    and refit), ``library``, ``excluded`` and ``multiple_testing``."""
    exps = exps if isinstance(exps, list) else [exps]
    t0 = time.perf_counter()
    if diagnosis.too_coarse() and not force:
        return {"searched": False, "outcome": f"not searched: {COARSE}", "found": []}
    adequate = "the final model is adequate"
    why_not = COARSE if diagnosis.too_coarse() else adequate if diagnosis.adequate else None
    if diagnosis.grip_depth is not None:
        exps = [with_depth(e, diagnosis.grip_depth["best_mm"]) for e in exps]
    three_d = any(not EFFECTS[n].in_plane for n in visible_effects(exps))
    specs, excluded = ft.library(three_d)
    model, free_names = _final_model(diagnosis)
    h = [q["h"] for q in diagnosis.meshes] if diagnosis.meshes else None

    def say(msg: str) -> None:
        rank0(logger, comm, msg)

    say(f"[beyond] {len(specs)} features beyond the vocabulary")
    with (
        ft.registered(specs) as classes,
        ForwardSet(exps, model + [c(k=0.0) for c in classes.values()], h=h, comm=comm) as fs,
    ):
        idx = {n: [i for i, (t, _) in enumerate(fs.params) if t.name == n] for n in classes}
        free = [fs.names.index(n) for n in free_names]
        cur = fit(fs, free, scale_start=False, space="linear")
        door, rj = gate(fs, cur, free, idx, diagnosis.discretisation_chi2)
        if why_not == adequate and door["open"]:
            why_not = None
            say(f"[beyond] adequate, but {_gate_text(door)}: searching")
        if why_not and not force:  # adequate: a too-coarse mesh returned above
            out = {
                "searched": False,
                "outcome": f"not searched: {why_not}, and {_shut(door)} ({_gate_text(door)})",
                "found": [],
                "gate": door,
            }
            say(f"[beyond] {out['outcome']}")
            return out
        found, rounds, base = [], [], cur
        while len(found) < max_features:
            cand = {n: i for n, i in idx.items() if n not in [f["feature"] for f in found]}
            rows, refits = _round(fs, cur, free, cand, confirm, None if found else rj)
            rounds.append(rows)
            sig = [q for q in rows if q.get("significant")]
            if not sig:
                break
            c = sig[0]["effect"]
            tie = find_tie(fs, rows, refits, free, cand).members
            found.append(_found(ft.spec_of(c), sig[0], refits[c], cur, fs.experiments, tie))
            cur, free = refits[c], sorted(free + cand[c])
            say(
                f"[beyond] {c}: misfit {base.misfit['combined']:.4g} → {cur.misfit['combined']:.4g}"
            )
            if sg.adequate(
                cur.chi2,
                cur.misfit["n"],
                len(free),
                diagnosis.discretisation_chi2 or 0.0,
                fs.noise_known,
            ):
                break
    m = len(specs)
    out = {
        "searched": True,
        "forced_past": why_not,
        "gate": door,
        "model": list(diagnosis.terms),
        "outcome": _outcome(found, rounds[-1] if rounds else []),
        "found": found,
        "rounds": rounds,
        "library": [s.name for s in specs],
        "excluded": excluded,
        "misfit_before": base.misfit["combined"],
        "misfit_after": cur.misfit["combined"],
        "multiple_testing": {
            "method": "Bonferroni",
            "family_size": m,
            "family_level": sg.LEVEL,
            "level_per_feature": family_alpha(m),
            "why": __doc__.split("Multiple testing. ")[1].split("\n\n")[0],
        },
        "seconds": time.perf_counter() - t0,
    }
    say(f"[beyond] {out['outcome']}")
    return out
