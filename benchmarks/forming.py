"""Forming benchmark (docs/forming.md): mesh convergence on the small hemisphere, then the cost
of a 250 mm blank.

1. ``--study convergence`` (R = 20 mm, 72 mm blank, die clearance and lip R/5 as in
   fabricsurf/studies/hemisphere_forming.py and tests/test_hemisphere.py, so that the meshes resolve
   the tools): the fitted woven fabric of docs/woven_fabric.md, with the assumed bending of
   demo_forming.py and the holder of fabricsurf/studies/hemisphere_forming.py (friction), formed to
   0.6 R in 12 steps on meshes h = R/5·√2^k,
   k = 1, 0, −1, −2. Printed per mesh: DOFs, Newton iterations, time, the punch force at the
   final stroke and the recovered shear at X = R/2 on the diagonal; then the differences of
   successive meshes and the observed rates. The same meshes in the kinematic limit (shear and
   bending a hundred times softer) give the recovered shear at X = R/2 against the fishnet
   drape: the error and its rate.
2. ``--study performance``: a 250 mm blank over R = 50 mm, the same tools, on four meshes
   h = R/4, R/5, R/7.07 (the finest in the range the convergence study shows to be
   asymptotic) and R/10 (issue 40's size). Printed per mesh: DOFs, Newton iterations and
   contact active-set changes per stroke step, the load stepper's attempts, the wall and CPU
   time; then how the CPU time grows with the number of elements. ``--tool-friction``: the
   same with friction on the punch and over the die's lip (μ = 0.3, as under the holder).

3. ``--study steps [--size quick|intermediate|full|full-150] [--case kinematic|fitted]``: one
   run of demos/demo_forming.py at its quick size (R = 20 mm, 72 mm blank, h = 4 mm), an
   intermediate one (R = 35 mm, 105 mm blank, h = 5 mm), its full size (R = 50 mm, 180 mm
   blank, h = 5 mm) or the full size before issue 40 (150 mm blank), stroke 0.6 R in 12 steps:
   the step log (per step the Newton iterations, cuts, l2 repeats, contact changes and time)
   and its totals, where the time of the demo goes, with the CPU time of the busiest rank
   beside the wall time (a measure a shared machine does not inflate).
4. ``--study demo [--size ...] [--runs ...]``: the demo's four forming runs (kinematic check,
   fitted, bending / 10, locking at 40°) on one experiment as the demo makes them: per run the
   steps, Newton iterations, cuts, l2 repeats, wall and CPU time; the machine's load beside
   them.

Run: ``mpirun -n 2 python benchmarks/forming.py [--study convergence|performance|both|steps]``.
"""

import argparse
import logging
import math
import sys
import time
from itertools import pairwise
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.experiments.forming.stroke_log import StrokeLog
from fabricsurf.log import configure, rank0
from fabricsurf.studies import hemisphere_forming as parts
from fabricsurf.verification.drapes.fishnet import bisector_shear

logger = logging.getLogger(__name__)

comm = MPI.COMM_WORLD
STROKE_FRACTION, STEPS = 0.6, 12
DOCUMENTED_PARAMS = parts.documented_fit()
"""The fitted woven fabric the benchmark forms: the one demo_forming.py forms without a params
file (fabricsurf.datasets.woven_fit), so that the benchmark measures what the demo runs."""


TOOL_FRICTION = {"punch_friction": 0.3, "die_friction": 0.3}
"""Friction on the punch and over the die's lip, as under the holder (fabric on steel)."""


