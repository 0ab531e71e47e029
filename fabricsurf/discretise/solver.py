"""Newton solver (PETSc SNES) for Π_h and load stepping with automatic step cutting (DESIGN §4).

The SNES callbacks follow the NonlinearPDE_SNESProblem of the dolfinx 0.5 unit tests: the
residual is dΠ/du with Dirichlet rows x − g (lifting), the Jacobian d²Π/du². Options go to the
database under a per-solver prefix only (never unprefixed/global ones).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

SNES_DEFAULTS: dict[str, object] = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-10,
    "snes_stol": 1e-14,
    "snes_max_it": 25,
    "snes_divergence_tolerance": 1e8,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}
_ids = itertools.count()


class SNESSolver:
    """Newton for R(u) = 0 with Jacobian ``jacobian`` (both UFL forms, usually from EnergyForm).

    ``nodal_forces`` is an optional callable returning (dofs, values) of dead point forces
    (corner forces) added to the external load: R ← R − f at those local dofs.
    """

    def __init__(self, residual: ufl.Form, jacobian: ufl.Form, u: fem.Function,
                 bcs: Sequence[fem.DirichletBCMetaClass] = (),
                 prefix: str | None = None, options: dict | None = None,
                 nodal_forces: Callable | None = None) -> None:
        V = u.function_space
        self.u, self.bcs, self.nodal_forces = u, list(bcs), nodal_forces
        self.comm = V.mesh.comm
        self.L = fem.form(residual)
        self.a = fem.form(jacobian)
        self.prefix = prefix or f"fabricsurf_{next(_ids)}_"
        self.b = fem_petsc.create_vector(self.L)
        self.A = fem_petsc.create_matrix(self.a)
        self.x = u.vector.copy()
        self.snes = PETSc.SNES().create(V.mesh.comm)
        self.snes.setFunction(self._F, self.b)
        self.snes.setJacobian(self._J, self.A)
        self.set_options(options or {})

    def set_options(self, options: dict) -> None:
        opts = PETSc.Options()
        for k, v in {**SNES_DEFAULTS, **options}.items():
            opts[self.prefix + k] = v
        self.snes.setOptionsPrefix(self.prefix)
        self.snes.setFromOptions()
        self.snes.getKSP().setFromOptions()

    def _update_u(self, x: PETSc.Vec) -> None:
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(self.u.vector)
        self.u.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def _F(self, snes, x, b) -> None:
        self._update_u(x)
        with b.localForm() as b_local:
            b_local.set(0.0)
        fem_petsc.assemble_vector(b, self.L)
        if self.nodal_forces is not None:
            dofs, vals = self.nodal_forces()
            with b.localForm() as b_local:
                b_local.array[dofs] -= vals
        fem_petsc.apply_lifting(b, [self.a], bcs=[self.bcs], x0=[x], scale=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(b, self.bcs, x, -1.0)

    def _J(self, snes, x, A, P) -> None:
        self._update_u(x)
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, self.a, bcs=self.bcs)
        A.assemble()

    def solve(self) -> tuple[int, int]:
        """Newton from the current u; returns (converged reason, iterations). u holds the result."""
        self.u.vector.copy(self.x)
        self.snes.solve(None, self.x)
        self._update_u(self.x)
        return self.snes.getConvergedReason(), self.snes.getIterationNumber()

    def internal_force(self) -> PETSc.Vec:
        """R(u) assembled without boundary conditions or nodal forces (owned entries complete)."""
        b = fem_petsc.assemble_vector(self.L)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b


class LoadStepError(RuntimeError):
    """The load path could not be followed even with the minimum step."""


class LoadStepper:
    """Follow a load parameter t through requested values, cutting the step on divergence.

    ``set_load(t)`` updates the problem data (Constants, BC values) for load t;
    ``on_converged(k, t, iters)`` is called for each requested value t_k once converged
    (write output there: everything converged is on disk when a later step fails).
    """

    def __init__(self, solver: SNESSolver, set_load: Callable[[float], None],
                 on_converged: Callable[[int, float, int], None] | None = None,
                 min_fraction: float = 1e-4, log: Callable | None = None):
        self.solver, self.set_load, self.on_converged = solver, set_load, on_converged
        self.min_fraction = min_fraction
        self.log = log or (lambda msg: None)
        self.t = 0.0
        self.iterations: list[int] = []

    def _try(self, t: float) -> tuple[bool, int, int]:
        backup = self.solver.u.vector.copy()
        self.set_load(t)
        reason, its = self.solver.solve()
        finite = bool(np.isfinite(self.solver.u.x.array).all())
        comm = getattr(self.solver, "comm", MPI.COMM_SELF)
        ok = reason > 0 and comm.allreduce(finite, op=MPI.LAND)
        if not ok:
            backup.copy(self.solver.u.vector)
            self.solver.u.x.scatter_forward()
        return ok, reason, its

    def advance_to(self, target: float, k: int) -> int:
        """Reach load ``target`` from the current load; returns total Newton iterations."""
        span = target - self.t
        dt, total = span, 0
        while abs(target - self.t) > 1e-14 * max(1.0, abs(target)):
            t_next = self.t + dt if abs(dt) < abs(target - self.t) else target
            ok, reason, its = self._try(t_next)
            total += its
            if ok:
                self.t = t_next
                dt = float(np.sign(span)) * min(abs(span), 1.5 * abs(dt))
                continue
            dt = 0.5 * (t_next - self.t)
            self.log(f"step {k}: SNES reason {reason} at t = {t_next:.6g}; "
                     f"cutting step to {dt:.3g}")
            if abs(dt) < self.min_fraction * abs(span):
                self.set_load(self.t)
                raise LoadStepError(
                    f"load step {k} (target {target:.6g}) failed: step cut below "
                    f"{self.min_fraction:g} of the increment at load {t_next:.6g}; last converged "
                    f"load {self.t:.6g}; SNES converged reason {reason}")
        return total

    def run(self, targets: Sequence[float]) -> list[int]:
        for k, target in enumerate(targets):
            its = self.advance_to(float(target), k)
            self.iterations.append(its)
            if self.on_converged is not None:
                self.on_converged(k, float(target), its)
        return self.iterations

