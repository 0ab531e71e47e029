"""Forward runs of a fit solved distributed over the ranks against whole on every rank.

The bias test of benchmarks/scale.py (187 × 119 mm, the diagnosis's full model, 12 load steps,
sensitivities to every modulus) at several element sizes, each run ``--repeat`` times per
mode; prints per h the cells, unknowns, Newton iterations, the median wall and CPU seconds of
a run (largest over the ranks) and the ratio distributed / rank-local. Run on 2 ranks:

    mpirun -n 2 .venv/bin/python benchmarks/local_solves.py [--h 23.8,11.9,5.95,3]

The threshold :data:`fabricsurf.inverse.forward.ranks.LOCAL_CELLS` rests on this table
(docs/dic.md, "Rank-local solves").
"""

from __future__ import annotations

import argparse
import logging
import math
import statistics
import time

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.diagnosis.diagnose import full_model
from fabricsurf.inverse.forward import warm_start
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, rank0

logger = logging.getLogger(__name__)

LENGTH, WIDTH, STEPS, STRAIN = 187.0, 119.0, 12, 0.15
TRUTH = {
    "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
    "shear": {"k_s": 0.5},
    "geodesic_bending": {"A_g": 40.0},
}


def experiment(points_per_step: int = 400):
    ny = max(2, round(math.sqrt(points_per_step * WIDTH / LENGTH)))
    nx = max(2, round(points_per_step / ny))
    path = list(np.linspace(STRAIN * LENGTH / STEPS, STRAIN * LENGTH, STEPS))
    exp = sy.template(LENGTH, WIDTH, path, sy.grid_points(LENGTH, WIDTH, nx, ny), name="bias")
    exp.u = np.zeros((len(exp.field_step), 2))
    exp.force = np.zeros(len(exp.steps))
    return exp


def timed_runs(exp, h: float, local: bool, repeat: int, comm: MPI.Comm) -> dict:
    """Median wall and CPU seconds of a run with all sensitivities (largest over ranks)."""
    with ForwardModel(exp, full_model(list(TRUTH), TRUTH), h=h, comm=comm, local=local) as fm:
        fm.run(sens=True)  # forms compiled, locators built
        walls, cpus, newton = [], [], 0
        for _ in range(repeat):
            comm.Barrier()
            t0, c0 = time.perf_counter(), time.process_time()
            pred = fm.run(sens=True)
            walls.append(comm.allreduce(time.perf_counter() - t0, op=MPI.MAX))
            cpus.append(comm.allreduce(time.process_time() - c0, op=MPI.MAX))
            newton = pred.newton
        mesh = fm.mesh()
    return {
        "cells": mesh["cells"],
        "dofs": mesh["dofs"],
        "newton": newton,
        "wall": statistics.median(walls),
        "cpu": statistics.median(cpus),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--h", default="23.8,11.9,5.95,3", help="comma-separated element sizes")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument(
        "--warm",
        action="store_true",
        help="warm-start the repeated runs (default cold: every step's Newton solve "
        "from the previous step, as a fit's first runs)",
    )
    args = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    warm_start.ENABLED = args.warm
    comm = MPI.COMM_WORLD
    exp = experiment()
    rank0(logger, comm, f"{comm.size} ranks; median of {args.repeat} runs with sensitivities")
    rank0(
        logger,
        comm,
        "h (mm) | cells | DOFs | Newton | distributed wall / CPU s | "
        "rank-local wall / CPU s | wall ratio",
    )
    for h in (float(x) for x in args.h.split(",")):
        d = timed_runs(exp, h, False, args.repeat, comm)
        loc = timed_runs(exp, h, True, args.repeat, comm)
        rank0(
            logger,
            comm,
            f"{h:g} | {d['cells']} | {d['dofs']} | {d['newton']}/{loc['newton']} | "
            f"{d['wall']:.2f} / {d['cpu']:.2f} | {loc['wall']:.2f} / {loc['cpu']:.2f} | "
            f"{d['wall'] / loc['wall']:.2f}",
        )


if __name__ == "__main__":
    main()
