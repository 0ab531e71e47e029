"""Benchmark of the continuum solver on a medium-mesh bias-extension run (docs/verification.md).

    mpirun -n 2 python benchmarks/solve.py [--h 4] [--ubar 30] [--steps 6]

Prints DOFs, quadrature points per cell/facet of each integral, Newton iterations per step,
time per Newton iteration and its ratio to the floor (one residual + Jacobian assembly, one LU
factorisation and solve of the same Jacobian; goal <= 1.5), and the speed-up from 1 rank
(rank 0 alone, COMM_SELF) to all ranks (COMM_WORLD).
"""

import argparse
import time

import basix
from mpi4py import MPI
from petsc4py import PETSc

from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE, FACET_QUADRATURE_DEGREE
from fabricsurf.experiments.bias_extension import BiasExtension


def quadrature_points() -> dict:
    tri = basix.make_quadrature(basix.CellType.triangle, CELL_QUADRATURE_DEGREE)[0]
    edge = basix.make_quadrature(basix.CellType.interval, FACET_QUADRATURE_DEGREE)[0]
    return {
        "cell (energy, dx)": len(tri),
        "interior facet (C0-IP, dS)": len(edge),
        "boundary facet (Nitsche, ds)": len(edge),
    }


def floor_seconds(test: BiasExtension, repeats: int = 3) -> float:
    """One residual + Jacobian assembly, LU factorisation and solve of the same Jacobian."""
    s = test.solver
    x, b = s.u.vector.copy(), s.b.duplicate()
    newton_ksp = s.snes.getKSP()
    ksp = PETSc.KSP().create(s.A.getComm())
    ksp.setType(newton_ksp.getType())
    ksp.getPC().setType(newton_ksp.getPC().getType())
    ksp.getPC().setFactorSolverType(newton_ksp.getPC().getFactorSolverType())
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        s.evaluate_residual(x, b)
        A = s.evaluate_jacobian(x)
        ksp.setOperators(A)
        ksp.setUp()
        dx = b.duplicate()
        ksp.solve(b, dx)
        times.append(time.perf_counter() - t0)
        ksp.reset()
    return min(times)


def run(comm: MPI.Comm, h: float, ubar: float, steps: int) -> dict:
    test = BiasExtension(h=h, comm=comm)
    test.run(ubar, steps)
    t0 = time.perf_counter()
    test.set_load(ubar * (1 + 0.5 / steps))
    reason, its = test.solver.solve()
    t_step = time.perf_counter() - t0
    floor = floor_seconds(test)
    V = test.problem.V
    return {
        "dofs": V.dofmap.index_map.size_global * V.dofmap.index_map_bs,
        "newton_per_step": test.solver.snes.getIterationNumber(),
        "iterations": its,
        "time_per_iteration": t_step / max(its, 1),
        "floor": floor,
        "reason": reason,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h", type=float, default=4.0, help="mesh size (mm)")
    ap.add_argument("--ubar", type=float, default=30.0, help="grip displacement (mm)")
    ap.add_argument("--steps", type=int, default=6)
    args = ap.parse_args()
    world = MPI.COMM_WORLD
    t0 = time.perf_counter()
    par = run(world, args.h, args.ubar, args.steps)
    t_par = time.perf_counter() - t0
    ser, t_ser = None, None
    if world.size > 1:
        if world.rank == 0:
            t0 = time.perf_counter()
            ser = run(MPI.COMM_SELF, args.h, args.ubar, args.steps)
            t_ser = time.perf_counter() - t0
        world.barrier()
    if world.rank != 0:
        return
    print(f"DOFs: {par['dofs']}")
    for k, v in quadrature_points().items():
        print(f"quadrature points per {k}: {v}")
    print(f"Newton iterations in the timed step: {par['iterations']} (SNES reason {par['reason']})")
    print(f"time per Newton iteration on {world.size} rank(s): {par['time_per_iteration']:.3f} s")
    print(f"floor (assembly + LU factorisation + solve): {par['floor']:.3f} s")
    print(
        f"ratio time per iteration / floor: {par['time_per_iteration'] / par['floor']:.2f}"
        " (goal <= 1.5)"
    )
    if ser is not None:
        print(
            f"whole run: 1 rank {t_ser:.2f} s, {world.size} ranks {t_par:.2f} s, "
            f"speed-up {t_ser / t_par:.2f}"
        )
        print(
            f"per Newton iteration: speed-up "
            f"{ser['time_per_iteration'] / par['time_per_iteration']:.2f}"
        )


if __name__ == "__main__":
    main()