def form(
    R: float,
    blank: float,
    h: float,
    values: dict | None = None,
    count_changes: bool = False,
    tooling: dict | None = None,
) -> dict:
    """One forming run; its DOFs, cost, punch force and recovered shear at X = R/2."""
    model = parts.forming_model(DOCUMENTED_PARAMS["params"], 0.1, 0.1)
    with parts.experiment(R, blank, h, 45.0, model, comm, **(tooling or {})) as e:
        parts.set_moduli(e, values or {})
        dofs = 3 * e.problem.V.dofmap.index_map.size_global
        changes, last = [], [e.active_set()]

        def count(k, s):
            now = e.active_set()
            changes.append(comm.allreduce(int(np.count_nonzero(now != last[0])), op=MPI.SUM))
            last[0] = now

        t0, c0 = time.perf_counter(), time.process_time()
        its = e.run(STROKE_FRACTION * R, STEPS, on_step=count if count_changes else None)
        seconds = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        cpu = comm.allreduce(time.process_time() - c0, op=MPI.MAX)
        p = e.profile(e.diagonal_deg, np.array([0.5 * R]))
        return {
            "h": h,
            "dofs": dofs,
            "cells": e.specimen.mesh.topology.index_map(2).size_global,
            "seconds": seconds,
            "cpu": cpu,
            "iterations": list(its),
            "attempts": list(e.stepper.attempts),
            "dissipated": e.dissipated(),
            "changes": changes,
            "force": e.force[-1],
            "shear": float(p["shear_recovered_deg"][0]),
            "gap": float(p["gap"][0]),
        }


SIZES = {
    "quick": (20.0, 72.0, 4.0),
    "intermediate": (35.0, 105.0, 5.0),
    "full": (50.0, 180.0, 5.0),
    "full-150": (50.0, 150.0, 5.0),
}
"""(R, blank, h) in mm of the step and demo studies; quick and full are those of
demo_forming.py, full-150 its full size before issue 40 (the blank's edge inside the holder's
pressure ramp)."""


def demo(size: str, runs: list[str], steps: int = STEPS) -> None:
    """The forming runs of demos/demo_forming.py on one experiment, in its order (each starts
    from the flat blank; the forms are compiled once): per run the steps, Newton iterations,
    cuts, l2 repeats, wall and CPU time (busiest rank), and the totals."""
    R, blank, h = SIZES[size]
    params = DOCUMENTED_PARAMS["params"]
    every = {
        "kinematic": parts.KINEMATIC,
        "fitted": parts.fitted_values(params, 0.1),
        **parts.effect_variants(params, 0.1),
    }
    rank0(
        logger,
        comm,
        f"== demo runs: {size} (R = {R:g} mm, {blank:g} mm blank, h = {h:g} mm),"
        f" stroke {STROKE_FRACTION * R:g} mm in {steps} steps, {comm.size} ranks, "
        f"load {_load()} ==",
    )
    rows, t0 = [], time.perf_counter()
    with parts.experiment(R, blank, h, 45.0, parts.forming_model(params, 0.1, 0.1), comm) as e:
        setup = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        for name in [n for n in every if n in runs or "all" in runs]:
            t, c = time.perf_counter(), time.process_time()
            try:
                r = parts.reform(e, every[name], STROKE_FRACTION * R, steps, label=f"{name}: ")
                book, note = r["step_log"], f"{r['diagonal_shear_max_diff_deg']:.2f} deg"
            except LoadStepError as err:
                book, note = StrokeLog.totals(e.steps), f"stopped at {err.last_load:.4g} mm"
            rows.append(
                (
                    name,
                    book,
                    comm.allreduce(time.perf_counter() - t, op=MPI.MAX),
                    comm.allreduce(time.process_time() - c, op=MPI.MAX),
                    note,
                )
            )
    rank0(logger, comm, f"\nset-up (mesh, forms) {setup:.1f} s; load now {_load()}")
    rank0(
        logger,
        comm,
        "run                 steps  Newton  cuts  l2   wall s   CPU s  CPU s/it  "
        "diagonal vs fishnet / stop",
    )
    for name, b, wall, cpu, note in rows:
        rank0(
            logger,
            comm,
            f"{name:18s} {b['steps']:6d} {b['newton_iterations']:7d} "
            f"{b['cuts']:5d} {b['fallbacks']:3d} {wall:8.1f} {cpu:7.1f} "
            f"{cpu / max(b['newton_iterations'], 1):9.3f}  {note}",
        )
    its = sum(b["newton_iterations"] for _, b, *_ in rows)
    rank0(
        logger,
        comm,
        f"total: {its} Newton iterations, {sum(w for *_, w, _, _ in rows):.1f} s "
        f"wall, {sum(c for *_, c, _ in rows):.1f} s CPU on the busiest rank",
    )


