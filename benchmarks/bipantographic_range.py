"""The bi-pantographic bias test (Barchiesi et al. 2020, eq. 2, Table 3 macro moduli) to ū = 50 mm
on nested graded meshes, with gradient and position-only clamps.

    mpirun -n 2 python benchmarks/bipantographic_range.py [--levels 2,4,8] [--steps 20]
                      [--ubar 50] [--clamps gradient,position] [--limit-stretch R]
                      [--identified] [--local-penalty] [--package-defaults] [--out FILE.json]

Prints, per clamp variant and level: DOFs, the force and the shear angles at A and B at
ū = 10, 20, 30, 40, 50 mm, the largest fibre stretch ρ (and ρ cos γ, the distance to the
energy's limit 1) and where, Newton iterations, wall time per load step and per Newton
iteration; then the observed rate of the force under refinement at each ū. The interior
penalty follows the stretch as in every ``BiasExtension.run`` (no callback);
``--package-defaults`` also leaves the solver options at the package's defaults, so each run is
the plain public API call. Exits with status 1 if any run stops short of ū.
"""

import argparse
import json
import logging
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.log import configure, rank0
from fabricsurf.network.homogenize import identify_macro
from fabricsurf.verification.bias_comparison import EPS_EXACT, IDENTIFIED_K_E
from fabricsurf.verification.bipantographic_range import (
    RANGE_OPTIONS,
    convergence,
    run_range,
    values_at,
)

logger = logging.getLogger(__name__)


def report(comm, run: dict, loads: list[float]) -> None:
    rank0(
        logger,
        comm,
        f"\n{run['clamp']} clamps, level {run['level']} ({run['dofs']} DOFs), "
        f"set-up {run['setup_seconds']:.1f} s",
    )
    if run["failure"]:
        rank0(logger, comm, "  FAILED: " + run["failure"]["message"])
        if "ubar" not in run:
            return
    for row in values_at(run, [u for u in loads if u <= run["ubar"][-1] + 1e-9]):
        rank0(
            logger,
            comm,
            f"  ū = {row['ubar']:4.0f} mm  F = {row['force']:9.4f} N  "
            f"γ_A = {row['angle_A_deg']:6.2f}°  γ_B = {row['angle_B_deg']:6.2f}°",
        )
    s = run["stretch"][-1]
    rank0(
        logger,
        comm,
        f"  largest stretch at ū = {s['ubar']:.0f} mm: ρ = {s['max_stretch']:.4f}"
        f" (ρ cos γ = {s['rho_cos_gamma']:.4f}) at {np.round(s['at'], 1)}",
    )
    its, st = np.array(run["newton"]), np.array(run["step_seconds"])
    rank0(
        logger,
        comm,
        f"  {len(its)} load steps, {its.sum()} Newton iterations "
        f"({its.min()}–{its.max()} per step), domain errors "
        f"{run['domain_errors']}; wall time {run['seconds']:.1f} s: "
        f"{st.mean():.2f} s per load step, "
        f"{st.sum() / its.sum():.3f} s per Newton iteration",
    )


def identified_moduli(comm) -> dict:
    """K_S, K_E, K_F of eq. (2) from the homogenised Table 3 micro lattice (as the bias demo)."""
    ident = comm.bcast(identify_macro(eps=EPS_EXACT) if comm.rank == 0 else None, root=0)
    return {"K_S": ident["K_S"], "K_E": IDENTIFIED_K_E, "K_F": ident["a_theta"]}


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--levels", default="2,4,8")
    ap.add_argument("--clamps", default="gradient,position")
    ap.add_argument("--ubar", type=float, default=50.0)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument(
        "--limit-stretch",
        type=float,
        default=None,
        help="regularise eq. (2) beyond this stretch (default: as printed)",
    )
    ap.add_argument(
        "--identified",
        action="store_true",
        help="the moduli identified from the Table 3 micro lattice (K_E = 1e6 N·mm) "
        "instead of Table 3's macro moduli",
    )
    ap.add_argument(
        "--local-penalty",
        action="store_true",
        help="interior-penalty stretch followed cell by cell (default: uniform, "
        "the largest stretch)",
    )
    ap.add_argument(
        "--package-defaults",
        action="store_true",
        help="the package's default solver options instead of the domain-aware "
        "line search (the plain public API)",
    )
    ap.add_argument("--out", type=Path, default=None, help="write all results as JSON")
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    moduli = identified_moduli(comm) if a.identified else None
    options = None if a.package_defaults else RANGE_OPTIONS
    loads = [u for u in (10.0, 20.0, 30.0, 40.0, 50.0) if u <= a.ubar]
    results = {}
    for clamp in a.clamps.split(","):
        runs = [
            run_range(
                clamp,
                int(lev),
                a.ubar,
                a.steps,
                a.limit_stretch,
                comm=comm,
                moduli=moduli,
                local_penalty=a.local_penalty,
                snes_options=options,
            )
            for lev in a.levels.split(",")
        ]
        for r in runs:
            report(comm, r, loads)
        ok = [r for r in runs if not r["failure"]]
        conv = convergence(ok, loads) if len(ok) == len(runs) and len(runs) > 1 else None
        if conv:
            for u, c in conv.items():
                rates = ", ".join("none" if x is None else f"{x:.2f}" for x in c["rates"])
                rank0(
                    logger,
                    comm,
                    f"  {clamp}: force at ū = {u} mm: differences "
                    + ", ".join(f"{d:.4f}" for d in c["differences"])
                    + f" N, rate(s) {rates}",
                )
        results[clamp] = {"runs": runs, "convergence": conv}
    if a.out and comm.rank == 0:
        a.out.write_text(json.dumps(results, indent=1))
    short = [
        f"{c} level {r['level']}" for c, v in results.items() for r in v["runs"] if r["failure"]
    ]
    if short:
        rank0(logger, comm, f"\nNOT REACHED ū = {a.ubar:g} mm: " + ", ".join(short))
        sys.exit(1)
    rank0(logger, comm, f"\nevery run reached ū = {a.ubar:g} mm")


if __name__ == "__main__":
    main()
