"""What a diagnosis spends, stage by stage, as it goes: forward runs, Newton iterations and
seconds per (mesh level, stage), for its progress messages with an estimate of the time left
and for the ``profile`` of diagnosis.json (docs/speed.md).

A :class:`Profile` is made active for the diagnosis (:func:`active`); every forward run
(:meth:`~.runs.ForwardModel.run`) adds itself to the stage being timed (:meth:`Profile.stage`).
A stage nested in another counts for itself alone (exclusive seconds and runs). The estimate of
the time left (:meth:`Profile.estimate_left`) takes, for each stage still to come, the mean
seconds of the completed stages of its kind in this diagnosis, else the kind's typical share
relative to the baseline fit (:data:`RELATIVE`, from the benchmark family): a rough figure,
which the progress message says.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import time
from collections.abc import Iterator

from mpi4py import MPI

from fabricsurf.log import rank0

logger = logging.getLogger(__name__)

KINDS = ("baseline", "ranking", "refits", "h/2 check")
"""The kinds of stages whose seconds are estimated (a stage's kind: the first of these its
name contains, else "other")."""
RELATIVE = {"baseline": 1.0, "ranking": 0.15, "refits": 0.6, "h/2 check": 0.4, "other": 0.1}
"""Seconds of a stage of each kind over the baseline fit's, in the benchmark family after
the linearised starts (docs/speed.md, "After"): used until this diagnosis has done one."""

_current: contextvars.ContextVar[Profile | None] = contextvars.ContextVar(
    "fabricsurf_profile", default=None
)


def kind(stage: str) -> str:
    """The kind of the stage named ``stage`` (:data:`KINDS`)."""
    return next((k for k in KINDS if k in stage), "other")


class Profile:
    """Forward runs, Newton iterations and exclusive seconds per (level, stage) (module
    docstring), on communicator ``comm``."""

    def __init__(self, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
        self.comm, self.t0 = comm, time.perf_counter()
        self.rows: dict[tuple[int, str], dict] = {}
        self._stack: list[list] = []

    @contextlib.contextmanager
    def stage(self, name: str, level: int | None = None, say: bool = True) -> Iterator[None]:
        """Time stage ``name`` of mesh level ``level`` (None: the enclosing stage's, else 0);
        with ``say``, log its start on rank 0."""
        if level is None:
            level = self._stack[-1][3] if self._stack else 0
        row = self.rows.setdefault(
            (level, name), {"forward_runs": 0, "newton": 0, "seconds": 0.0, "done": 0}
        )
        if say:  # collective: every rank enters the same stages
            (elapsed,) = self._slowest(self.elapsed())
            rank0(logger, self.comm, f"[level {level}] {name} ({elapsed:.0f} s so far)")
        frame = [row, time.perf_counter(), 0.0, level]
        self._stack.append(frame)
        try:
            yield
        finally:
            self._stack.pop()
            dt = time.perf_counter() - frame[1]
            row["seconds"] += dt - frame[2]
            row["done"] += 1
            if self._stack:
                self._stack[-1][2] += dt

    def add_run(self, newton: int) -> None:
        """A forward run of ``newton`` Newton iterations in the stage being timed."""
        if self._stack:
            row = self._stack[-1][0]
            row["forward_runs"] += 1
            row["newton"] += int(newton)

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def estimate_left(self, stages: list[str]) -> float:
        """Seconds the stages named ``stages``, still to come, will take (module docstring)."""
        done: dict[str, list[float]] = {}
        for (_, name), row in self.rows.items():
            if row["done"]:
                done.setdefault(kind(name), []).append(row["seconds"] / row["done"])
        base = done.get("baseline", [self.elapsed()])
        unit = sum(base) / len(base)
        left = 0.0
        for name in stages:
            seen = done.get(kind(name))
            left += sum(seen) / len(seen) if seen else RELATIVE[kind(name)] * unit
        return left

    def progress(self, level: int, stage: str, stages_left: list[str]) -> None:
        """Log (rank 0) the level, the stage, the seconds so far and the estimated time left
        (the slowest rank's; collective)."""
        elapsed, left = self._slowest(self.elapsed(), self.estimate_left(stages_left))
        rank0(
            logger,
            self.comm,
            f"[level {level}] {stage}: {elapsed:.0f} s so far, "
            f"about {left:.0f} s left (a rough estimate)",
        )

    def _slowest(self, *values: float) -> list[float]:
        """Each of ``values``' maximum over the ranks (collective)."""
        every = self.comm.allgather(values)
        return [max(v[i] for v in every) for i in range(len(values))]

    def as_json(self) -> dict:
        """The ``profile`` of diagnosis.json: per stage its level, name, forward runs and
        Newton iterations (the busier rank's: where the ranks shared refits each counts its
        own) and seconds (the slowest rank's), and their totals; the same on every rank."""
        keys = list(self.rows)
        mine = [[self.rows[k]["forward_runs"], self.rows[k]["newton"]] for k in keys]
        secs = [self.rows[k]["seconds"] for k in keys]
        every = self.comm.allgather((mine, secs))
        counts = [[max(p[0][i][j] for p in every) for j in (0, 1)] for i in range(len(keys))]
        secs = [max(p[1][i] for p in every) for i in range(len(keys))]
        stages = [
            {"level": lv, "stage": name, "forward_runs": c[0], "newton": c[1], "seconds": s}
            for (lv, name), c, s in zip(keys, counts, secs)
        ]
        total = self.comm.allreduce(self.elapsed(), op=MPI.MAX)
        return {
            "stages": stages,
            "forward_runs": sum(q["forward_runs"] for q in stages),
            "newton": sum(q["newton"] for q in stages),
            "seconds": total,
            "reduction": "counts: the busier rank's; seconds: the slowest rank's",
        }


@contextlib.contextmanager
def active(profile: Profile) -> Iterator[Profile]:
    """Let ``profile`` record every forward run within (this context only)."""
    token = _current.set(profile)
    try:
        yield profile
    finally:
        _current.reset(token)


def current() -> Profile | None:
    """The active profile (None: nothing is recorded)."""
    return _current.get()


def stage(name: str) -> contextlib.AbstractContextManager[None]:
    """:meth:`Profile.stage` ``name`` of the active profile, at the enclosing stage's level
    and silently (nothing when no profile is active): for the parts of a stage that its
    caller times (a round's ranking run and its refits)."""
    prof = current()
    return contextlib.nullcontext() if prof is None else prof.stage(name, say=False)


ROUND = ("ranking", "refits")
"""The stages of one round of a diagnosis (for the estimate of the time left)."""


def timed(name: str, level: int) -> contextlib.AbstractContextManager[None]:
    """:meth:`Profile.stage` ``name`` of mesh level ``level`` of the active profile, its start
    logged (nothing when no profile is active). Collective when active."""
    prof = current()
    return contextlib.nullcontext() if prof is None else prof.stage(name, level)


def progress(level: int, stage: str, stages_left: list[str]) -> None:
    """:meth:`Profile.progress` of the active profile (nothing when none is). Collective when
    active."""
    prof = current()
    if prof is not None:
        prof.progress(level, stage, stages_left)
