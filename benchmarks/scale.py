"""Compare, fit and diagnose at the size of DIC data: time and memory per stage (issue 36).

Synthetic bias-extension field data on the full specimen (187 × 119 mm, 12 steps to 15 % of the
length, fibres at ±45°): the continuum solution with geodesic bending (A_g = 40 N·mm) at the
default mesh, evaluated at an nx × ny grid of points per step (``--points``: the total number of
field rows over all steps), plus Gaussian noise (0.02 mm, 0.05 N); written with the contract's
writer. Then, through the command line in this process, as a user would:

* ``fit DATA --terms fibre_stretch,shear,geodesic_bending`` (with the h/2 mesh check);
* ``compare DATA --params fit.json`` (misfit, figures, per-point CSV, the prediction bands;
  the true moduli, without bands, when the fit failed);
* ``diagnose DATA --terms fibre_stretch,shear --max-effects 1 --confirm 1``.

Every command's wall time is split into the stages of the issue by wrapping the functions that
do them (time inside a nested stage counts for that stage only): reading (the loader),
forward solves (the load stepping and Newton solves), sensitivities (the tangent solves),
evaluation at points (locating the points and evaluating there), statistics (residuals,
misfits, covariances, identifiability, scores), figures, writing (JSON, CSV), and "other" (mesh
building, form set-up, the fit's own loop). The peak resident memory of each rank per stage is
read from VmHWM after resetting it at the stage's start (/proc/self/clear_refs). The growth
exponent of each stage is log(t₂/t₁)/log(N₂/N₁) between successive sizes (≈ 1: O(N); stages
that take well under a second are dominated by fixed costs, their exponents mean little).
The CPU seconds of each stage are printed beside its wall time (on a shared machine the wall
time is mostly waiting; MPI's busy waiting counts as CPU), and per command the forward runs per
element size (with or without sensitivities), their Newton iterations and seconds.
``--profile`` writes rank 0's cProfile of each command; ``--cold`` turns the warm start of the
forward runs off (inverse/forward/warm_start.py: every load step from the last converged one,
as before), for comparison; ``--distributed`` solves every mesh distributed over the ranks
(before the rank-local solves of inverse/forward/ranks.py); ``--diagnose-args`` passes
options to diagnose (e.g. ``--max-dofs 1``: the default mesh only, no mesh selection).
Aims (issue 36): at 10⁶ points ≤ 2 GB per rank, a one-effect diagnosis ≤ 2 min on 2 ranks.
``--limit-gb`` sets an address-space limit per process (RLIMIT_AS) to show what fails under it.

    mpirun -n 2 .venv/bin/python benchmarks/scale.py --points 1e4,1e5,1e6 --out out/scale
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import functools
import importlib
import io
import json
import logging
import math
import pstats
import resource
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.cli import main
from fabricsurf.inverse.contract.data import write_experiment
from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, rank0

logger = logging.getLogger(__name__)

LENGTH, WIDTH, STEPS, STRAIN = 187.0, 119.0, 12, 0.15
TRUTH = {
    "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
    "shear": {"k_s": 0.5},
    "geodesic_bending": {"A_g": 40.0},
}
NOISE_MM, NOISE_N = 0.02, 0.05
STAGES = (
    "reading",
    "forward solves",
    "sensitivities",
    "evaluation at points",
    "statistics",
    "figures",
    "writing",
    "other",
)
HOOKS = {  # stage: (module, name), name "Class.method" for a method; missing ones are skipped
    "reading": [("fabricsurf.inverse.contract.data", "load_experiment")],
    "forward solves": [("fabricsurf.inverse.forward.runs", "ForwardModel.run")],
    "sensitivities": [("fabricsurf.inverse.forward.tangent", "sensitivities")],
    "evaluation at points": [
        ("fabricsurf.discretise.evaluation", "eval_points"),
        ("fabricsurf.discretise.evaluation", "PointLocator.__init__"),
        ("fabricsurf.discretise.evaluation", "PointLocator.__call__"),
    ],
    "statistics": [
        ("fabricsurf.inverse.forward.misfit", "residuals"),
        ("fabricsurf.inverse.forward.misfit", "misfit"),
        ("fabricsurf.inverse.uncertainty.statistical", "sandwich"),
        ("fabricsurf.inverse.uncertainty.statistical", "blocks"),
        ("fabricsurf.inverse.uncertainty.systematic", "model_form"),
        ("fabricsurf.inverse.uncertainty.systematic", "mesh_shift"),
        ("fabricsurf.inverse.fitting.optimum", "undetermined"),
        ("fabricsurf.inverse.fitting.fit", "FitResult.uncertainty"),
        ("fabricsurf.inverse.diagnosis.ranking", "scores"),
        ("fabricsurf.inverse.diagnosis.ranking", "gauss_newton_start"),
        ("fabricsurf.inverse.forward.linalg", "lstsq"),
        ("fabricsurf.inverse.fitting.band", "_half_widths"),
    ],
    "figures": [
        ("fabricsurf.inverse.plots.figures", n)
        for n in (
            "error_map",
            "field_band",
            "force_curves",
            "force_band",
            "error_vs_step",
            "misfit_path",
        )
    ],
    "writing": [
        ("fabricsurf.discretise.output", "write_json"),
        ("fabricsurf.inverse.plots.outputs", "_per_point"),
        ("fabricsurf.inverse.plots.outputs", "field_band_csv"),
        ("fabricsurf.inverse.fitting.band", "write_band"),
    ],
}


def peak_mb(reset: bool = False) -> float:
    """This process's peak resident memory since the last reset (MB); ``reset``: start anew."""
    with open("/proc/self/status") as f:
        hwm = next(int(x.split()[1]) for x in f if x.startswith("VmHWM:")) / 1024.0
    if reset:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    return hwm


