"""The ``fabricsurf`` logger: progress of long runs and notes, written on rank 0.

Library code reports through :func:`rank0_print` (or ``logger``), never ``print``. Progress is
logged at :data:`PROGRESS`, between INFO and WARNING, so that it survives the
``logging.disable(logging.INFO)`` that keeps the JIT compiler quiet
(:func:`fabricsurf.cli.compiler_messages`). By default the messages go to the current
``sys.stdout``, one flushed write per message, so they reach the terminal when they are written,
under ``mpirun`` too. A library user silences them with
``logging.getLogger("fabricsurf").setLevel(logging.WARNING)`` (the command line's ``--quiet``)
or sends them elsewhere by replacing the logger's handlers (:func:`use_handler`).
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Iterator

PROGRESS = 25
"""The level of progress messages (load steps, fit iterations, stages of a diagnosis)."""
logging.addLevelName(PROGRESS, "PROGRESS")

logger = logging.getLogger("fabricsurf")


class StdoutHandler(logging.StreamHandler):
    """A handler on whatever ``sys.stdout`` is when a message is written (so that pytest's
    capture or ``contextlib.redirect_stdout`` see it), flushed after every message."""

    def __init__(self) -> None:
        super().__init__(sys.stdout)
        self.setFormatter(logging.Formatter("%(message)s"))

    @property
    def stream(self):
        return sys.stdout

    @stream.setter
    def stream(self, value) -> None:  # StreamHandler.__init__ assigns it; the property wins
        pass


def use_handler(handler: logging.Handler) -> None:
    """Send fabricsurf's messages to ``handler`` only (instead of standard output)."""
    for h in list(logger.handlers):
        logger.removeHandler(h)
    logger.addHandler(handler)


if not logger.handlers:
    logger.addHandler(StdoutHandler())
    logger.setLevel(PROGRESS)
    logger.propagate = False


def rank0_print(comm, *args, level: int = PROGRESS) -> None:
    """Log ``args`` (joined by spaces, as ``print`` does) at ``level`` on rank 0 of ``comm``;
    the other ranks say nothing."""
    if comm.rank == 0:
        logger.log(level, " ".join(str(a) for a in args))


@contextlib.contextmanager
def progress(show: bool) -> Iterator[None]:
    """Show progress messages (``show``) or only warnings and errors, then restore the level."""
    level = logger.level
    logger.setLevel(PROGRESS if show else logging.WARNING)
    try:
        yield
    finally:
        logger.setLevel(level)
