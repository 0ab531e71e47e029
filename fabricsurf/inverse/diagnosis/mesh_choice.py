"""The diagnosis on the mesh it needs (docs/diagnosis.md, "Mesh selection").

:func:`~.diagnose.diagnose` measures its own discretisation error: χ²_h, the squared difference
in noise units between the predictions at the fit's mesh size h and at h/2, at the fitted
moduli. When that exceeds the noise tolerance band (:func:`~.significance.too_coarse`) the
diagnosis cannot tell model error from mesh error. :func:`diagnose_on_mesh` then halves h of
every experiment and diagnoses again, until the check passes or the budget is spent:

* uniform refinement by 2: the bias plug-in's mesh stays fibre-aligned (where a P × Q lattice
  fits at h, the 2P × 2Q one fits at h/2, within its size window; tests/test_mesh_choice.py);
* warm-started: the baseline fit starts at the baseline moduli found on the coarser mesh (no
  scan by decades), every effect added there is refitted again (whatever its linearised score:
  a score linearised at modulus 0 can rank a strongly nonlinear effect low) from its moduli
  there among the other starts, and the coarser mesh is the finer one's scout;
* the budget (:class:`Budget`): the displacement unknowns of the fit's mesh, all experiments
  together; the cells of the finest mesh solved (the h/2 check of the next level: sixteen
  times the cells of the present fit's mesh), the same memory guard as the command line's
  ``--max-elements``; the wall time of the whole diagnosis, a level being started only when the
  time spent plus :data:`LEVEL_GROWTH` times the last level's fits;
* the h/2 check's own rate (:func:`_by_rate`): from the second level on, when at the rate the
  check fell over the last two levels the band needs two or more halvings that the budget does
  not hold, refining stops there and says why.

Every level is recorded (h, cells, unknowns, mesh kinds, time, χ²_h against the band, verdict,
adequacy, moduli with their intervals) in the result's ``mesh_selection``; the grip depth, when
profiled, is chosen on the first mesh and kept.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.beyond import search_beyond
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.diagnosis.nuisance import with_depth
from fabricsurf.inverse.diagnosis.report import Diagnosis
from fabricsurf.inverse.fitting.plausibility import say_implausible
from fabricsurf.inverse.forward.profile import timed
from fabricsurf.log import rank0

logger = logging.getLogger(__name__)
DEFAULT_MAX_DOFS = 100_000
"""Default budget of displacement unknowns of the fit's mesh (its h/2 check solves on about
four times as many: ~100 000 cells, ~5 GB at the command line's memory estimate)."""
DEFAULT_MAX_CELLS = 400_000
"""Default budget of cells of the finest mesh solved (the command line's ``--max-elements``)."""
DEFAULT_SECONDS = 3600.0
"""Default wall-time budget of the whole diagnosis (s)."""
LEVEL_GROWTH = 4.0
"""A level on a mesh refined by 2 is predicted to take this many times the last one: four
times the unknowns (a direct solver's factorisation grows faster, the warm start saves the scan
and most iterations)."""


@dataclass(frozen=True)
class Budget:
    """How far the mesh selection may refine (module docstring); ``seconds`` None: no limit."""

    max_dofs: int = DEFAULT_MAX_DOFS
    max_cells: int = DEFAULT_MAX_CELLS
    seconds: float | None = DEFAULT_SECONDS

    def __post_init__(self) -> None:
        for name in ("max_dofs", "max_cells"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"mesh budget: {name} = {v!r} must be a whole number ≥ 1")
        s = self.seconds
        if s is not None and not (isinstance(s, (int, float)) and math.isfinite(s) and s > 0):
            raise ValueError(
                f"mesh budget: seconds = {s!r} must be a finite time > 0 (s) or None (no limit)"
            )

    def as_dict(self) -> dict:
        return {
            "max_dofs": int(self.max_dofs),
            "max_cells": int(self.max_cells),
            "seconds": self.seconds,
        }


