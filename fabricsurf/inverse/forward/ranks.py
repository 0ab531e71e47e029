"""Rank-local forward solves: small meshes solved whole on every rank (docs/dic.md, "Speed").

A fit or a diagnosis runs the forward model tens to hundreds of times on meshes of a few
hundred to a few thousand cells. Distributed over the ranks, each Newton iteration of such a
mesh is a handful of collective operations (assembly's ghost exchange, MUMPS's distributed
factorisation, the norms) on a problem that a single core factors in milliseconds: the ranks
wait for each other more than they compute, and on a shared machine far more. The inverse
layer already holds every data point on every rank, so nothing is lost by solving such a mesh
on ``MPI.COMM_SELF`` on every rank: the same computation, the same answer, no communication.

Two rules keep the ranks one program:

* **Agreement** (:func:`agree`): every rank computes the run, then the ranks compare digests of
  what they computed; where they differ (they should not: the same serial code on the same
  input), rank 0's values are sent to all. A run that fails on rank 0 raises rank 0's error
  on every rank; one that fails elsewhere only takes rank 0's values. So whatever follows —
  the fit's steps, its tests, what it writes — is decided on identical numbers.
* **One voice** (:func:`one_voice`): the plug-ins report progress on rank 0 of their own
  communicator, which every rank is on ``COMM_SELF``; the other ranks' reports are muted.

Meshes above :data:`LOCAL_CELLS` (estimated before meshing) stay distributed: there the work
per iteration outweighs the communication and the memory of a whole mesh per rank counts.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import math
import os
import pickle
from collections.abc import Callable, Iterator
from typing import TypeVar

import numpy as np
from mpi4py import MPI

from fabricsurf.errors import InputError
from fabricsurf.inverse.forward import warm_start
from fabricsurf.log import muted, rank0

logger = logging.getLogger(__name__)

LOCAL_CELLS = 1000
"""Meshes of at most this many triangles (estimated: 2 per h × h square of the specimen's
length × width) are solved whole on every rank when a run has several (module docstring).
Where the CPU time of a run on 2 ranks crosses that of one rank alone (benchmarks/
local_solves.py): at 308 cells the distributed run costs 1.5 times the serial one, at 1 232
cells 0.8 times (docs/dic.md, "Rank-local solves")."""

SPREAD_RESIDUALS = 500_000
"""A diagnosis shares its candidates' refits among the ranks up to this many residuals; each
refit's result (its Jacobian and displacement sensitivities, 2 N × p doubles, about 40 MB at
this size and 5 moduli) is then gathered on every rank, which at DIC size (10⁶ rows and more)
would cost more memory than the time it saves. 2·10⁵ until the speed profile (docs/speed.md)
showed the 10⁵-row cases of the benchmark family (2.1–2.7·10⁵ residuals) refitting one
candidate after the other."""

T = TypeVar("T")

differed = 0
"""How many rank-local runs of this process ended with values that differed between the ranks
(rank 0's taken); 0 when the ranks compute bit for bit alike, as they should."""


def estimated_cells(length: float, width: float, h: float) -> float:
    """2 triangles per h × h square of a length × width specimen (a blank's quarter or a
    lattice mesh has fewer: the estimate errs towards distributing)."""
    return 2.0 * math.ceil(length / h) * math.ceil(width / h)


ENVIRONMENT = "FABRICSURF_LOCAL_CELLS"
"""An environment variable that replaces :data:`LOCAL_CELLS` (0: every mesh distributed)."""


def local_cells() -> float:
    """The threshold in force: :data:`ENVIRONMENT` when set, else :data:`LOCAL_CELLS`. A value
    that is not a number ≥ 0 is an :class:`~fabricsurf.errors.InputError` naming the variable
    (the command line checks it on every rank before computing: cli/environment.py)."""
    text = os.environ.get(ENVIRONMENT, "").strip()
    if not text:
        return LOCAL_CELLS
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not value >= 0:
        raise InputError(
            f"environment variable {ENVIRONMENT}={text!r}: give a number of cells "
            f">= 0 (0: solve every mesh distributed over the ranks; unset: "
            f"{LOCAL_CELLS})"
        )
    return value


def solve_comm(comm: MPI.Comm, cells: float, local: bool | None = None) -> MPI.Comm:
    """The communicator a forward model solves on: ``COMM_SELF`` when ``comm`` has several
    ranks and the mesh is small (``cells`` ≤ :func:`local_cells`, or ``local`` True),
    ``comm`` otherwise (one rank, a large mesh, or ``local`` False). The same on every rank
    (rank 0 decides)."""
    if comm.size == 1:
        return comm
    use = None
    if comm.rank == 0:
        try:
            use = (0 < cells <= local_cells()) if local is None else bool(local)
        except ValueError as e:
            use = e
    use = comm.bcast(use, root=0)
    if isinstance(use, ValueError):
        raise use
    return MPI.COMM_SELF if use else comm


def one_voice(comm: MPI.Comm, local: bool) -> contextlib.AbstractContextManager[None]:
    """Mute the package's messages (:func:`fabricsurf.log.muted`: this context only, no
    logger's level) on the ranks of ``comm`` other than 0 while a rank-local model builds or
    runs (each rank is rank 0 of its own ``COMM_SELF``)."""
    return muted(local and comm.rank != 0)


def rank0_first(comm: MPI.Comm, local: bool, build: Callable[[], T]) -> T:
    """``build()`` on rank 0 first, then on the other ranks, when ``local`` (each rank builds
    the same rank-local model): rank 0 compiles the forms into the JIT cache and the others
    load them, instead of every rank compiling the same form at once (dolfinx then makes all
    but one wait for the cache, and gives up after its timeout on a loaded machine). An error
    on rank 0 is raised on every rank; the others' errors are their own, as when distributed."""
    if not local or comm.size == 1:
        return build()
    out, err = None, None
    if comm.rank == 0:
        try:
            out = build()
        except Exception as e:  # raised on every rank below
            err = e
    failed = comm.bcast(_portable(err) if err is not None else None, root=0)
    if failed is not None:
        raise err if comm.rank == 0 else failed
    return out if comm.rank == 0 else build()


def _digest(value) -> bytes:
    """A digest of every array (and scalar) in ``value``, a dataclass or a list of them."""
    h = hashlib.blake2b(digest_size=16)
    items = value if isinstance(value, list) else [value]
    for item in items:
        for v in vars(item).values() if hasattr(item, "__dict__") else [item]:
            if isinstance(v, np.ndarray):
                h.update(np.ascontiguousarray(v).view(np.uint8))
            else:
                h.update(repr(v).encode())
    return h.digest()


def _portable(err: BaseException) -> BaseException:
    """``err`` if it pickles, else a RuntimeError with its message (sent to the other ranks)."""
    try:
        pickle.dumps(err)
        return err
    except Exception:
        return RuntimeError(f"{type(err).__name__}: {err}")


def agree(comm: MPI.Comm, local: bool, run: Callable[[], T], *, ignore=("seconds",)) -> T:
    """``run()`` on every rank; with ``local`` (redundant solves), rank 0's outcome on all
    (module docstring). Fields named in ``ignore`` (wall times) are not compared."""
    if not local or comm.size == 1 or _alone:
        return run()
    try:
        out, err = run(), None
    except Exception as e:  # rank 0's error is raised everywhere below
        out, err = None, e
    failed = comm.bcast(err is not None, root=0)
    if failed:
        err = comm.bcast(_portable(err) if comm.rank == 0 else None, root=0)
        raise err
    mine = b"" if err is not None else _digest(_without(out, ignore))
    if len(set(comm.allgather(mine))) > 1:
        global differed
        differed += 1
        rank0(
            logger,
            comm,
            "rank-local solves differ between ranks: rank 0's values taken",
            level=logging.DEBUG,
        )
        out = comm.bcast(out if comm.rank == 0 else None, root=0)
    return out


def _without(value, ignore):
    """``value`` with the ``ignore`` fields blanked (a shallow copy; lists element-wise)."""
    if isinstance(value, list):
        return [_without(v, ignore) for v in value]
    if not hasattr(value, "__dict__"):
        return value
    clone = object.__new__(type(value))
    clone.__dict__.update({k: (None if k in ignore else v) for k, v in vars(value).items()})
    return clone


_alone = False
"""Inside :func:`independent`: the ranks run different things, nothing is agreed or spread."""


@contextlib.contextmanager
def independent(fm, comm: MPI.Comm | None = None) -> Iterator[None]:
    """Let the ranks run different things (no agreement after a run, no nested spread: the
    ranks' runs are not the same run); ``fm``'s moduli are restored after, and the warm starts
    its runs and its scouts' stored are then those stored before, followed by those every
    rank stored here, in rank order (the last :data:`~.warm_start.KEEP` / size of each rank's
    per model), gathered over ``comm`` (None: all forgotten), so that the ranks compute alike
    again."""
    global _alone
    vals, _alone = fm.values(), True
    models = _with_scouts(fm)
    before = [warm_start.snapshot(m) for m in models]
    ok = False
    try:
        yield
        ok = True
    finally:
        _alone = False
        share = max(1, warm_start.KEEP // (comm.size if comm is not None else 1))
        mine = [warm_start.export(m, mark)[-share:] for m, (_, mark) in zip(models, before)]
        if len(_with_scouts(fm)) != len(models):
            mine = [[] for _ in models]  # a scout built here: not on every rank
        every = comm.allgather(mine) if comm is not None and ok else None
        for m in _with_scouts(fm):
            warm_start.forget(m)
        for k, m in enumerate(models if every is not None else []):
            warm_start.adopt(m, before[k][0] + [run for part in every for run in part[k]])
        fm.set_values(vals)


def not_alone(what: str) -> None:
    """Refuse to build ``what`` (a forward model: its construction is collective) on one rank
    inside :func:`independent`, where the other ranks run other things: a clear error on
    every rank (:func:`spread` raises it everywhere) instead of a deadlock."""
    if _alone:
        raise RuntimeError(
            f"{what} cannot be built inside evaluations shared among the ranks (its "
            "construction is collective): build it before sharing them"
        )


def _with_scouts(fm) -> list:
    """Every ForwardModel of ``fm`` and of its coarse copies."""
    out, todo = [], [fm]
    while todo:
        f = todo.pop()
        if f is None:
            continue
        out += list(getattr(f, "models", [f]))
        todo += [getattr(m, "_coarse", None) for m in [f, *getattr(f, "models", [])]]
    return out


def spread(fm, items: list, evaluate: Callable[[object], T]) -> list[T]:
    """``[evaluate(x) for x in items]``, the items shared among the ranks when every model of
    ``fm`` solves rank-local (rank r evaluates items r, r + size, …; the values are then
    gathered on every rank, in order; inside another spread, one rank's share, they run in
    turn; fewer items than ranks are evaluated on every rank). An error in any evaluation is
    raised on every rank (the first item's that failed)."""
    comm = getattr(fm, "comm", MPI.COMM_SELF)
    models = list(getattr(fm, "models", [fm]))
    if (
        comm.size == 1
        or _alone
        or len(items) < comm.size
        or not all(getattr(m, "local", False) for m in models)
    ):
        # one rank, distributed, already spread, or too few items to keep every rank busy
        # (each is then evaluated on every rank, and may share its own inner trials)
        return [evaluate(x) for x in items]
    mine: dict[int, tuple] = {}
    with independent(fm, comm):
        for i in range(comm.rank, len(items), comm.size):
            try:
                mine[i] = (evaluate(items[i]), None)
            except Exception as e:  # raised on every rank below
                mine[i] = (None, _portable(e))
                break
    done = {i: v for part in comm.allgather(mine) for i, v in part.items()}
    failed = sorted(i for i, (_, e) in done.items() if e is not None)
    if failed:
        raise done[failed[0]][1]
    return [done[i][0] for i in range(len(items))]
