"""C0-IP convergence of the manufactured solutions in 2D and 3D (docs/verification.md).

The 3D case holds all seven terms; its forms take minutes to compile on a cold cache, so it runs
here rather than in the test suite (which checks the 2D case). Prints the errors and observed
rates in L2, H1 and broken H2 (theory for P2 C0-IP: 2, 2, 1).

    mpirun -n 2 .venv/bin/python benchmarks/convergence.py [--d 3]
"""

from __future__ import annotations

import argparse
import logging

from mpi4py import MPI

from fabricsurf.log import configure, rank0
from fabricsurf.verification.rates import rates
from research.verification.manufactured import (
    full_3d_model,
    in_plane_model,
    manufactured_solve,
    u_2d,
    u_3d,
)

logger = logging.getLogger(__name__)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--d", type=int, nargs="+", default=[2, 3])
    ap.add_argument("--meshes", type=int, nargs="+", default=[4, 8, 16])
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    cases = {2: (in_plane_model, u_2d), 3: (full_3d_model, u_3d)}
    for d in a.d:
        model_fn, ue = cases[d]
        errors = [manufactured_solve(model_fn(), ue, n, d)[0] for n in a.meshes]
        hs = [1.0 / n for n in a.meshes]
        for norm in ("L2", "H1", "H2"):
            e = [x[norm] for x in errors]
            rank0(
                logger,
                MPI.COMM_WORLD,
                f"d = {d} {norm}: errors {[f'{v:.3e}' for v in e]}, "
                f"rates {[round(r, 2) for r in rates(e, hs)]}",
            )


if __name__ == "__main__":
    main()
