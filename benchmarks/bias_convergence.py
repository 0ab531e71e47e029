"""Mesh convergence of the bias-extension grip force, down to the clamp boundary layer.

    mpirun -n 2 python benchmarks/bias_convergence.py [--levels 2,4,8,16] [--grading 0.6]
                                                      [--ubar 18.7] [--steps 4]

Continuum (a) of demos/demo_bias_extension.py (fibre_stretch k_l = 30, shear k_s = 0.5,
geodesic_bending A_g = 40; gradient clamps) on nested meshes of 11·n × 7·n crossed squares,
graded towards the edges (``--grading 0`` for uniform meshes). Prints, per level, the force,
the shear angles at A and B, the time, and the observed rates log2(d_n / d_2n) of the force
differences with the Richardson estimate of the limit. The finest level is the costly one (its
size and time are in docs/verification.md).
"""

import argparse
import logging
import time

from mpi4py import MPI

from fabricsurf.experiments.bias_extension import default_model
from fabricsurf.log import configure, rank0
from fabricsurf.verification.bias_convergence import force_convergence

logger = logging.getLogger(__name__)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--levels", default="2,4,8,16")
    ap.add_argument("--grading", type=float, default=0.6)
    ap.add_argument("--ubar", type=float, default=18.7, help="grip displacement (mm)")
    ap.add_argument("--steps", type=int, default=4)
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    levels = [int(s) for s in a.levels.split(",")]
    conv = force_convergence(default_model(), levels, a.ubar, a.steps, grading=a.grading, comm=comm)
    rank0(logger, comm, f"\nū = {a.ubar} mm, grading {a.grading}, {comm.size} rank(s)")
    rank0(
        logger,
        comm,
        "level  square side (mm)  at the edges (mm)  force (N)     γ_A (deg)  γ_B (deg)",
    )
    for lev, h, f, (ga, gb) in zip(
        conv["levels"], conv["h_nominal_mm"], conv["force"], conv["angles_AB_deg"]
    ):
        rank0(
            logger,
            comm,
            f"{lev:5d}  {h:16.3f}  {(1 - a.grading) * h:17.3f}  {f:12.6f}  {ga:9.4f}  {gb:9.4f}",
        )
    rank0(logger, comm, "differences (N): " + ", ".join(f"{d:.4f}" for d in conv["differences"]))
    rank0(
        logger,
        comm,
        "rates: "
        + ", ".join("none (oscillating)" if r is None else f"{r:.2f}" for r in conv["rates"]),
    )
    if conv["extrapolated_force"] is not None:
        rank0(
            logger,
            comm,
            f"Richardson limit {conv['extrapolated_force']:.4f} N; finest error "
            f"estimate {conv['finest_error_estimate']:.4f} N "
            f"({conv['finest_error_estimate'] / abs(conv['force'][-1]):.2e} rel.)",
        )
    rank0(logger, comm, f"total {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
