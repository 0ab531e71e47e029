"""Load stepping with automatic step cutting on divergence (docs/theory.md), apart from the
Newton solver it drives (as dolfiny keeps continuation apart from Newton): any object with
``solve() -> (reason, iterations)``, ``state()``, ``restore(state)`` and ``u`` can be stepped.

A ``predictor`` may offer, for each requested step, a state to start Newton from instead of the
last converged one (e.g. the same step of an earlier run with nearby moduli, corrected by its
sensitivities: fabricsurf/inverse/forward/warm_start.py). The step is then tried once from that
state at its full load, by ``solve(near=True)`` (a solver given a predictor must take it: the
start's residual is no measure of the step, :meth:`~.solver.SNESSolver.solve`); if Newton does
not converge from it, the step is followed as without a predictor, from the last converged
state. For a problem whose equilibrium at a load does not depend on the path taken to it
(elastic, no friction or history), the converged state is the same up to Newton's tolerance.

A solver whose equilibrium does depend on the path (friction: the forming plug-in) may take
the cut increments as continuation only: if it has an attribute ``step_end``, the stepper sets
it True for a solve at the requested load and False for the cut loads before it, and the
solver solves every attempt from the state of the last requested load (the cut loads only give
Newton its starting point). The answer at a requested load then does not depend on how often
its increment was cut, so it does not jump where a neighbouring set of moduli needs one cut
more or less (docs/forming.md, "Cuts that do not change the path").

Each cut of an increment is logged at DEBUG (detail: the step's own line, at PROGRESS, is the
caller's), on rank 0 of the solver's communicator.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.snes import reason_name
from fabricsurf.discretise.solver import SNESSolver
from fabricsurf.log import rank0

logger = logging.getLogger(__name__)


class LoadStepError(RuntimeError):
    """The load path could not be followed even with the minimum step.

    Attributes (the same on every rank): ``step`` (1-based, as in the output files),
    ``target``, ``last_load`` (the last converged load), ``reason`` (SNES code of the last
    attempt), ``attempts`` (the loads tried in this step, with their SNES reason codes),
    ``partial`` (what the caller converged before the failure, or None) and ``experiment``
    (the name of the experiment that failed, or None). A caller that knows more raises
    :meth:`carrying` ``from`` the error instead of changing it.
    """

    def __init__(
        self,
        message: str,
        step: int = 0,
        target: float = float("nan"),
        last_load: float = float("nan"),
        reason: int = 0,
        attempts: Sequence[tuple[float, int]] = (),
        partial=None,
        experiment: str | None = None,
    ) -> None:
        super().__init__(message)
        self.step, self.target, self.last_load = step, target, last_load
        self.reason, self.attempts = reason, list(attempts)
        self.partial, self.experiment = partial, experiment

    def carrying(
        self, message: str | None = None, partial=None, experiment: str | None = None
    ) -> LoadStepError:
        """The same failure (step, loads, reason, attempts) with a new ``message`` and what the
        caller adds: the steps it converged (``partial``) and the experiment's name; what is
        not given is kept."""
        return LoadStepError(
            str(self) if message is None else message,
            self.step,
            self.target,
            self.last_load,
            self.reason,
            self.attempts,
            self.partial if partial is None else partial,
            self.experiment if experiment is None else experiment,
        )

    def as_dict(self) -> dict:
        """Where the load path stopped, JSON-ready: step, last_load, reason, message."""
        return {
            "step": self.step,
            "last_load": self.last_load,
            "reason": self.reason,
            "message": str(self),
        }


class LoadStepper:
    """Follow a load parameter t through requested values, cutting the step on divergence.

    ``set_load(t)`` updates the problem data (Constants, BC values) for load t;
    ``on_converged(k, t, iters)`` is called for each requested value t_k (k from 0) once
    converged (write output there: everything converged is on disk when a later step fails).
    Messages and :class:`LoadStepError` count steps from 1, as the output files do.
    ``predictor(k, t_k)``, called with the load already set to t_k, returns a start for Newton
    (an array like ``solver.u.x.array``, ghosts included) or None (module docstring);
    ``predicted`` records per step whether the predicted start converged (None: no start).
    Each cut is logged at DEBUG (module docstring), its line prefixed with ``label``.
    """

    def __init__(
        self,
        solver: SNESSolver,
        set_load: Callable[[float], None],
        on_converged: Callable[[int, float, int], None] | None = None,
        min_fraction: float = 1e-4,
        predictor: Callable[[int, float], np.ndarray | None] | None = None,
        label: str = "",
    ):
        self.solver, self.set_load, self.on_converged = solver, set_load, on_converged
        self.min_fraction, self.predictor, self.label = min_fraction, predictor, label
        self.comm = getattr(solver, "comm", MPI.COMM_SELF)
        self.t = 0.0
        self.iterations: list[int] = []
        self.attempts: list[int] = []
        self.predicted: list[bool | None] = []

    def _try(
        self, t: float, start: np.ndarray | None = None, final: bool = True
    ) -> tuple[bool, int, int]:
        """One attempt at load ``t`` (``final``: the requested load itself, module docstring);
        (converged, SNES reason, iterations), the state restored if it failed."""
        backup = self.solver.state()
        if hasattr(self.solver, "step_end"):
            self.solver.step_end = final
        self.set_load(t)
        if start is not None:
            self.solver.u.x.array[:] = start
        reason, its = self.solver.solve() if start is None else self.solver.solve(near=True)
        finite = bool(np.isfinite(self.solver.u.x.array).all())
        ok = reason > 0 and self.comm.allreduce(finite, op=MPI.LAND)
        if not ok:
            self.solver.restore(backup)
        return ok, reason, its

    def advance_to(self, target: float, k: int) -> int:
        """Reach load ``target`` (requested step ``k``, 0-based) from the current load;
        returns the total Newton iterations (failed attempts included)."""
        done, total = self._predicted(target, k)
        if done:
            return total
        span = target - self.t
        dt, tried = span, []
        while abs(target - self.t) > 1e-14 * max(1.0, abs(target)):
            t_next = self.t + dt if abs(dt) < abs(target - self.t) else target
            ok, reason, its = self._try(t_next, final=t_next == target)
            total += its
            tried.append((t_next, reason))
            if ok:
                self.t = t_next
                dt = float(np.sign(span)) * min(abs(span), 1.5 * abs(dt))
                continue
            dt = 0.5 * (t_next - self.t)
            self._say(
                f"step {k + 1}: SNES {reason_name(reason)} at load {t_next:.6g}; "
                f"cutting the increment to {dt:.3g}"
            )
            if abs(dt) < self.min_fraction * abs(span):
                self.set_load(self.t)
                raise LoadStepError(
                    _failure_message(k + 1, target, self.t, reason, tried, self.min_fraction),
                    k + 1,
                    target,
                    self.t,
                    reason,
                    tried,
                )
        self.attempts.append(len(tried))
        return total

    def _predicted(self, target: float, k: int) -> tuple[bool, int]:
        """Step ``k`` from the predictor's start, if it offers one (class docstring): (whether
        the step is done, the Newton iterations it cost)."""
        start = None
        if self.predictor is not None:
            self.set_load(target)
            start = self.predictor(k, target)
            if start is None:
                self.set_load(self.t)
        if start is None:
            self.predicted.append(None)
            return False, 0
        ok, reason, its = self._try(target, start)
        self.predicted.append(ok)
        if ok:
            self.t = target
            self.attempts.append(1)
        else:
            self._say(
                f"step {k + 1}: SNES {reason_name(reason)} from the predicted state; "
                "stepping from the last converged one"
            )
        return ok, its

    def _say(self, message: str) -> None:
        rank0(logger, self.comm, self.label + message, level=logging.DEBUG)

    def run(self, targets: Sequence[float]) -> list[int]:
        for k, target in enumerate(targets):
            its = self.advance_to(float(target), k)
            self.iterations.append(its)
            if self.on_converged is not None:
                self.on_converged(k, float(target), its)
        return self.iterations


def _failure_message(
    step: int,
    target: float,
    last: float,
    reason: int,
    tried: list[tuple[float, int]],
    min_fraction: float,
) -> str:
    failed = [(t, r) for t, r in tried if r <= 0]
    shown = ", ".join(f"{t:.6g}" for t, _ in failed[:3])
    if len(failed) > 4:
        shown += f", ... ({len(failed) - 4} more), "
    elif len(failed) == 4:
        shown += ", "
    shown += f"{failed[-1][0]:.6g}" if len(failed) > 3 else ""
    return (
        f"load step {step} (target {target:.6g}) failed: Newton did not converge "
        f"({reason_name(reason)}) even after cutting the increment {len(failed) - 1} times "
        f"to below {min_fraction:g} of the step; loads tried without convergence: {shown}; "
        f"last converged load {last:.6g}"
    )
