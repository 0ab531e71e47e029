"""Where a Newton iteration of the forming benchmark goes, form by form (docs/forming.md,
"Performance"): the 250 mm blank over R = 50 mm with friction on all tools
(benchmarks/forming.py --study performance --tool-friction), formed over a few steps, then,
at that state, for each integral of the residual, the Jacobian and the tools' friction forms:
its type, the explicit quadrature degree and UFL's estimate, the quadrature points, and the
time of assembling it alone; beside them the residual and Jacobian as the solver assembles
them, the mirror conditions' lifting and one MUMPS factorisation and solve.

Run: ``python benchmarks/forming_forms.py [--h 10] [--steps 2] [--repeat 5] [--flags='-O3 ...']``
(``--flags``: C compiler flags of the kernels in one string).
"""

import argparse
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import basix
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from forming import DOCUMENTED_PARAMS
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms import estimate_total_polynomial_degree, expand_derivatives

from fabricsurf.log import configure, rank0
from fabricsurf.studies import hemisphere_forming as parts

logger = logging.getLogger(__name__)

comm = MPI.COMM_WORLD
TOOL_FRICTION = {"punch_friction": 0.3, "die_friction": 0.3}
POINTS_CELL = {
    "cell": basix.CellType.triangle,
    "interior_facet": basix.CellType.interval,
    "exterior_facet": basix.CellType.interval,
}


def _timed(fn, repeat: int) -> float:
    """Seconds per call of ``fn`` (the slowest rank's CPU), the best of ``repeat``."""
    best = float("inf")
    for _ in range(repeat):
        c = time.process_time()
        fn()
        best = min(best, time.process_time() - c)
    return comm.allreduce(best, op=MPI.MAX)


def _pieces(form: ufl.Form) -> list[tuple[str, ufl.Form]]:
    """The form split into its integrals (one per type, subdomain and degree)."""
    return [(f"{i.integral_type()}[{i.subdomain_id()}]", ufl.Form([i])) for i in form.integrals()]


def _assembler(form, rank: int, mat_type: str | None = None):
    if rank == 1:
        b = fem_petsc.create_vector(form)

        def run():
            with b.localForm() as local:
                local.set(0.0)
            fem_petsc.assemble_vector(b, form)

        return run
    A = fem_petsc.create_matrix(form, mat_type)

    def run():
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, form)
        A.assemble()

    return run


def report(e, repeat: int, jit: dict, mat_type: str | None = None) -> None:
    p = e.problem
    v, du = ufl.TestFunction(p.V), ufl.TrialFunction(p.V)
    dP = ufl.derivative(p.extra_energy(), p.u, v)
    forms = {
        "residual": (p.energy.residual(v) + dP, 1),
        "Jacobian": (p.energy.jacobian(du, v) + ufl.derivative(dP, p.u, du), 2),
    }
    tf, tJ = p.tool_friction()
    forms.update({"tool friction residual": (tf, 1), "tool friction Jacobian": (tJ, 2)})
    rank0(
        logger,
        comm,
        "form                     integral            explicit  UFL est.  points  ms/assembly",
    )
    for name, (form, rank) in forms.items():
        for label, piece in _pieces(form):
            itg = piece.integrals()[0]
            deg = itg.metadata().get("quadrature_degree")
            est = estimate_total_polynomial_degree(expand_derivatives(itg.integrand()))
            pts = len(basix.make_quadrature(POINTS_CELL[itg.integral_type()], int(deg))[1])
            t = _timed(_assembler(fem.form(piece, jit_params=jit), rank, mat_type), repeat)
            rank0(
                logger,
                comm,
                f"{name:24s} {label:20s} {deg!s:>8s} {est:9d} {pts:7d} {1e3 * t:11.1f}",
            )
    s = e.solver
    x = s.b.duplicate()
    with x.localForm() as xl:
        xl.array[:] = p.u.x.array
    b, lift = s.b.duplicate(), s.b.duplicate()
    calls = {
        "residual _F (with the friction forms)": lambda: s._F(None, x, b),
        "Jacobian _J (with the friction forms)": lambda: s._J(None, x, s.A, s.A),
        "the mirror conditions' lifting alone": lambda: fem_petsc.apply_lifting(
            lift, [s.a], bcs=[s.bcs], x0=[x], scale=-1.0
        ),
    }
    rank0(logger, comm, f"\nas the solver assembles them ({s.A.getType()} Jacobian), ms per call:")
    for label, fn in calls.items():
        rank0(logger, comm, f"  {label}: {1e3 * _timed(fn, repeat):.1f}")
    info = s.A.getInfo()
    rank0(logger, comm, f"  Jacobian: {int(comm.allreduce(info['nz_used']))} non-zeros")
    for solver, pc_type in (
        ("mumps", "lu"),
        ("mumps", "cholesky"),
        ("superlu_dist", "lu"),
        ("petsc", "lu"),
    ):
        if solver == "petsc" and comm.size > 1:
            continue
        rank0(
            logger,
            comm,
            f"  {solver} {pc_type} factorisation + solve "
            f"{1e3 * _factor_solve(s, b, solver, pc_type, repeat):.1f}",
        )


def _factor_solve(s, b, solver: str, pc_type: str, repeat: int) -> float:
    """CPU seconds of one numeric factorisation and solve of the Jacobian (the symbolic one
    done before), the best of ``repeat``, each after a fresh assembly."""
    ksp = PETSc.KSP().create(comm)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType(pc_type)
    pc.setFactorSolverType(solver)
    if solver == "petsc":
        pc.setFactorOrdering("nd")
    y = b.duplicate()
    x = b.duplicate()
    with x.localForm() as xl:
        xl.array[:] = s.u.x.array
    best = float("inf")
    for _ in range(repeat + 1):
        s._J(None, x, s.A, s.A)
        ksp.setOperators(s.A)
        c = time.process_time()
        ksp.setUp()
        ksp.solve(b, y)
        best = min(best, time.process_time() - c)
    ksp.destroy()
    return comm.allreduce(best, op=MPI.MAX)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h", type=float, default=10.0)
    ap.add_argument("--steps", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument(
        "--flags",
        default=None,
        help="the kernels' compiler flags in one string, e.g. '-O3 -march=native'",
    )
    ap.add_argument("--mat-type", default=None, help="PETSc matrix type of the pieces (aij, baij)")
    args = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    jit = {} if args.flags is None else {"cffi_extra_compile_args": args.flags.split()}
    R = 50.0
    model = parts.forming_model(DOCUMENTED_PARAMS["params"], 0.1, 0.1)
    with parts.experiment(R, 250.0, args.h, 45.0, model, comm, **TOOL_FRICTION) as e:
        dofs = 3 * e.problem.V.dofmap.index_map.size_global
        cells = e.specimen.mesh.topology.index_map(2).size_global
        its = e.run(0.6 * R * args.steps / 12, args.steps)
        rank0(
            logger,
            comm,
            f"h = {args.h:g} mm: {cells} cells, {dofs} DOFs, {comm.size} ranks; "
            f"state after {args.steps} steps ({list(its)} iterations)",
        )
        report(e, args.repeat, jit, args.mat_type)


if __name__ == "__main__":
    main()
