"""Newton solver (PETSc SNES) for Π_h (docs/theory.md); load stepping is in
:mod:`fabricsurf.discretise.stepping`.

The SNES callbacks follow the NonlinearPDE_SNESProblem of the dolfinx 0.5 unit tests: the
residual is dΠ/du with Dirichlet rows x − g (lifting), the Jacobian d²Π/du². Options go to the
database under a per-solver prefix only (never unprefixed/global ones), and are removed from it
again once SNES and KSP have read them (nothing is left behind in the global database).

Energies with a restricted domain (e.g. the bi-pantographic energy, defined for ρ cos γ < 1
only) give NaN or inf outside it. Every residual evaluation checks, collectively, that the
assembled cell and facet contributions are finite (before the Dirichlet rows overwrite
anything); if not, it reports a function domain error to SNES (``SNESSetFunctionDomainError``)
and returns an inf residual on every rank. A backtracking line search
(``snes_linesearch_type: bt``, see :data:`~.snes.DOMAIN_AWARE`) then halves the step until the
trial state is back in the domain; with the default full-step (``basic``) line search the solve
stops with DIVERGED_LINE_SEARCH and the load stepper cuts the load step. A converged state
therefore always has a finite residual: every quadrature point is inside the domain. The check
costs one pass over the local vector and one allreduce per residual evaluation.
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

from fabricsurf.discretise.compat import set_domain_error
from fabricsurf.discretise.constraints import Multiplier, uzawa
from fabricsurf.discretise.resources import Owner, destroy, dot_function, weak_method
from fabricsurf.discretise.snes import RELATIVE, STEP_RTOL, apply_options, jit_params

_ids = itertools.count()


class SNESSolver(Owner):
    """Newton for R(u) = 0 with Jacobian ``jacobian`` (both UFL forms, usually from EnergyForm).

    ``nodal_forces`` is an optional callable returning (dofs, values) of dead point forces
    (corner forces) added to the external load: R ← R − f at those local dofs. ``options`` are
    PETSc options without the prefix (over :data:`~.snes.SNES_DEFAULTS`), plus the keys of
    :data:`~.snes.SOLVER_KEYS`. ``domain_errors`` counts the residual evaluations that left the
    energy's domain (module docstring). It owns its SNES, matrix and vectors (:meth:`close`,
    discretise/resources.py).
    """

    matrix_type: str = "baij"
    """The Jacobian's PETSc type: node blocks, inserted block by block (docs/speed.md)."""

    def __init__(
        self,
        residual: ufl.Form,
        jacobian: ufl.Form,
        u: fem.Function,
        bcs: Sequence[fem.DirichletBCMetaClass] = (),
        prefix: str | None = None,
        options: dict | None = None,
        nodal_forces: Callable | None = None,
        multipliers: Sequence[Multiplier] = (),
    ) -> None:
        V = u.function_space
        options = dict(options or {})
        mode = options.pop("jacobian", "given")
        if mode not in ("given", "exact"):
            raise ValueError(f"jacobian = {mode!r}: must be 'given' or 'exact'")
        if mode == "exact":
            jacobian = ufl.derivative(residual, u, ufl.TrialFunction(V))
        self.u, self.bcs, self.nodal_forces = u, list(bcs), nodal_forces
        self.multipliers = list(multipliers)
        self.comm = V.mesh.comm
        self._jit = jit_params(options.pop("compile", "optimised"))
        self.step_rtol = float(options.pop("step_rtol", STEP_RTOL))
        self.L = fem.form(residual, jit_params=self._jit)
        self.a = fem.form(jacobian, jit_params=self._jit)
        self._cheap: tuple | None = None
        self._cheap_when: Callable[[], bool] | None = None
        self.A_cheap: PETSc.Mat | None = None
        self.cheap_evaluations = 0
        self.prefix = prefix or f"fabricsurf_{next(_ids)}_"
        self.b = fem_petsc.create_vector(self.L)
        self.A = fem_petsc.create_matrix(self.a, self.matrix_type)
        self.x = self.b.duplicate()
        self.force = self.b.duplicate()
        self.domain_errors = 0
        self.snes = PETSc.SNES().create(V.mesh.comm)
        self.snes.setFunction(weak_method(self._F), self.b)
        self.snes.setJacobian(weak_method(self._J), self.A)
        self._in_use = self.A
        self.initial_norm = np.inf
        self.polished = 0
        if self.multipliers:
            self.snes.setMonitor(weak_method(self._monitor))
        self.set_options(options)

    def _release(self) -> None:
        destroy(self.snes, self.A, self.A_cheap, self.b, self.x, self.force)

    def add_cheap_forms(
        self, residual: ufl.Form, jacobian: ufl.Form, when: Callable[[], bool]
    ) -> None:
        """A cheaper residual and Jacobian, equal to the full ones whenever ``when()`` holds
        (a model whose second-gradient moduli are all zero: their cell kernels and the
        interior-penalty facet terms then vanish exactly, docs/speed.md). Compiled at their
        first use; every residual and Jacobian evaluation uses them while ``when()`` holds.
        The cheap Jacobian has a matrix of its own, :attr:`A_cheap`, of its sparsity: without
        the facet couplings it factorises in half the time (the full matrix, first assembled
        from the cheap forms, had no room for them: PETSc fixes an AIJ matrix's structure at
        its first assembly, tests/test_cheap_forms.py)."""
        self._cheap, self._cheap_when = (residual, jacobian), when

    def _cheap_now(self) -> bool:
        return self._cheap_when is not None and self._cheap_when()

    def forms(self) -> tuple[fem.FormMetaClass, fem.FormMetaClass]:
        """(residual, Jacobian) as evaluated now: the cheap pair while it equals the full one
        (:meth:`add_cheap_forms`), else the full pair."""
        if not self._cheap_now():
            return self.L, self.a
        self.cheap_evaluations += 1
        return self._compiled_cheap()

    def _compiled_cheap(self) -> tuple[fem.FormMetaClass, fem.FormMetaClass]:
        if isinstance(self._cheap[0], ufl.Form):
            self._cheap = tuple(fem.form(f, jit_params=self._jit) for f in self._cheap)
            self.A_cheap = fem_petsc.create_matrix(self._cheap[1], self.matrix_type)
        return self._cheap

    def _jacobian_matrix(self) -> PETSc.Mat:
        """The matrix of the Jacobian :meth:`forms` gives now, SNES's from the next solve."""
        A = self.A
        if self._cheap_now():
            self._compiled_cheap()  # makes A_cheap at the first use
            A = self.A_cheap
        if A is not self._in_use:
            self.snes.setJacobian(weak_method(self._J), A)
            self._in_use = A
        return A

    def set_options(self, options: dict) -> None:
        """:func:`~.snes.apply_options` to this solver's SNES and prefix."""
        apply_options(self.snes, self.prefix, options)

    def _update_u(self, x: PETSc.Vec) -> None:
        """u ← x, ghosts included (through the arrays: no PETSc vector wrapped around u)."""
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with x.localForm() as x_local:
            self.u.x.array[:] = x_local.array_r

    def _F(self, snes, x, b) -> None:
        self._update_u(x)
        with b.localForm() as b_local:
            b_local.set(0.0)
        L, a = self.forms()
        fem_petsc.assemble_vector(b, L)
        with b.localForm() as b_local:
            finite = self.comm.allreduce(bool(np.isfinite(b_local.array).all()), op=MPI.LAND)
        if not finite:
            self.domain_errors += 1
            if snes is not None:
                set_domain_error(snes, "function")
            b.set(np.inf)
            return
        if self.nodal_forces is not None:
            dofs, vals = self.nodal_forces()
            with b.localForm() as b_local:
                b_local.array[dofs] -= vals
        fem_petsc.apply_lifting(b, [a], bcs=[self.bcs], x0=[x], scale=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(b, self.bcs, x, -1.0)

    def _monitor(self, snes, its: int, norm: float) -> None:
        """Record the residual norm with which a Newton solve starts."""
        if its == 0:
            self.initial_norm = norm

    def _J(self, snes, x, A, P) -> None:
        self._update_u(x)
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, self.forms()[1], bcs=self.bcs)
        A.assemble()
        if not np.isfinite(A.norm(PETSc.NormType.FROBENIUS)) and snes is not None:
            set_domain_error(snes, "jacobian")

    def evaluate_residual(self, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """R(x) into b as SNES sees it (boundary rows, nodal forces, domain check)."""
        self._F(None, x, b)

    def evaluate_jacobian(self, x: PETSc.Vec) -> PETSc.Mat:
        """The Jacobian at x (boundary rows and columns set), in :attr:`A` or :attr:`A_cheap`."""
        A = self._jacobian_matrix()
        self._J(None, x, A, A)
        return A

    def _newton(self, near: bool = False) -> tuple[int, int]:
        """One SNES solve (``near``: by the correction test alone, :meth:`solve`); a
        linear-solver failure (e.g. MUMPS on a singular tangent raises a PETSc error rather
        than returning a reason) counts as DIVERGED_LINEAR_SOLVE, so the load stepper cuts the
        step and reports it like any other divergence."""
        with self.x.localForm() as x_local:
            x_local.array[:] = self.u.x.array
        self._jacobian_matrix()
        try:
            if near and self.step_rtol > 0.0:
                its, reason = self._polish()
            else:
                self.snes.solve(None, self.x)
                reason, its = self.snes.getConvergedReason(), self.snes.getIterationNumber()
            if reason == RELATIVE and self.step_rtol > 0.0:
                more, reason = self._polish()
                its += more
        except PETSc.Error:
            return (
                int(PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE),
                self.snes.getIterationNumber(),
            )
        self._update_u(self.x)
        return reason, its

    def _polish(self) -> tuple[int, int]:
        """Newton on from an iterate accepted by the relative residual test alone (or from a
        start ``near`` the solution, :meth:`solve`), until its correction is below
        :attr:`step_rtol` of the state (PETSc's step test, ``snes_stol``, with rtol off) or the
        residual below ``snes_atol``, within ``snes_max_it`` more iterations: (iterations,
        reason). The residual norm the first solve started from is kept (:attr:`initial_norm`)."""
        rtol, _, stol, _ = self.snes.getTolerances()
        initial = self.initial_norm
        self.polished += 1
        self.snes.setTolerances(rtol=0.0, stol=max(stol, self.step_rtol))
        try:
            self.snes.solve(None, self.x)
        finally:
            self.snes.setTolerances(rtol=rtol, stol=stol)
            self.initial_norm = initial
        return self.snes.getIterationNumber(), self.snes.getConvergedReason()

    def solve(self, near: bool = False) -> tuple[int, int]:
        """Newton from the current u; returns (converged reason, iterations). u holds the result.

        A solve that meets only the relative residual test (‖R‖ ≤ rtol ‖R₀‖) goes on until a
        Newton correction is below :attr:`step_rtol` of the state (:meth:`_polish`). ‖R₀‖
        measures the load increment, not the accuracy: with stiff fibres it is the Dirichlet
        lifting of the grip increment, ~K·Δū, and rtol of it accepted states whose grip force
        depended on the step size by up to 12 % (docs/theory.md, "Converged load steps").
        From a start ``near`` the solution (a warm start, stepping.py) ‖R₀‖ measures nothing of
        the increment, and rtol of it can lie below the residual's rounding floor: that solve
        takes the correction test (or ``snes_atol``) alone.

        With exact constraints (``multipliers``), Newton runs at fixed multipliers, which are
        then updated until every constraint holds to :data:`CONSTRAINT_TOLERANCE`
        (discretise/constraints.py), stiffening the augmentation after an update that cut the
        largest violation by less than :data:`SLOW_CONTRACTION`; the iterations of all solves
        are summed. If they do not within :data:`MAX_MULTIPLIER_UPDATES`, the reason is SNES's
        DIVERGED_MAX_IT.

        The solves after an update continue the first one: they start from its converged state,
        and their relative tolerance is taken of the residual the first one started from (an
        absolute tolerance rtol · ‖R₀‖ for them). Measured from their own, tiny, initial
        residual, rtol asked for less than the rounding floor of a stiffened augmentation
        (380 × 100 mm at ±30°: the residual stagnated at 6e-10 against 1e-13 asked).
        """
        for m in self.multipliers:
            m.relax()
        reason, its = self._newton(near)
        if not self.multipliers:
            return reason, its
        rtol, atol, _, _ = self.snes.getTolerances()
        self.snes.setTolerances(atol=max(atol, rtol * self.initial_norm))
        try:
            return uzawa(self, reason, its)
        finally:
            self.snes.setTolerances(atol=atol)

    def state(self) -> list[np.ndarray]:
        """u and the multipliers, to :meth:`restore` after a failed attempt."""
        return [self.u.x.array.copy()] + [m.state() for m in self.multipliers]

    def restore(self, state: list[np.ndarray]) -> None:
        self.u.x.array[:] = state[0]
        for m, s in zip(self.multipliers, state[1:]):
            m.restore(s)

    def internal_force(self) -> PETSc.Vec:
        """R(u) assembled without boundary conditions or nodal forces (owned entries complete),
        into the solver's own work vector :attr:`force`: the next call overwrites it, and the
        solver destroys it."""
        with self.force.localForm() as f_local:
            f_local.set(0.0)
        fem_petsc.assemble_vector(self.force, self.forms()[0])
        self.force.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return self.force

    def virtual_work(self, w: fem.Function) -> float:
        """R(u)·w of the internal force (e.g. a reaction, w the boundary motion), reduced over
        ranks."""
        return dot_function(self.internal_force(), w)
