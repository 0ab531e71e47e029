"""The Newton solver of the forming problem (tools.ContactProblem): a secant predictor
along the stroke, full Newton steps with the ``l2`` line search as a fallback, the friction of
the punch and the die's lip added to residual and Jacobian while it is on, and the dissipation
of each converged step (docs/forming.md)."""

from __future__ import annotations

from contextlib import contextmanager
from typing import Protocol

import numpy as np
import ufl
from dolfinx import cpp as _cpp
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabricsurf.discretise.snes import SNES_DEFAULTS, SOLVER_KEYS
from fabricsurf.discretise.solver import SNESSolver

FULL_STEP_ITERATIONS = 40
"""Newton iterations of the full-step attempt: it converges in 7–24 from the extrapolated start
and in about 30 in the first step (from the flat blank) of the demo's full size, where 25 were
too few and the `l2` repeat from the flat blank failed too (docs/forming.md)."""
FULL_STEP_DIVERGENCE = 1e2
"""PETSc's divergence tolerance of the full-step attempt: it stops once the residual exceeds this
multiple of the one it started from. A full-step attempt that fails seldom wanders: its
residual grows, to 10²–10⁸ times its start by its 40th iteration, and passes 10² after a median
of 11 iterations (49 of 52 failing attempts in the forming tests and the double dome, on 1 and
2 ranks). Of 424 converging attempts, one rose above 10² (to 324 times its start; the 99th
percentile is 44) and is repeated by the fallback from the same start: the answer cannot
depend on the tolerance, only the time (docs/forming.md, "A failing attempt stops early")."""
FALLBACK = {
    "snes_linesearch_type": "l2",
    "snes_max_it": 50,
    "snes_divergence_tolerance": SNES_DEFAULTS["snes_divergence_tolerance"],
}
"""Newton's options for the repeat of a failed full-step attempt (:class:`ContactSolver`);
if it fails too, the load stepper cuts the stroke increment."""

FALLBACK_STREAK = 2
"""Consecutive steps whose full-step attempt failed and whose repeat converged, after which the
repeat's options are tried first (:class:`ContactSolver`), until they fail where full steps
converge. A single failed attempt is common (the forming demo: one repeat in 12 steps); a run
where every step needs the repeat (an unbalanced pair on a coarse mesh: 11 of 12 steps) spends
no more failed attempts (docs/forming.md, "Which attempt first")."""

LINEAR_SOLVER: dict = {}
"""Options of the linear solver beyond the SNES defaults (MUMPS LU). MUMPS's LDLᵀ
(``{"pc_type": "cholesky"}``) saves about a seventh of the CPU on the symmetric Jacobian but
failed at the forming demo's first step where LU converges (docs/forming.md): an option."""


class StrokeTools(Protocol):
    """What the solver reads of the tools (:class:`~.tools.Tools`): the stroke now and at the
    last converged step, the friction regularisation, the holder's friction coefficient and
    whether tool friction is on."""

    mu: fem.Constant
    stroke: fem.Constant
    stroke_n: fem.Constant
    eps: fem.Constant
    damping: fem.Constant
    slip_rate: float
    stabilisation: float
    R: float

    def tool_friction(self) -> bool: ...


