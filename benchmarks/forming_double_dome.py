"""The double dome of demos/demo_double_dome.py (our dimensions: fabricsurf/studies/double_dome.py)
on a sequence of meshes: the time against the cells, and how the sheet's departure from the
kinematic drape over the dome falls with h (docs/tool_surfaces.md, "A double dome").

Per blank (0/90 and ±45°) and mesh h = h0/√2^k: cells of the quarter, unknowns, Newton
iterations, wall time of the forming run, punch force at the full stroke, largest shear, and
the drape check (tool_drape.compare, cell side ``--a`` fixed over the meshes so that only the
sheet's error changes): the nodes compared, max and RMS of the difference. Then per blank the
exponent of the time's growth with the cells and the ratios of the RMS differences.

Run: ``mpirun -n 2 python benchmarks/forming_double_dome.py [--R 20] [--h0 3.5] [--levels 3]
[--steps 8] [--a 1]``.
"""

import argparse
import logging
import math
import time
from itertools import pairwise

from mpi4py import MPI

from fabricsurf.log import configure, rank0
from fabricsurf.studies import double_dome as dd
from fabricsurf.studies import hemisphere_forming as parts
from fabricsurf.verification.drapes import tool_drape

logger = logging.getLogger(__name__)
comm = MPI.COMM_WORLD
BLANKS = {"0/90": (0.0, 90.0), "±45": (45.0, -45.0)}
K_BEND = 1.0


def run(R: float, surface, angles, h: float, args: argparse.Namespace) -> dict:
    params = parts.documented_fit()["params"]
    model = parts.forming_model(params, K_BEND, K_BEND)
    with dd.experiment(R, surface, angles, h, model, comm) as e:
        t0 = time.perf_counter()
        res = dd.form(e, parts.fitted_values(params, K_BEND), 0.75 * R, args.steps, f"h={h:.3g}: ")
        seconds = time.perf_counter() - t0
        check = dd.drape_check(tool_drape.Continuum(e), surface, R, args.a)
        return {
            "h": h,
            "cells": comm.allreduce(e.specimen.mesh.topology.index_map(2).size_local),
            "dofs": e.problem.V.dofmap.index_map.size_global * 3,
            "newton": res["step_log"]["newton_iterations"],
            "seconds": seconds,
            "force": res["punch_force_N"][-1],
            "shear": res["max_shear_deg"],
            "nodes": check["nodes"],
            **check["continuum_vs_drape"],
        }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--R", type=float, default=20.0, help="the domes' radius (mm)")
    ap.add_argument("--h0", type=float, default=3.5, help="the coarsest mesh (mm)")
    ap.add_argument("--levels", type=int, default=3, help="meshes h0/√2^k, k < levels")
    ap.add_argument("--steps", type=int, default=8, help="stroke steps to 0.75 R")
    ap.add_argument("--a", type=float, default=1.0, help="the drape's cell side (mm)")
    args = ap.parse_args()
    configure()
    surface = dd.punch(args.R, comm)
    hs = [args.h0 / math.sqrt(2.0) ** k for k in range(args.levels)]
    rows = {name: [run(args.R, surface, ang, h, args) for h in hs] for name, ang in BLANKS.items()}
    rank0(
        logger,
        comm,
        "blank      h   cells   dofs  Newton  wall (s)  force (N)  max shear  nodes  "
        "drape max  drape RMS (deg)",
    )
    for name, rs in rows.items():
        for r in rs:
            rank0(
                logger,
                comm,
                f"{name:>5} {r['h']:6.3f} {r['cells']:7d} {r['dofs']:6d} {r['newton']:7d} "
                f"{r['seconds']:9.1f} {r['force']:10.3f} {r['shear']:10.2f} {r['nodes']:6d} "
                f"{r['max_deg']:10.3f} {r['rms_deg']:10.3f}",
            )
        for a, b in pairwise(rs):
            growth = math.log(b["seconds"] / a["seconds"]) / math.log(b["cells"] / a["cells"])
            rank0(
                logger,
                comm,
                f"{name}: h {a['h']:.3g} -> {b['h']:.3g}: time ~ cells^{growth:.2f}, drape RMS "
                f"ratio {a['rms_deg'] / b['rms_deg']:.2f}, max ratio "
                f"{a['max_deg'] / b['max_deg']:.2f}",
            )


if __name__ == "__main__":
    main()
