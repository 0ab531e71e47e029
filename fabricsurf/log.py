"""The package's messages: one channel, the standard :mod:`logging` (as dolfinx and
fenicsx-pulse do).

**In the library.** Every module that reports has ``logger = logging.getLogger(__name__)`` (a
child of the ``fabricsurf`` logger) and reports through :func:`rank0` (progress, notes, detail)
or :func:`warn` (warnings), never ``print`` or ``warnings.warn`` (tests/test_layout.py). Both
say a message on rank 0 of the communicator the work runs on; the other ranks say nothing.
The levels:

* DEBUG: detail (a load step's increment cut, a digest that differed between ranks);
* :data:`PROGRESS` (25): progress of long runs and notes (load steps, fit iterations, the
  stages of a diagnosis, the mesh a bias test got);
* WARNING: something the user should act on (a mesh that may lock, a mesh coarser than the
  tools, a near-mechanism): :func:`warn`, once per message;
* ERROR: the command line's last message when it fails.

PROGRESS sits between INFO and WARNING, so that it survives the ``logging.disable(
logging.INFO)`` with which the command line keeps the JIT compiler quiet.

**No configuration at import.** The package adds no handler, sets no level and leaves
propagation on: its messages reach whatever logging the application configured (pytest's
``caplog`` included). A library user turns progress on with, e.g.,
``logging.basicConfig(level=PROGRESS, format="%(message)s")`` (INFO would also show the JIT
compiler's messages), or takes the command line's terminal output with :func:`configure`.
Without either, warnings only are shown (on standard error: by FFCx's root handler once it is
imported, else by Python's last resort).

**Programs.** The command line, the demos and the benchmarks call :func:`configure`: a handler
on rank 0 that writes every message to the current ``sys.stdout`` and flushes it (so it
reaches the terminal when it is written, under ``mpirun`` too, whose pipe would otherwise hold
it), at DEBUG (``-v``), PROGRESS (default) or WARNING (``-q``). While it is in force the
configured loggers do not propagate: FFCx calls ``logging.basicConfig()`` when it is imported,
so every FEniCSx program has a handler on the root logger, which would write each message a
second time (on standard error, as ``WARNING:fabricsurf…:``). :meth:`Configuration.undo` (or
leaving its ``with`` block) puts everything back.

**Nesting.** Inside :func:`detail` the progress messages of the work called are logged at
DEBUG (the load steps of each run of a convergence study are detail of the study); inside
:func:`muted` nothing is said (the ranks other than 0 while each solves the same rank-local
model: fabricsurf/inverse/forward/ranks.py). Both hold for the calling context only and
change no logger's level.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import sys
from collections.abc import Iterable, Iterator

PROGRESS = 25
"""The level of progress messages (load steps, fit iterations, stages of a diagnosis)."""
logging.addLevelName(PROGRESS, "PROGRESS")

PACKAGE = "fabricsurf"
"""The package's logger, parent of every module's."""

_NORMAL, _DETAIL, _MUTED = 0, 1, 2
_state: contextvars.ContextVar[int] = contextvars.ContextVar("fabricsurf_log", default=_NORMAL)
_warned: set[tuple[str, str]] = set()


def rank0(log: logging.Logger, comm, msg: str, *args, level: int = PROGRESS) -> None:
    """Log ``msg`` (``%``-formatted with ``args``, if any, as :mod:`logging` does) to ``log`` at
    ``level`` on rank 0 of ``comm``; the other ranks say nothing. Inside :func:`detail` a
    PROGRESS message is logged at DEBUG; inside :func:`muted`, not at all."""
    if comm.rank != 0:
        return
    state = _state.get()
    if state == _MUTED:
        return
    if state == _DETAIL and level == PROGRESS:
        level = logging.DEBUG
    log.log(level, msg, *args, stacklevel=2)


def warn(log: logging.Logger, comm, msg: str) -> None:
    """A warning: logged to ``log`` at WARNING on rank 0 of ``comm``, once per message and
    logger (as Python shows a warning once per place) until :func:`configure` starts a new
    run; the other ranks say nothing. :func:`detail` does not lower it."""
    if comm.rank != 0 or _state.get() == _MUTED or (log.name, msg) in _warned:
        return
    _warned.add((log.name, msg))
    log.warning(msg, stacklevel=2)


def forget_warnings() -> None:
    """Let every warning be said again (the test suite calls it before each test)."""
    _warned.clear()


@contextlib.contextmanager
def _within(state: int) -> Iterator[None]:
    token = _state.set(max(state, _state.get()))
    try:
        yield
    finally:
        _state.reset(token)


def detail(on: bool = True) -> contextlib.AbstractContextManager[None]:
    """While in force (if ``on``), progress messages of the calling context are logged at DEBUG:
    the work called is detail of the caller's, which reports its own progress."""
    return _within(_DETAIL if on else _NORMAL)


