"""The step log of a forming run (experiments/hemisphere.py): one record per requested stroke
step, and a progress line for it the moment it converges.

A forming run at a user's size takes minutes; a user must see where it is. Each converged
step records the stroke, the punch force, the Newton iterations (failed attempts included),
the attempts (1: no cut), the repeats with the fallback line search, how many quadrature points
entered or left contact with the punch since the previous step, and its wall-clock time (the
largest over ranks). Every number is reduced over ranks, so the records are the same on every
rank; the line is logged at PROGRESS on rank 0 (fabricsurf/log.py: a program's terminal
handler flushes it, so it reaches the terminal at once under ``mpirun`` too).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
from mpi4py import MPI

from fabricsurf.log import rank0

logger = logging.getLogger(__name__)


class StrokeLog:
    """Records of the steps of one run (:attr:`records`), written as they converge."""

    def __init__(
        self,
        comm: MPI.Comm,
        active_set: Callable[[], np.ndarray],
        fallbacks: Callable[[], int],
        label: str = "",
    ) -> None:
        self.comm, self.active_set, self.fallbacks = comm, active_set, fallbacks
        self.label = label
        self.records: list[dict] = []
        self._active, self._fallbacks = active_set(), fallbacks()
        self._t = time.perf_counter()

    def step(
        self, k: int, stroke: float, force: float, iterations: int, attempts: int, steps: int
    ) -> dict:
        """Record requested step ``k`` (0-based) of ``steps``, converged at ``stroke``."""
        now, fb = self.active_set(), self.fallbacks()
        changes = self.comm.allreduce(int(np.count_nonzero(now != self._active)), op=MPI.SUM)
        t = time.perf_counter()
        seconds = self.comm.allreduce(t - self._t, op=MPI.MAX)
        rec = {
            "step": k + 1,
            "stroke_mm": stroke,
            "punch_force_N": force,
            "newton_iterations": int(iterations),
            "attempts": int(attempts),
            "fallbacks": fb - self._fallbacks,
            "contact_changes": changes,
            "seconds": seconds,
        }
        self.records.append(rec)
        self._active, self._fallbacks, self._t = now, fb, t
        rank0(
            logger,
            self.comm,
            f"{self.label}step {k + 1}/{steps}: stroke {stroke:.4g} mm, "
            f"force {force:.4g} N, {iterations} Newton iterations, {attempts - 1} cuts, "
            f"{rec['fallbacks']} l2 repeats, {changes} contact changes, {seconds:.1f} s",
        )
        return rec

    @staticmethod
    def totals(r: list[dict]) -> dict:
        """Totals over step records: iterations, cuts, repeats, changes, seconds."""
        return {
            "steps": len(r),
            "newton_iterations": sum(x["newton_iterations"] for x in r),
            "cuts": sum(x["attempts"] - 1 for x in r),
            "fallbacks": sum(x["fallbacks"] for x in r),
            "contact_changes": sum(x["contact_changes"] for x in r),
            "seconds": sum(x["seconds"] for x in r),
        }