def level_record(d: Diagnosis, seconds: float) -> dict:
    """One mesh tried: its sizes, time, the h/2 check against the noise band, the answer."""
    f = d.final_fit
    n, p = f.misfit["n"], len(f.names)
    meshes, chi2_h = d.meshes or [], d.discretisation_chi2
    return {
        "h": [m["h"] for m in meshes],
        "mesh_kind": [m["mesh_kind"] for m in meshes],
        "cells": sum(m["cells"] for m in meshes),
        "dofs": sum(m["dofs"] for m in meshes),
        "seconds": seconds,
        "chi2_h": chi2_h,
        "noise_band": (sg.adequacy_bound(n, p) - 1.0) * max(n - p, 1),
        "discretisation_misfit": None if chi2_h is None else math.sqrt(chi2_h / max(n, 1)),
        "too_coarse": d.too_coarse(),
        "verdict": d.verdict,
        "terms": list(d.terms),
        "adequate": d.adequate,
        "misfit": f.misfit["combined"],
        "moduli": {
            k: {"value": m["value"], "ci95": m.get("ci95")}
            for k, m in f.as_dict()["moduli"].items()
        },
    }


def _why_not(level: dict, spent: float, last: float, budget: Budget) -> str | None:
    """The budget the next level would exceed (None: it fits)."""
    dofs, cells = 4 * level["dofs"], 16 * level["cells"]
    h = ", ".join(f"{x / 2:.4g}" for x in level["h"])
    if dofs > budget.max_dofs:
        return (
            f"the mesh budget is spent: h = {h} mm would have about {dofs:,} unknowns, "
            f"more than max_dofs = {budget.max_dofs:,} (--max-dofs)"
        )
    if cells > budget.max_cells:
        return (
            f"the mesh budget is spent: the h/2 check of h = {h} mm would have about "
            f"{cells:,} cells, more than max_cells = {budget.max_cells:,} (--max-elements)"
        )
    if budget.seconds is not None and spent + LEVEL_GROWTH * last > budget.seconds:
        return (
            f"the time budget is spent: {spent:.0f} s used, a level at h = {h} mm would "
            f"take about {LEVEL_GROWTH * last:.0f} s more, beyond {budget.seconds:g} s "
            "(--time-budget)"
        )
    return None


def _by_rate(levels: list[dict], spent: float, budget: Budget) -> str | None:
    """Why the band is out of the budget's reach, judged by the h/2 check's own rate over the
    last two levels (None: within reach, or no rate). The check falls by ρ per halving: the
    band then needs n = ⌈log(band/χ²_h)/log ρ⌉ more halvings, each four times the unknowns and
    ``LEVEL_GROWTH`` times the time of the one before. A check that did not fall gives no rate:
    it rises before it falls where the mesh is not yet asymptotic (docs/diagnosis.md, the
    gradient clamps' held-aside case), so refining goes on within the budget."""
    rho = sg.fall(levels)
    if rho is None or rho >= 1.0:
        return None
    a, b, q = levels[-2]["chi2_h"], levels[-1]["chi2_h"], levels[-1]
    n = max(1, math.ceil(math.log(q["noise_band"] / b) / math.log(rho)))
    dofs = q["dofs"] * 4**n
    seconds = q["seconds"] * sum(LEVEL_GROWTH**k for k in range(1, n + 1))
    over = [
        f"max_dofs = {budget.max_dofs:,}" if dofs > budget.max_dofs else "",
        f"--time-budget {budget.seconds:g} s"
        if budget.seconds is not None and spent + seconds > budget.seconds
        else "",
    ]
    if n < 2 or not any(over):
        return None  # the next level may reach it, or the budget holds the levels it needs
    h = ", ".join(f"{x / 2**n:.3g}" for x in q["h"])
    size = f"{dofs:,} unknowns and {seconds:.0f} s" if n <= 6 else f"{dofs:.2g} unknowns"
    return (
        f"the h/2 check went {a:.3g} -> {b:.3g} when h was halved (x{rho:.2f}): at that "
        f"rate the noise band {q['noise_band']:.4g} needs {n} more halvings (h = {h} mm, "
        f"about {size}), beyond {' and '.join(o for o in over if o)}"
        + (PREASYMPTOTIC if rho > sg.SLOW_FALL else "")
    )


PREASYMPTOTIC = (
    f"; a fall slower than x{sg.SLOW_FALL:g} per halving is slower than the discretisation's "
    "order: these meshes are not yet asymptotic (a feature finer than h, such as the boundary "
    "layers of stiff fibres, dominates their error), so the halvings counted at that rate are a "
    "guess"
)