class ContactSolver(SNESSolver):
    """SNESSolver that follows the stroke: a secant predictor, and full Newton steps with the
    ``l2`` line search as a fallback.

    A solve starts from the last converged state (the load stepper restores it after a failed
    attempt): that state is copied to ``u_n``, the r_n of the friction potential, first, and
    the regularising slip set from the stroke increment since it (``s_n``). The start is then
    extrapolated along the path through the last two converged states (u_n + (s − s_n)/(s_n −
    s_prev)·(u_n − u_prev)): a stroke increment moves the whole sheet (the flange draws in, the
    net shears), and Newton started from the previous state spends most of its iterations
    finding that motion. Newton takes full steps first; if that attempt fails, it is repeated
    from the same predicted state with ``fallback`` options (the ``l2`` line search, which
    damps the overshoot at the kinks of the contact residual) before the load stepper cuts the
    increment (docs/forming.md, measured); after :data:`FALLBACK_STREAK` such repeats in a row
    the fallback options go first. :attr:`fallbacks` counts the repeats. A converged
    solve adds the friction work of its step (``dissipation``, the solved domain) to
    :attr:`dissipated`, and the viscous stabilisation's (``damping``, a form, or None when
    it is off; its coefficient η/Δs set from the step's stroke, :meth:`_drag_forms`) to
    :attr:`damped`.
    A cut of a stroke increment (the load stepper's ``step_end`` False, stepping.py) is
    continuation only: its solves keep u_n, s_n and the path at the last requested step, and
    the requested stroke is then solved from there, its Newton started on the line through
    u_n and the cut's state; the friction's path, and so the answer, is that of the requested
    steps however often they were cut (docs/forming.md, "Cuts that do not change the path").
    ``history``: the part of the residual that depends on u_n (the holder's friction and the
    viscous drag, a UFL form) for :meth:`path_action`; :attr:`on_converged`, if set, is called
    after every converged step of the path, not a cut's solves (the forward model's
    sensitivities along the path).
    ``tool_friction`` (residual, Jacobian) of the punch's and the lip's
    friction potentials are compiled when first needed and added to R and J only while
    Tools.tool_friction() holds (Dirichlet rows and columns left out, as in the main forms;
    their lifting vanishes, every iterate meeting the homogeneous mirror conditions)."""

    def __init__(
        self,
        *args,
        tools: StrokeTools,
        u_n: fem.Function,
        dissipation,
        damping=None,
        tool_friction: tuple | None = None,
        fallback: dict | None = None,
        history=None,
        **kw,
    ) -> None:
        super().__init__(*args, **kw)
        self.tools, self.u_n = tools, u_n
        self._history, self._history_forms, self.on_converged = history, None, None
        self._dissipation = fem.form(dissipation)
        self._damping = None if damping is None else self._drag_forms(damping)
        self._tool_friction, self._friction_forms = tool_friction, None
        self._bf = self.b.duplicate()
        options = args[5] if len(args) > 5 else kw.get("options")
        self._options = {k: v for k, v in (options or {}).items() if k not in SOLVER_KEYS}
        self._fallback = fallback
        self.reset()

    def reset(self) -> None:
        """Back to the flat blank at s = 0: no displacement, dissipation or path history."""
        self.u.x.array[:] = 0.0
        self.dissipated, self.damped, self.s_n = 0.0, 0.0, 0.0
        if self._damping is not None:
            self._tau_n.x.array[:] = 0.0
        self.u_prev: np.ndarray | None = None
        self.s_prev = 0.0
        self.fallbacks = 0
        self.fallback_first, self._streak = False, 0
        self.step_end, self._mid = True, None

    def _release(self) -> None:
        super()._release()
        self._bf.destroy()

    def _drag_forms(self, damping) -> tuple:
        """(∫ (η/Δs)|Δr|² dX, ∫ τ_n·Δr dX) of a step, τ_n the drag's traction at the end of the
        last converged step (zero at rest): their mean is the step's dissipation by the
        trapezoid rule, the rule the punch's work is summed with, so that the work balance
        closes to O(Δs²) (forming/friction.py)."""
        self._tau_n = fem.Function(self.u.function_space, name="drag_n")
        lag = ufl.inner(self._tau_n, self.u - self.u_n) * ufl.dx(self.u.function_space.mesh)
        return fem.form(damping), fem.form(lag)

    def _drag_step(self) -> None:
        """Add the converged step's dissipation by the drag to :attr:`damped`; τ_n ← its
        traction (η/Δs)(u − u_n)."""
        now, lag = (fem.assemble_scalar(f) for f in self._damping)
        self.damped += 0.5 * self.comm.allreduce(now + lag, op=MPI.SUM)
        rate = float(self.tools.damping.value)
        self._tau_n.x.array[:] = rate * (self.u.x.array - self.u_n.x.array)

    def _friction(self) -> tuple | None:
        """The compiled (residual, Jacobian) of the tools' friction while it is on, else None."""
        if self._tool_friction is None or not self.tools.tool_friction():
            return None
        if self._friction_forms is None:
            self._friction_forms = tuple(fem.form(f) for f in self._tool_friction)
        return self._friction_forms

    def path_dependent(self) -> bool:
        """Whether the residual depends on the last converged state u_n: friction on any tool,
        or the viscous drag."""
        on = float(self.tools.mu.value) != 0.0 or self.tools.stabilisation != 0.0
        return self._history is not None and (on or self.tools.tool_friction())

    def path_action(self, s: fem.Function) -> PETSc.Vec:
        """(∂R/∂u_n)·s at the current state, R the whole residual (the tools' friction while it
        is on), without boundary conditions (owned entries complete; the caller destroys it):
        how the step's residual moves with its start, for sensitivities along the path."""
        if self._history_forms is None:
            self._direction = fem.Function(self.u.function_space, name="du_n")
            tool = [] if self._tool_friction is None else [self._tool_friction[0]]
            parts = [self._history, *tool]
            self._history_forms = [
                fem.form(ufl.derivative(f, self.u_n, self._direction)) for f in parts
            ]
        self._direction.x.array[:] = s.x.array
        b = self.b.duplicate()
        with b.localForm() as local:
            local.set(0.0)
        forms = self._history_forms if self._friction() is not None else self._history_forms[:1]
        for form in forms:
            fem_petsc.assemble_vector(b, form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def _update_u(self, x: PETSc.Vec) -> None:
        """u ← x, and the tools given as surfaces re-tabulated there (tabulated_tools.py)."""
        super()._update_u(x)
        for table in getattr(self.tools, "tables", ()):
            table.refresh()

    def _F(self, snes, x, b) -> None:
        super()._F(snes, x, b)
        forms = self._friction()
        if forms is not None:
            with self._bf.localForm() as local:
                local.set(0.0)
            fem_petsc.assemble_vector(self._bf, forms[0])
            self._bf.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            fem_petsc.set_bc(self._bf, self.bcs, x, 0.0)
            b.axpy(1.0, self._bf)

    def _J(self, snes, x, A, P) -> None:
        super()._J(snes, x, A, P)
        forms = self._friction()
        if forms is not None:
            a = forms[1]
            _cpp.fem.petsc.assemble_matrix(
                A, a, _cpp.fem.pack_constants(a), _cpp.fem.pack_coefficients(a), self.bcs
            )
            A.assemble()

    def _attempt(self, options: dict | None) -> tuple[int, int]:
        """One Newton solve with ``options`` over the problem's own (None: the full steps)."""
        if options is None:
            return super().solve()
        self.set_options({**self._options, **options})
        try:
            return super().solve()
        finally:
            self.set_options(self._options)

    @contextmanager
    def exact_tangent(self):
        """The Jacobian at u with the curvature of the tools given as analytic surfaces, for the
        sensitivities (factorised at their first solve); Newton's has the frozen normal."""
        tables = [t for t in getattr(self.tools, "tables", ()) if t.K is not None]
        for table in tables:
            table.curved = True
        try:
            if tables:
                with self.x.localForm() as x_local:
                    x_local.array[:] = self.u.x.array
                self.evaluate_jacobian(self.x)
            yield
        finally:
            for table in tables:
                table.curved = False
                table.K.x.array[:] = 0.0

    def _predict(self, s: float) -> None:
        """Extrapolate u along the path through (s_prev, u_prev) and (s_n, u_n) to s; after a
        cut, along the line through (s_n, u_n) and the cut's state (class docstring)."""
        if self._mid is not None:
            f = (s - self.s_n) / (self._mid - self.s_n)
            self.u.x.array[:] = self.u_n.x.array + f * (self.u.x.array - self.u_n.x.array)
        elif self.u_prev is not None and self.s_n != self.s_prev:
            f = (s - self.s_n) / (self.s_n - self.s_prev)
            self.u.x.array[:] += f * (self.u_n.x.array - self.u_prev)

    def solve(self) -> tuple[int, int]:
        if self._mid is None:  # u is the state of the last requested step (not a cut's)
            self.u_n.x.array[:] = self.u.x.array
        self.tools.stroke_n.value = self.s_n
        if self._friction() is not None:  # the tools given as surfaces at (r_n, s_n)
            for table in getattr(self.tools, "last_tables", ()):
                table.refresh()
        s = float(self.tools.stroke.value)
        ds = abs(s - self.s_n)
        self.tools.eps.value = self.tools.slip_rate * max(ds, 1e-6 * self.tools.R)
        # no drag on a solve at the same stroke (the softened start)
        self.tools.damping.value = self.tools.stabilisation / ds if ds > 0.0 else 0.0
        self._predict(s)
        predicted = self.u.x.array.copy()
        first = self._fallback if self.fallback_first else None
        reason, its = self._attempt(first)
        if reason <= 0 and self._fallback:
            self.fallbacks += 1
            self.u.x.array[:] = predicted
            reason, more = self._attempt(None if first else self._fallback)
            its += more
            if reason > 0:  # the other options converged where the first did not
                self._streak = self._streak + 1 if first is None else 0
                self.fallback_first = self._streak >= FALLBACK_STREAK
        elif first is None:
            self._streak = 0
        if reason > 0 and not self.step_end:  # a cut's state: a start, not a step of the path
            self._mid = s
        elif reason > 0:
            self._mid = None
            self.u_prev, self.s_prev, self.s_n = self.u_n.x.array.copy(), self.s_n, s
            self.dissipated += self.comm.allreduce(
                fem.assemble_scalar(self._dissipation), op=MPI.SUM
            )
            if self._damping is not None:
                self._drag_step()
            if self.on_converged is not None:
                self.on_converged()
        return reason, its