def _load() -> str:
    """The machine's 1-minute load average (the times of a shared machine depend on it)."""
    try:
        return Path("/proc/loadavg").read_text().split()[0]
    except OSError:
        return "?"


def steps(size: str, case: str) -> None:
    R, blank, h = SIZES[size]
    values = (
        parts.KINEMATIC
        if case == "kinematic"
        else {**DOCUMENTED_PARAMS["params"], "normal_bending": {"k_b": 0.1}, "twist": {"k_t": 0.1}}
    )
    rank0(
        logger,
        comm,
        f"== steps: {size} (R = {R:g} mm, {blank:g} mm blank, h = {h:g} mm), "
        f"{case}, {comm.size} ranks ==",
    )
    model = parts.forming_model(DOCUMENTED_PARAMS["params"], 0.1, 0.1)
    with parts.experiment(R, blank, h, 45.0, model, comm) as e:
        parts.set_moduli(e, values)
        t0, c0 = time.perf_counter(), time.process_time()
        e.run(STROKE_FRACTION * R, STEPS)
        seconds = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        cpu = comm.allreduce(time.process_time() - c0, op=MPI.MAX)
        book = StrokeLog.totals(e.steps)
    rank0(logger, comm, "\n step  stroke  Newton  cuts  l2  contact   s")
    for r in e.steps:
        rank0(
            logger,
            comm,
            f"{r['step']:5d} {r['stroke_mm']:7.2f} {r['newton_iterations']:7d} "
            f"{r['attempts'] - 1:5d} {r['fallbacks']:3d} {r['contact_changes']:8d}"
            f" {r['seconds']:5.1f}",
        )
    rank0(
        logger,
        comm,
        f"total: {book['newton_iterations']} Newton iterations, {book['cuts']} "
        f"cuts, {book['fallbacks']} l2 repeats, {seconds:.1f} s wall "
        f"({seconds / max(book['newton_iterations'], 1):.3f} s per iteration), "
        f"{cpu:.1f} s of CPU on the busiest rank (the wall time on an idle "
        "machine; on a shared one the wall time is inflated)",
    )


def rates(values: list[float]) -> tuple[list[float], list[float]]:
    """Differences of successive meshes and the observed rates (mesh ratio √2)."""
    d = [abs(a - b) for a, b in pairwise(values)]
    return d, observed_rates(d)


def observed_rates(errors: list[float]) -> list[float]:
    """log(e_k / e_k+1) / log √2 of successive errors or differences (mesh ratio √2)."""
    return [
        math.log(a / b) / math.log(math.sqrt(2.0)) if a > 0 and b > 0 else float("nan")
        for a, b in pairwise(errors)
    ]


def convergence() -> None:
    R, blank = 20.0, 72.0
    meshes = [R / 5.0 * math.sqrt(2.0) ** k for k in (1, 0, -1, -2)]
    rank0(
        logger,
        comm,
        f"== convergence: R = {R:g} mm, {blank:g} mm blank, stroke "
        f"{STROKE_FRACTION * R:g} mm in {STEPS} steps ==",
    )
    rows, kin = [], []
    for h in meshes:
        rows.append(form(R, blank, h))
        kin.append(form(R, blank, h, parts.KINEMATIC))
        r, k = rows[-1], kin[-1]
        rank0(
            logger,
            comm,
            f"h = {h:6.3f} mm ({r['dofs']} DOFs): {r['seconds']:6.1f} s, "
            f"{sum(r['iterations'])} Newton iterations, force {r['force']:.5g} N, "
            f"shear at R/2 {r['shear']:.4g} deg; kinematic limit {k['shear']:.4g}"
            f" deg ({k['seconds']:.1f} s)",
        )
    for key, label in (("force", "punch force (N)"), ("shear", "shear at X = R/2 (deg)")):
        d, r = rates([row[key] for row in rows])
        rank0(
            logger,
            comm,
            f"{label}: differences {np.round(d, 4).tolist()}; observed rates "
            f"{np.round(r, 2).tolist()}",
        )
    exact = float(np.degrees(bisector_shear(R, np.array([0.5 * R])))[0])
    err = [abs(k["shear"] - exact) for k in kin]
    r = observed_rates(err)
    rank0(
        logger,
        comm,
        f"kinematic limit at X = R/2: fishnet {exact:.4f} deg; errors "
        f"{np.round(err, 4).tolist()}; observed rates {np.round(r, 2).tolist()}"
        f"; gaps to the punch {np.round([k['gap'] for k in kin], 4).tolist()} mm",
    )


