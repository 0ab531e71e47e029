"""Forming benchmark: a 250 mm blank over a hemispherical punch of radius 50 mm on three meshes
(docs/forming.md).

Prints, per mesh, the DOFs, the Newton iterations and the contact active-set changes (the
quadrature points that enter or leave contact with the punch) per stroke step, and the time;
then the mesh convergence of the punch force at the final stroke and of the shear angle at a
point of the diagonal, with the observed rate from the three meshes (ratio √2). The model is
the fitted woven fabric of docs/woven_fabric.md with the assumed bending of demo_forming.py.

Run: ``mpirun -n 2 python benchmarks/forming.py`` (``--quick``: the tests' 60 mm blank over
R = 20 mm).
"""

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import rank0_print
from research.forming import parts

comm = MPI.COMM_WORLD
ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true")
args = ap.parse_args()
R, BLANK = (20.0, 60.0) if args.quick else (50.0, 250.0)
STROKE, STEPS = 0.6 * R, 12
MESHES = [R / 5.0 * math.sqrt(2.0), R / 5.0, R / 5.0 / math.sqrt(2.0)]
POINT = 0.5 * R
"""Reference distance from the pole, on the diagonal, of the shear angle studied."""

rows = []
for h in MESHES:
    e = parts.experiment(R, BLANK, h, 45.0, parts.forming_model(parts.DOCUMENTED_PARAMS["params"],
                                                                0.1, 0.1), comm)
    dofs = 3 * e.problem.V.dofmap.index_map.size_global
    changes, last = [], [e.active_set()]

    def count(k, s, e=e, last=last, changes=changes):
        now = e.active_set()
        changes.append(comm.allreduce(int(np.count_nonzero(now != last[0])), op=MPI.SUM))
        last[0] = now
        rank0_print(comm, f"    s = {s:.4g} mm: F = {e.force[-1]:.4g} N, "
                          f"{changes[-1]} active-set changes")

    t0 = time.perf_counter()
    its = e.run(STROKE, STEPS, on_step=count)
    seconds = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    shear = float(e.profile(0.0, np.array([POINT]))["shear_deg"][0])
    rows.append({"h": h, "dofs": dofs, "force": e.force[-1], "shear": shear, "seconds": seconds})
    rank0_print(comm, f"h = {h:.3f} mm: {dofs} DOFs, {seconds:.1f} s, force {e.force[-1]:.5g} N, "
                      f"shear at X = {POINT:g} mm {shear:.4g} deg")
    rank0_print(comm, f"  Newton iterations per step {its}; attempts {e.stepper.attempts}")
    rank0_print(comm, f"  active-set changes per step {changes}")
    e.close()

rank0_print(comm, "\nmesh   DOFs    seconds  s/DOF")
for r in rows:
    rank0_print(comm, f"{r['h']:6.3f} {r['dofs']:6d} {r['seconds']:8.1f}  "
                      f"{r['seconds'] / r['dofs']:.2e}")
first, last = rows[0], rows[-1]
grow = math.log(last["seconds"] / first["seconds"]) / math.log(last["dofs"] / first["dofs"])
rank0_print(comm, f"time grows as DOFs^{grow:.2f}")
for key in ("force", "shear"):
    q = [r[key] for r in rows]
    d1, d2 = abs(q[0] - q[1]), abs(q[1] - q[2])
    rate = math.log(d1 / d2) / math.log(math.sqrt(2.0)) if d1 > 0 and d2 > 0 else float("nan")
    rank0_print(comm, f"{key}: {q[0]:.6g}, {q[1]:.6g}, {q[2]:.6g}; differences {d1:.3g}, "
                      f"{d2:.3g}; observed rate {rate:.2f}")
