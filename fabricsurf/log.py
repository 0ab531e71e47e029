"""The ``fabricsurf`` logger: progress of long runs and notes, written on rank 0.

Library code reports through :func:`rank0_print` (or ``logger``), never ``print``. Progress is
logged at :data:`PROGRESS`, between INFO and WARNING, so that it survives the
``logging.disable(logging.INFO)`` that keeps the JIT compiler quiet
(:func:`fabricsurf.cli.compiler_messages`). By default the messages go to the current
``sys.stdout``, one flushed write per message, so they reach the terminal when they are written,
under ``mpirun`` too. A library user silences them with
``logging.getLogger("fabricsurf").setLevel(logging.WARNING)`` (the command line's ``--quiet``)
or sends them elsewhere by replacing the logger's handlers (:func:`use_handler`).

Warnings the package issues with ``warnings.warn`` (a mesh too coarse for the tools, a
near-mechanism) reach the same logger as one line ``warning: …`` on rank 0 while
:func:`package_warnings` is in force (the command line's); without it Python shows them its
own way.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import warnings
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


PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep
"""Warnings attributed to a file under this directory are the package's own."""


def ours(category: type[Warning], filename: str) -> bool:
    """Whether a warning is one the package issued: a UserWarning (what ``warnings.warn``
    gives by default; numpy's RuntimeWarnings and the libraries' DeprecationWarnings are
    not) attributed to a module of the package (``stacklevel=2`` names the package's caller)."""
    return issubclass(category, UserWarning) and os.path.abspath(filename).startswith(PACKAGE)


@contextlib.contextmanager
def package_warnings(rank: int) -> Iterator[None]:
    """The package's warnings (:func:`ours`) as one line ``warning: MESSAGE`` through the logger
    at WARNING (shown with --quiet too), on rank ``0`` only (every rank of a distributed mesh
    issues the same one); any other warning is shown as before. Python's filters still decide
    whether a warning is shown at all (by default once per message and place).

    FFCx, on import, routes every warning through the root logger
    (``logging.captureWarnings``), which prints it as ``WARNING:py.warnings:FILE:LINE:
    UserWarning: …`` with a line of source. Capturing is switched on here first, so that
    FFCx's call, when it comes, leaves this hook in place; on exit the previous state is back."""
    before = warnings.showwarning
    logging.captureWarnings(True)
    captured = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if not ours(category, filename):
            captured(message, category, filename, lineno, file, line)
        elif rank == 0:
            logger.warning(f"warning: {message}")

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = captured
        if captured is not before:
            logging.captureWarnings(False)