def warm_params(d: Diagnosis, params: dict | None) -> dict:
    """The given moduli with the baseline's replaced by its fit on the last mesh."""
    fitted = d.base_fit.params()
    return {**(params or {}), **{t: fitted[t] for t in d.baseline}}


def diagnose_on_mesh(
    exps: Experiment | list[Experiment],
    baseline: list[str],
    h: float | None = None,
    budget: Budget | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    beyond_features: int = 1,
    **kw,
) -> Diagnosis:
    """:func:`~.diagnose.diagnose` at ``h`` (default: each test's own), then on meshes refined
    by 2 while the h/2 check says the mesh is too coarse and ``budget`` allows (module
    docstring). ``kw``: the other arguments of :func:`~.diagnose.diagnose`. Returns the last
    level's diagnosis with ``mesh_selection`` filled in. Each level is logged at PROGRESS.
    When the last level's model is not adequate (and its mesh fine enough), the feature
    library is searched for up to ``beyond_features`` energies beyond the vocabulary
    (:func:`~.beyond.search_beyond`, once, on that mesh; 0: not searched)."""
    if beyond_features < 0:
        raise ValueError(f"beyond_features = {beyond_features}: 0 (no search) or more")
    exps = exps if isinstance(exps, list) else [exps]
    given = exps
    budget = budget or Budget()
    hs = [float(h) if h else get_test(e.test).default_h(e.setup) for e in exps]
    params, grip, levels = kw.pop("params", None), None, []
    t_start, warm, stopped = MPI.Wtime(), None, None
    while True:
        t0 = MPI.Wtime()
        d = diagnose(
            exps,
            baseline,
            h=hs,
            params=params,
            comm=comm,
            warm_start=warm,
            **kw,
            say_implausible=False,
            level=len(levels),
        )
        levels.append(level_record(d, comm.allreduce(MPI.Wtime() - t0, op=MPI.MAX)))
        grip = grip or d.grip_depth
        _say(comm, len(levels) - 1, levels[-1])
        if not d.too_coarse():
            break
        spent = comm.allreduce(MPI.Wtime() - t_start, op=MPI.MAX)
        stopped = comm.bcast(
            _why_not(levels[-1], spent, levels[-1]["seconds"], budget)
            or _by_rate(levels, spent, budget)
        )
        if stopped:
            break
        if grip is not None:  # the depth chosen on the first mesh: not profiled again
            exps = [with_depth(e, grip["best_mm"]) for e in exps]
            kw["grip_depths"] = None
        hs, params, warm = [x / 2 for x in hs], warm_params(d, params), d.final_fit.params()
    d.grip_depth = grip
    d.mesh_selection = {
        "budget": budget.as_dict(),
        "levels": levels,
        "refinements": len(levels) - 1,
        "stopped": stopped,
        "seconds": comm.allreduce(MPI.Wtime() - t_start, op=MPI.MAX),
    }
    if stopped:
        rank0(logger, comm, f"[mesh] not refined further: {stopped}")
    hint = sg.stiff_yarn_note(levels, d.final_fit) if d.too_coarse() else None
    d.mesh_selection["yarn_note"] = hint  # Diagnosis.notes says it again
    if hint:
        rank0(logger, comm, f"[mesh] {hint}")
    say_implausible(getattr(d, "implausible", None), comm)  # the last level's only
    if beyond_features > 0:
        with timed("search beyond the vocabulary", len(levels) - 1):
            d.beyond = search_beyond(d, given, max_features=beyond_features, comm=comm)
    return d


def _say(comm: MPI.Comm, k: int, q: dict) -> None:
    check = (
        "not measured"
        if q["chi2_h"] is None
        else f"h/2 check chi2_h = {q['chi2_h']:.4g} against the noise band "
        f"{q['noise_band']:.4g} ({'too coarse' if q['too_coarse'] else 'fine enough'})"
    )
    rank0(
        logger,
        comm,
        f"[mesh] level {k}: h = {', '.join(f'{x:.4g}' for x in q['h'])} mm "
        f"({', '.join(str(x) for x in q['mesh_kind'])}), {q['dofs']:,} unknowns, "
        f"{q['seconds']:.1f} s: verdict {q['verdict']}, adequate {q['adequate']}; " + check,
    )
