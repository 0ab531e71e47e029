"""SIGINT and SIGTERM (what ``mpirun`` sends every rank on a Ctrl-C) during a command: the
handler that ends the process at once with status 130 (:func:`interruptible`), and the clean-up
it runs first, without any MPI call (:func:`interrupted`): the open output directory published
with its report, or removed. No exception unwinds through code that may call MPI, which could
wait forever for a rank that has already stopped.

Imported when a command starts (:func:`fabricsurf.cli.main`), not with :mod:`fabricsurf.cli`:
it imports the output directories (:mod:`fabricsurf.cli.outdir`), and with them the library.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import sys
import threading
import time
from collections.abc import Iterator

from mpi4py import MPI

from fabricsurf.cli.outdir import OPEN_DIRS, OutputDir, publish
from fabricsurf.errors import InputError


@contextlib.contextmanager
def interruptible(command: str) -> Iterator[None]:
    """SIGINT and SIGTERM end this process at once (status 130), after
    :func:`interrupted` cleaned up: no exception unwinds through code
    that may call MPI, which could wait forever for a rank that has already stopped. The
    previous handlers are restored on exit.

    gmsh's Python module sets SIGINT to its default action when imported and, in every
    ``gmsh.finalize()``, back to the handler it found then (``gmsh.oldsig``): after the first
    gmsh mesh, a Ctrl-C of a serial run (mpirun sends SIGTERM instead) raised
    KeyboardInterrupt with a traceback. It is imported first here and told to restore this
    handler."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.getsignal(s) for s in signals}
    try:
        import gmsh
    except (ImportError, OSError):  # no gmsh (or no libgmsh): nothing resets the handler
        gmsh = None
    saved = getattr(gmsh, "oldsig", None)
    prefix = "fabricsurf" + (f" {command}" if command else "")

    def handler(signum, frame):
        for s in signals:
            signal.signal(s, signal.SIG_IGN)
        msg = interrupted(signal.Signals(signum).name)
        if msg:  # on stderr: the handler may have cut a write to stdout (a progress line)
            os.write(2, f"{prefix}: {msg}\n".encode())
        sys.stderr.flush()
        os._exit(130)

    for s in signals:
        signal.signal(s, handler)
    if gmsh is not None:
        gmsh.oldsig = handler
    try:
        yield
    finally:
        if gmsh is not None:
            gmsh.oldsig = saved
        for s, h in previous.items():
            signal.signal(s, h)


INTERRUPT_WAIT = 0.8
"""Seconds a rank waits for the one cleaning up after an interrupt (mpirun kills at 1 s)."""


def interrupted(signame: str) -> str | None:
    """Clean up after SIGINT or SIGTERM, from the signal handler, without any MPI call (the
    ranks may be anywhere, some blocked in a collective call another has left): the rank that
    claims the open OutputDir's staging directory (renames it, which only one can do)
    publishes it (``keep_on_error``, after its ``on_interrupt`` report) or removes it, and gets
    the message; the others wait for it to finish and get None. With no OutputDir open, rank 0
    gets the message."""
    if not OPEN_DIRS:
        return f"interrupted by {signame}" if MPI.COMM_WORLD.rank == 0 else None
    od = OPEN_DIRS[-1]
    try:
        return _claim_and_clean(od, signame)
    finally:  # rank 0, after the claiming rank is done (or the wait is over)
        od.unlock()


def _claim_and_clean(od: OutputDir, signame: str) -> str | None:
    claimed = od.stage.with_name(od.stage.name + ".interrupted")
    try:
        os.rename(od.stage, claimed)  # atomic: one rank only succeeds
    except OSError:
        t0 = time.monotonic()
        while claimed.exists() and time.monotonic() - t0 < INTERRUPT_WAIT:
            time.sleep(0.01)
        return None
    for tmp in claimed.rglob("*.tmp"):  # a write the signal cut short (written, then renamed)
        tmp.unlink(missing_ok=True)
    try:
        if od.keep:
            note = od.on_interrupt(claimed) if od.on_interrupt else ""
            publish(claimed, od.out)
            return f"interrupted by {signame}{note}"
        shutil.rmtree(claimed, ignore_errors=True)
        return f"interrupted by {signame}; nothing was published to {od.out}"
    except (InputError, OSError) as e:
        return f"interrupted by {signame}; {e}"
    finally:  # rank 0, which holds the lock, may be stuck in MPI and never run its handler
        od.lock_path.unlink(missing_ok=True)