def performance(
    tools: bool = False,
    divisions: tuple = (4.0, 5.0, 5.0 * math.sqrt(2.0), 10.0),
) -> None:
    """The 250 mm blank on meshes h = R/d for d in ``divisions`` (default four); with ``tools``
    friction on the punch and the die's lip too (:data:`TOOL_FRICTION`), else under the holder
    only."""
    R, blank = 50.0, 250.0
    which = "friction on all tools" if tools else "friction under the holder"
    rank0(
        logger,
        comm,
        f"== performance: R = {R:g} mm, {blank:g} mm blank, {which}, {comm.size} "
        f"ranks, load {_load()} ==",
    )
    rows = []
    for h in (R / d for d in divisions):
        r = form(R, blank, h, count_changes=True, tooling=TOOL_FRICTION if tools else None)
        rows.append(r)
        rank0(
            logger,
            comm,
            f"h = {h:.3f} mm: {r['dofs']} DOFs, {r['cells']} cells, "
            f"{r['seconds']:.1f} s, force {r['force']:.5g} N, dissipated "
            f"{r['dissipated']:.5g} N·mm",
        )
        rank0(
            logger,
            comm,
            f"  Newton iterations per step {r['iterations']}; attempts {r['attempts']}",
        )
        rank0(logger, comm, f"  active-set changes per step {r['changes']}")
    rank0(logger, comm, "\n    h   cells   DOFs  wall s  CPU s  Newton its  CPU s/iteration")
    for r in rows:
        n = sum(r["iterations"])
        rank0(
            logger,
            comm,
            f"{r['h']:6.3f} {r['cells']:6d} {r['dofs']:6d} {r['seconds']:7.1f} "
            f"{r['cpu']:6.1f} {n:10d}  {r['cpu'] / n:.3f}",
        )
    first, last = rows[0], rows[-1]
    if len(rows) > 1:
        grow = math.log(last["cpu"] / first["cpu"]) / math.log(last["cells"] / first["cells"])
        rank0(logger, comm, f"CPU time grows as cells^{grow:.2f}")
    rank0(
        logger,
        comm,
        f"h = R/{R / last['h']:.3g} takes {last['seconds']:.1f} s "
        f"wall, {last['cpu']:.1f} s CPU on the busiest rank (issue 40: at most a "
        f"minute on 2 ranks); load now {_load()}",
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--study", choices=("convergence", "performance", "both", "steps", "demo"), default="both"
    )
    ap.add_argument("--size", choices=tuple(SIZES), default="quick")
    ap.add_argument("--steps", type=int, default=STEPS, help="demo study: stroke steps")
    ap.add_argument(
        "--runs",
        nargs="+",
        default=["all"],
        help="demo study: which runs (kinematic, fitted, 'bending / 10', "
        "'locking at 40 deg'; default all)",
    )
    ap.add_argument("--case", choices=("kinematic", "fitted"), default="kinematic")
    ap.add_argument(
        "--tool-friction",
        action="store_true",
        help="performance study: friction on the punch and the die's lip too",
    )
    ap.add_argument(
        "--divisions",
        default="4,5,7.0711,10",
        help="performance study: meshes h = R/d, comma-separated d (default "
        "4,5,7.0711,10; 10 is issue 40's size)",
    )
    args = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    if args.study == "steps":
        steps(args.size, args.case)
    if args.study == "demo":
        demo(args.size, args.runs, args.steps)
    if args.study in ("convergence", "both"):
        convergence()
    if args.study in ("performance", "both"):
        performance(args.tool_friction, tuple(float(d) for d in args.divisions.split(",")))
