"""The search beyond the vocabulary (the package's docstring): the named effects' rounds over
the feature library, each feature tested at the Bonferroni-corrected level.

The rule (the corrected level, the share of the excess, the gate, the finer mesh) is
:mod:`.rule`'s.
"""

from __future__ import annotations

import logging
import time

from mpi4py import MPI

from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.beyond import features as ft
from fabricsurf.inverse.diagnosis.beyond import finer_mesh as fm
from fabricsurf.inverse.diagnosis.beyond import rule
from fabricsurf.inverse.diagnosis.beyond.record import _found, _outcome
from fabricsurf.inverse.diagnosis.beyond.refine import judge_finer
from fabricsurf.inverse.diagnosis.beyond.rule import family_alpha, gate, judge_round
from fabricsurf.inverse.diagnosis.nuisance import with_depth
from fabricsurf.inverse.diagnosis.report import Diagnosis
from fabricsurf.inverse.diagnosis.ties import find_tie
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.fitting.preconditions import visible_effects
from fabricsurf.inverse.forward import warm_start
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.log import rank0
from fabricsurf.model.terms import EFFECTS, make_term

logger = logging.getLogger(__name__)


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
        warm_start.seed(fs, diagnosis.carried or [])  # the final fit's states: a warm start
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
            first = not found
            d = diagnosis.final_fit.mesh_difference if first else None
            rows, refits = judge_round(fs, cur, free, cand, confirm, rj if first else None, d)
            rounds.append(rows)
            for q in [q for q in rows if q.get("significant")]:
                if fm.settled(q):
                    break
                say(
                    f"[beyond] {q['effect']}: its evidence moved on the h/2 residuals; again at h/2"
                )
                h_fit = [x.h for x in fs.models]  # the meshes in use (h may be None: defaults)
                q["at_finer_mesh"] = judge_finer(
                    exps, model, free_names, classes[q["effect"]], h_fit, len(cand), comm
                )
                if q["at_finer_mesh"]["significant"]:
                    break
                q["significant"] = False
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
            "why": rule.__doc__.split("Multiple testing. ")[1].split("\n\n")[0],
        },
        "seconds": time.perf_counter() - t0,
    }
    say(f"[beyond] {out['outcome']}")
    return out
