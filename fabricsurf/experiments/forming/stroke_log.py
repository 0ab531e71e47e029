"""The step log of a forming run (experiments/hemisphere.py): one record per requested stroke
step, and a progress line for it the moment it converges.

A forming run at a user's size takes minutes; a user must see where it is. Each converged
step records the stroke, the punch force, the Newton iterations (failed attempts included),
the attempts (1: no cut), the repeats with the fallback line search, how many quadrature points
entered or left contact with the punch since the previous step, the largest shear angle, and
its wall-clock time (the largest over ranks). A shear past :data:`COLLAPSE_DEG` is warned of
once: the net is then near collapse, and a step that fails after it most likely failed there.
Every number is reduced over ranks, so the records are the same on every rank; the line is
logged at PROGRESS on rank 0 (fabricsurf/log.py: a program's terminal handler flushes it, so it
reaches the terminal at once under ``mpirun`` too).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.log import rank0, warn

logger = logging.getLogger(__name__)
COLLAPSE_DEG = 80.0
"""A shear angle (deg) past which the net is near collapse: its fibres within 10° of parallel, a
cell's area cos γ < 0.18 of its reference area, far past any woven fabric's locking (40–55°,
Cao et al. 2008). A fabric model without locking (or with a soft one) can shear that far where
the flange is compressed; the kinematics become singular at 90° and Newton fails near it."""
STABILISATION_SHARE = 0.05
"""Share of the punch's work dissipated by the viscous stabilisation above which a run warns:
the drag, not the fabric, then carries a visible part of the load."""


class StrokeLog:
    """Records of the steps of one run (:attr:`records`), written as they converge."""

    def __init__(
        self,
        comm: MPI.Comm,
        active_set: Callable[[], np.ndarray],
        fallbacks: Callable[[], int],
        label: str = "",
        shear: Callable[[], float] | None = None,
    ) -> None:
        self.comm, self.active_set, self.fallbacks = comm, active_set, fallbacks
        self.shear = shear  # the largest shear angle (deg), the same on every rank
        self._collapsed = False
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
            "max_shear_deg": None if self.shear is None else self.shear(),
            "seconds": seconds,
        }
        self.records.append(rec)
        self._active, self._fallbacks, self._t = now, fb, t
        rank0(
            logger,
            self.comm,
            f"{self.label}step {k + 1}/{steps}: stroke {stroke:.4g} mm, "
            f"force {force:.4g} N, {iterations} Newton iterations, {attempts - 1} cuts, "
            f"{rec['fallbacks']} l2 repeats, {changes} contact changes, "
            + ("" if self.shear is None else f"largest shear {rec['max_shear_deg']:.1f}°, ")
            + f"{seconds:.1f} s",
        )
        if (rec["max_shear_deg"] or 0.0) > COLLAPSE_DEG and not self._collapsed:
            self._collapsed = True  # the first step past it says so; the lines show the rest
            warn(logger, self.comm, f"{self.label}{collapse_text(rec['max_shear_deg'])}")
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


def collapse_text(shear_deg: float, where: str = "") -> str:
    """What a shear past :data:`COLLAPSE_DEG` means (``where``: at which point), and what to
    do."""
    return (
        f"the largest shear angle reached {shear_deg:.1f}°{where}, past {COLLAPSE_DEG:g}°: the "
        "net is near collapse there (its fibres nearly parallel), which no woven fabric "
        "reaches; the fabric model does not lock (add shear_locking, or stiffen it) or the "
        "blank is drawn where it should wrinkle"
    )


def collapsed(
    err: LoadStepError, records: list[dict], where: Callable[[], tuple[float, float]]
) -> LoadStepError:
    """The failure ``err`` of a run whose step ``records`` hold the largest shear of each step:
    when the last converged step's is past :data:`COLLAPSE_DEG`, its message adds so, and the
    reference point ``where()`` of the largest shear (a collective call); else unchanged."""
    last = (records[-1].get("max_shear_deg") or 0.0) if records else 0.0
    if last <= COLLAPSE_DEG:
        return err.carrying()
    X, Y = where()
    text = collapse_text(last, f" at the reference point ({X:.4g}, {Y:.4g}) mm")
    return err.carrying(f"{err}; at the last converged step {text}")


def stabilisation_share(
    comm: MPI.Comm, stroke: list[float], force: list[float], damped: float, label: str = ""
) -> float:
    """The share of the punch's work ∫ F ds (trapezoid rule) that the viscous stabilisation
    dissipated (``damped``, N·mm, whole blank), logged at PROGRESS on rank 0; a warning above
    :data:`STABILISATION_SHARE`."""
    work = float(np.trapz(force, stroke))
    share = damped / work if work > 0.0 else float("inf")
    text = (
        f"{label}stabilisation dissipated {damped:.4g} N·mm, {share:.2%} of the punch's work "
        f"({work:.4g} N·mm)"
    )
    if share > STABILISATION_SHARE:
        warn(
            logger,
            comm,
            f"{text}: more than {STABILISATION_SHARE:.0%}, so the drag carries part of the "
            "load; lower [tooling] stabilisation",
        )
    else:
        rank0(logger, comm, text)
    return share