def muted(on: bool = True) -> contextlib.AbstractContextManager[None]:
    """While in force (if ``on``), :func:`rank0` and :func:`warn` say nothing in the calling
    context."""
    return _within(_MUTED if on else _NORMAL)


class StdoutHandler(logging.StreamHandler):
    """A handler on whatever ``sys.stdout`` is when a message is written (so that pytest's
    capture or ``contextlib.redirect_stdout`` see it), flushed after every message."""

    def __init__(self) -> None:
        super().__init__(sys.stdout)

    @property
    def stream(self):
        return sys.stdout

    @stream.setter
    def stream(self, value) -> None:  # StreamHandler.__init__ assigns it; the property wins
        pass


class TerminalFormatter(logging.Formatter):
    """The message as it is; a warning with ``warning: `` before each of its lines."""

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        if logging.WARNING <= record.levelno < logging.ERROR:
            text = "\n".join(f"warning: {line}" for line in text.split("\n"))
        return text


class Configuration:
    """What :func:`configure` changed, and how to put it back (:meth:`undo`, or leave the
    ``with`` block)."""

    def __init__(self, level: int, comm, names: Iterable[str]) -> None:
        if comm is None:
            from mpi4py import MPI

            comm = MPI.COMM_WORLD
        self.handler: logging.Handler = StdoutHandler() if comm.rank == 0 else logging.NullHandler()
        self.handler.setFormatter(TerminalFormatter("%(message)s"))
        self.handler._fabricsurf_terminal = True
        self.saved = []
        for name in dict.fromkeys(names):
            lg = logging.getLogger(name)
            self.saved.append((lg, lg.level, list(lg.handlers), lg.propagate))
            for h in list(lg.handlers):  # an earlier configuration's: replaced, not stacked
                if getattr(h, "_fabricsurf_terminal", False):
                    lg.removeHandler(h)
            lg.addHandler(self.handler)
            lg.setLevel(level)
            lg.propagate = False  # FFCx's root handler (module docstring) would repeat them
        self.warned = set(_warned)
        _warned.clear()

    def undo(self) -> None:
        """Remove the handler, restore the loggers' levels, handlers and propagation as they
        were."""
        for lg, level, handlers, propagate in reversed(self.saved):
            for h in list(lg.handlers):
                if h not in handlers:
                    lg.removeHandler(h)
            for h in handlers:
                if h not in lg.handlers:
                    lg.addHandler(h)
            lg.setLevel(level)
            lg.propagate = propagate
        self.saved = []
        _warned.clear()
        _warned.update(self.warned)

    def __enter__(self) -> Configuration:
        return self

    def __exit__(self, *exc) -> None:
        self.undo()


def configure(
    level: int = PROGRESS, comm=None, names: Iterable[str] = (PACKAGE, "__main__")
) -> Configuration:
    """The terminal output of a program (the command line, a demo, a benchmark): on rank 0 of
    ``comm`` (default ``MPI.COMM_WORLD``) a handler that writes each message of the loggers
    ``names`` (the package's and the running script's) at ``level`` or above to the current
    ``sys.stdout`` and flushes it, warnings as ``warning: …``; on the other ranks a handler that
    drops them (nothing reaches Python's last-resort output). The loggers' levels are set to
    ``level`` and they stop propagating (module docstring: FFCx's root handler). A handler of
    an earlier call is replaced, not stacked.
    Returns the :class:`Configuration`, whose :meth:`~Configuration.undo` (or the end of its
    ``with`` block) restores everything."""
    return Configuration(level, comm, names)


def level_of(verbose: bool = False, quiet: bool = False) -> int:
    """The level of a program's ``-v`` (DEBUG), default (PROGRESS) and ``-q`` (WARNING)."""
    return logging.DEBUG if verbose else logging.WARNING if quiet else PROGRESS