class Stages:
    """Exclusive wall time and peak memory per stage (module docstring)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.t = dict.fromkeys(STAGES, 0.0)
        self.cpu = dict.fromkeys(STAGES, 0.0)
        self.peak = dict.fromkeys(STAGES, 0.0)
        # [stage, start, time in nested stages, peak so far, CPU start, CPU in nested stages]
        self.stack: list[list] = []
        self.counts: dict[str, int] = {}  # forward runs per mesh size, Newton iterations

    def count_run(self, fn):
        """Wrap ForwardModel.run: count the runs per element size and their Newton iterations."""

        @functools.wraps(fn)
        def counted(model, *a, **k):
            pred = fn(model, *a, **k)
            key = f"h={model.h:.4g}" + (" +sens" if (a and a[0]) or k.get("sens") else "")
            for name, v in (
                (f"runs {key}", 1),
                (f"newton {key}", pred.newton),
                (f"seconds {key}", round(pred.seconds, 1)),
            ):
                self.counts[name] = self.counts.get(name, 0) + v
            return pred

        return counted

    def enter(self, stage: str) -> None:
        if self.stack:
            self.stack[-1][3] = max(self.stack[-1][3], peak_mb())
        peak_mb(reset=True)
        self.stack.append([stage, time.perf_counter(), 0.0, 0.0, time.process_time(), 0.0])

    def leave(self) -> None:
        stage, t0, nested, peak, c0, cnested = self.stack.pop()
        dt, dc = time.perf_counter() - t0, time.process_time() - c0
        self.t[stage] += dt - nested
        self.cpu[stage] += dc - cnested
        peak = max(peak, peak_mb())
        self.peak[stage] = max(self.peak[stage], peak)
        if self.stack:
            self.stack[-1][5] += dc
            self.stack[-1][2] += dt
            self.stack[-1][3] = max(self.stack[-1][3], peak)

    def wrap(self, stage: str, fn):
        @functools.wraps(fn)
        def timed(*a, **k):
            self.enter(stage)
            try:
                return fn(*a, **k)
            finally:
                self.leave()

        return timed

    def install(self) -> None:
        """Wrap every hooked function where it is defined and wherever it was imported (the
        forward runs counted first, inside their timer)."""
        from fabricsurf.inverse.forward.runs import ForwardModel

        ForwardModel.run = self.count_run(ForwardModel.run)
        for stage, hooks in HOOKS.items():
            for modname, name in hooks:
                try:
                    mod = importlib.import_module(modname)
                except ImportError:  # an older tree without it
                    continue
                owner, attr = mod, name
                if "." in name:
                    cls, attr = name.split(".")
                    owner = getattr(mod, cls, None)
                fn = getattr(owner, attr, None) if owner is not None else None
                if fn is None:
                    continue
                timed = self.wrap(stage, fn)
                setattr(owner, attr, timed)
                if owner is mod:
                    for m in list(sys.modules.values()):
                        if (
                            getattr(m, "__name__", "").startswith("fabricsurf")
                            and getattr(m, attr, None) is fn
                        ):
                            setattr(m, attr, timed)


def make_data(
    n_points: int, root: Path, comm: MPI.Comm, steps: int = STEPS, h: float | None = None
) -> Path:
    """The synthetic data of the module docstring with about ``n_points`` field rows over
    ``steps`` load steps, made on the mesh ``h`` (default: the test's own)."""
    per_step = n_points / steps
    ny = max(2, round(math.sqrt(per_step * WIDTH / LENGTH)))
    nx = max(2, round(per_step / ny))
    path = list(np.linspace(STRAIN * LENGTH / steps, STRAIN * LENGTH, steps))
    exp = sy.template(
        LENGTH, WIDTH, path, sy.grid_points(LENGTH, WIDTH, nx, ny), name=f"bias_{n_points}"
    )
    sy.continuum_data(
        exp, full_model(list(TRUTH), TRUTH), h=h or min(LENGTH, WIDTH) / 10.0, comm=comm
    )
    sy.add_noise(exp, NOISE_MM, NOISE_N, seed=36)
    d = root / f"data_{n_points}"
    if comm.rank == 0:
        write_experiment(d, exp, overwrite=True)
        (root / f"out_{n_points}").mkdir(parents=True, exist_ok=True)
        (root / f"out_{n_points}" / "truth.json").write_text(json.dumps(TRUTH))
    comm.barrier()
    return d


COMMANDS = {
    "fit": lambda d, o: [
        "fit",
        str(d),
        "--terms",
        "fibre_stretch,shear,geodesic_bending",
        "--out",
        str(o / "fit"),
    ],
    "compare": lambda d, o: [
        "compare",
        str(d),
        "--params",
        str(o / "fit" / "fit.json" if (o / "fit" / "fit.json").is_file() else o / "truth.json"),
        "--out",
        str(o / "compare"),
    ],
    "diagnose": lambda d, o: [
        "diagnose",
        str(d),
        "--terms",
        "fibre_stretch,shear",
        "--max-effects",
        "1",
        "--confirm",
        "1",
        "--out",
        str(o / "diagnose"),
    ],
}


def run(
    st: Stages,
    command: str,
    data: Path,
    out: Path,
    comm: MPI.Comm,
    h: float | None = None,
    extra: list[str] | None = None,
    profile: bool = False,
) -> dict:
    """One command under the stage timers: {"status", "seconds", "stages": {stage: [s, MB per
    rank]}, "counts"}; its output in ``out``/COMMAND.log and, with ``profile``, rank 0's
    cProfile in ``out``/COMMAND.prof (and the top functions in COMMAND.prof.txt)."""
    st.reset()
    comm.barrier()
    peak_mb(reset=True)
    t0 = time.perf_counter()
    st.enter("other")
    sink = io.StringIO()
    prof = cProfile.Profile() if profile and comm.rank == 0 else None
    args = COMMANDS[command](data, out) + ([] if h is None else ["--h", str(h)]) + (extra or [])
    try:
        with contextlib.redirect_stdout(sink):
            if prof is not None:
                prof.enable()
            try:
                status = main(args)
            finally:
                if prof is not None:
                    prof.disable()
    except MemoryError as e:
        status = f"MemoryError: {e}"
    st.leave()
    if comm.rank == 0:
        (out / f"{command}.log").write_text(sink.getvalue())
        if prof is not None:
            prof.dump_stats(out / f"{command}.prof")
            text = io.StringIO()
            pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(40)
            (out / f"{command}.prof.txt").write_text(text.getvalue())
    wall = time.perf_counter() - t0
    peaks = comm.gather([st.peak[s] for s in STAGES])
    times = np.max(comm.allgather([st.t[s] for s in STAGES]), axis=0)
    cpus = np.max(comm.allgather([st.cpu[s] for s in STAGES]), axis=0)
    note = [ln for ln in sink.getvalue().splitlines() if "failed" in ln or "error" in ln]
    return {
        "status": status,
        "note": note[:2],
        "seconds": comm.allreduce(wall, op=MPI.MAX),
        "cpu": float(np.sum(cpus)),
        "stages": {
            s: [float(times[i]), [p[i] for p in peaks] if peaks else None, float(cpus[i])]
            for i, s in enumerate(STAGES)
        },
        "counts": dict(sorted(st.counts.items())),
    }


def table(results: dict, comm: MPI.Comm) -> None:
    """Per command: stage × size seconds and peak MB per rank, and the growth exponents."""
    sizes = sorted(results, key=int)
    for command in COMMANDS:
        rows = [(n, results[n].get(command)) for n in sizes if command in results[n]]
        if not rows:
            continue
        rank0(
            logger,
            comm,
            f"\n{command}: "
            + "  ".join(
                f"N={n}: {r['seconds']:.1f} s (CPU {r.get('cpu', 0):.1f} s, the busier rank), "
                f"status {r['status']}"
                for n, r in rows
            ),
        )
        head = f"{'stage':22s}" + "".join(f"{'N=' + n:>38s}" for n, _ in rows) + "  exponents"
        rank0(logger, comm, head)
        for s in STAGES:
            cells, ts = "", []
            for _, r in rows:
                t, mb, cpu = (r["stages"][s] + [0.0])[:3]
                cells += (
                    f"{t:9.2f} s (CPU {cpu:7.2f}) "
                    f"{'/'.join(f'{m:.0f}' for m in (mb or [])):>11s} MB"
                )
                ts.append(t)
            ns = [int(n) for n, _ in rows]
            exps = [
                math.log(max(ts[i + 1], 1e-3) / max(ts[i], 1e-3)) / math.log(ns[i + 1] / ns[i])
                for i in range(len(ns) - 1)
            ]
            rank0(logger, comm, f"{s:22s}{cells}  " + " ".join(f"{e:5.2f}" for e in exps))
        for n, r in rows:
            rank0(
                logger,
                comm,
                f"N={n} counts: " + ", ".join(f"{k} {v}" for k, v in r.get("counts", {}).items()),
            )


def main_benchmark() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", default="1e4,1e5", help="comma-separated field row counts")
    ap.add_argument("--commands", default="fit,compare,diagnose")
    ap.add_argument("--out", required=True)
    ap.add_argument(
        "--h",
        type=float,
        default=None,
        help="element size in mm (default: the test's own, 11.9 mm here); the "
        "forward solves do not depend on N, a coarser mesh shows the N-dependent "
        "stages sooner",
    )
    ap.add_argument("--steps", type=int, default=STEPS, help="load steps")
    ap.add_argument(
        "--limit-gb",
        type=float,
        default=None,
        help="address-space limit per process (RLIMIT_AS), GB",
    )
    ap.add_argument(
        "--diagnose-args",
        default="",
        help="further options of diagnose, e.g. '--max-dofs 1' (no mesh selection)",
    )
    ap.add_argument(
        "--cold",
        action="store_true",
        help="no warm start of the forward runs (every load step from the last "
        "converged one, as before; inverse/forward/warm_start.py)",
    )
    ap.add_argument(
        "--distributed",
        action="store_true",
        help="solve every mesh distributed over the ranks (as before the rank-local "
        "solves of inverse/forward/ranks.py)",
    )
    ap.add_argument(
        "--profile",
        action="store_true",
        help="cProfile on rank 0: OUT/out_N/COMMAND.prof and COMMAND.prof.txt",
    )
    args = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    root = Path(args.out)
    if args.cold:
        importlib.import_module("fabricsurf.inverse.forward.warm_start").ENABLED = False
    if args.distributed:
        importlib.import_module("fabricsurf.inverse.forward.ranks").LOCAL_CELLS = 0
    results: dict = {}
    st = Stages()
    st.install()
    limit = resource.getrlimit(resource.RLIMIT_AS)
    for n in [int(float(x)) for x in args.points.split(",")]:
        data = make_data(n, root, comm, args.steps, args.h)
        results[str(n)] = {}
        if args.limit_gb:
            resource.setrlimit(resource.RLIMIT_AS, (int(args.limit_gb * 2**30), limit[1]))
        for command in args.commands.split(","):
            extra = args.diagnose_args.split() if command == "diagnose" else []
            results[str(n)][command] = res = run(
                st, command, data, root / f"out_{n}", comm, args.h, extra, args.profile
            )
            rank0(
                logger,
                comm,
                f"[scale] N = {n} {command}: {res['seconds']:.1f} s, status "
                f"{res['status']} {res['note']}",
            )
        if args.limit_gb:
            resource.setrlimit(resource.RLIMIT_AS, limit)
        if comm.rank == 0:
            (root / "scale.json").write_text(json.dumps(results, indent=1))
        table(results, comm)


if __name__ == "__main__":
    main_benchmark()
