"""Output directories of the command line: checked before any computation, written atomically.

Everything a command writes goes to a staging directory beside OUT (``.OUT.partial-…``); only when
the command ends (successfully, or with the converged part of a failed run) are the files moved
into OUT, one atomic rename each, after checking that none would replace a directory (or a file by
a directory): a publish moves everything or nothing. A command that fails before that leaves OUT
untouched; a publish that cannot be done keeps the staging directory, renamed
``.OUT.unpublished-…``, and names it.

``--out`` is checked first: its symbolic links are resolved (a dangling or looping link is
refused), and it must not be, contain or lie inside any input, so an input is never overwritten.

One output directory belongs to one run (:mod:`fabricsurf.cli.ownership`, docs/usage.md "Output
directories"): a lock beside OUT refuses a concurrent run before it computes; the staging
directories of a killed run are removed by the next; each publish records its files in OUT, and the
next one removes those of the earlier run it does not write itself; a file in OUT that no run
recorded (the user's) and that the run would write is refused, before any computation when the
command names it in ``files``, else at the publish, which then moves nothing; names beside OUT are
shortened with a hash when OUT's name is long.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

from mpi4py import MPI

from fabricsurf.cli.ownership import (
    MANIFEST,
    recorded,
    release_lock,
    remove_stale_stages,
    short_name,
    take_lock,
    unrecorded,
    unrecorded_message,
)
from fabricsurf.discretise.output import on_rank0
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.tables import broken_link


def _existing_ancestor(path: Path) -> Path:
    probe = path
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return probe


def _resolve(out: Path) -> Path:
    """``out`` with its symbolic links resolved; a dangling or looping link (``out`` itself or
    a directory on its way) is refused, naming the link."""
    probe = Path()
    for part in out.parts:
        probe = probe / part
        link = broken_link(probe)
        if link == "loops":
            raise InputError(
                f"--out {out}: {probe} is a symbolic link that loops (-> {os.readlink(probe)})"
            )
        if link:
            raise InputError(
                f"--out {out}: {probe} is a symbolic link to "
                f"{os.readlink(probe)}, which does not exist"
            )
    return out.resolve()


def _inputs_clash(out: Path, real: Path, inputs: tuple[tuple[str, Path], ...]) -> None:
    """--out must not be, contain or lie inside an input (``inputs``: (label, path) pairs)."""
    for label, path in inputs:
        p = Path(path).resolve()
        if real == p:
            why = "is"
        elif p.is_relative_to(real):
            why = "contains"
        elif real.is_relative_to(p):
            why = "lies inside"
        else:
            continue
        raise InputError(
            f"--out {out}: it {why} the input {label}; outputs must not "
            "overwrite or mix with the inputs: choose another directory"
        )


def _clash(dst: Path, will_be_dir: bool) -> str | None:
    """Why ``dst`` cannot be replaced by a file (or a directory), or None."""
    if dst.is_dir() and not will_be_dir:
        return f"{dst} is a directory where a file of the same name is to be written"
    if dst.exists() and not dst.is_dir() and will_be_dir:
        return f"{dst} is a file where a directory of the same name is to be written"
    return None


def _check(
    out: Path, files: tuple[str, ...], inputs: tuple[tuple[str, Path], ...] = ()
) -> tuple[str, tuple[int, Path]]:
    """Validate ``--out`` (before any computation), take its lock and create the staging
    directory; returns the staging directory and the lock."""
    real = _resolve(out)
    if real == real.parent:
        raise InputError(
            f"--out {out}: the root of the file system; give a directory of its own for the results"
        )
    _inputs_clash(out, real, inputs)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a directory")
    probe = _existing_ancestor(out.parent)
    if not probe.is_dir():
        raise InputError(f"--out {out}: {probe} is a file, not a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise InputError(f"--out {out}: {probe} is not writable")
    if out.is_dir() and not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"--out {out}: the directory is not writable")
    for name in files:
        why = _clash(out / name, will_be_dir=False)
        if why:
            raise InputError(f"--out {out}: {why}")
    found = unrecorded(out, files)
    if found:
        raise InputError(
            f"--out {out}: {unrecorded_message(out, found)}; move it elsewhere "
            "or give another --out"
        )
    # beside the real OUT (a rename cannot cross file systems), named as given when it is there
    parent = out.parent if out.parent.resolve() == real.parent else real.parent
    parent.mkdir(parents=True, exist_ok=True)
    short = short_name(real.name)
    try:
        lock = (take_lock(parent / f".{short}.lock", out), parent / f".{short}.lock")
    except OSError as e:
        raise InputError(f"--out {out}: cannot create files in {parent} ({e.strerror})") from None
    try:
        remove_stale_stages(parent, short)
        stage = tempfile.mkdtemp(prefix=f".{short}.partial-", dir=parent)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(stage, 0o777 & ~umask)  # mkdtemp's 0700 would otherwise become OUT's mode
    except BaseException:
        release_lock(lock)
        raise
    return stage, lock


def _refusal(stage: Path, out: Path, files: list[str]) -> str | None:
    """Why the staged results cannot be moved into OUT, or None: a directory where a file goes
    (or the reverse), or a file of OUT that no run recorded (:func:`unrecorded`)."""
    if not out.exists():
        return None
    for src in sorted(stage.rglob("*")):
        why = _clash(out / src.relative_to(stage), src.is_dir())
        if why:
            return why
    found = unrecorded(out, files)
    return unrecorded_message(out, found) if found else None


def publish(stage: Path, out: Path) -> None:
    """Move the staged files into OUT with their record (:data:`MANIFEST`), then remove the
    files the previous record names that this run did not write."""
    files = sorted(str(p.relative_to(stage)) for p in stage.rglob("*") if not p.is_dir())
    why = _refusal(stage, out, files)
    if why:  # kept under a name the next run's clean-up of stale stages leaves alone
        kept = stage.with_name(stage.name.replace(".partial-", ".unpublished-", 1))
        os.rename(stage, kept)
        raise InputError(f"--out {out}: {why}; nothing was published, the results are in {kept}")
    (stage / MANIFEST).write_text(
        json.dumps(
            {"files": files, "pid": os.getpid(), "time": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
        )
    )
    if not out.exists():
        os.replace(stage, out.resolve())
        return
    items = sorted(stage.rglob("*"))
    previous = recorded(out)
    for src in items:
        dst = out / src.relative_to(stage)
        if src.is_dir():
            dst.mkdir(parents=True, exist_ok=True)
        else:
            os.replace(src, dst)
    for old in previous:
        if str(old.relative_to(out)) not in files:
            old.unlink(missing_ok=True)
    shutil.rmtree(stage)


def _publish_whole(stage: Path, out: Path) -> None:
    """:func:`publish` with SIGINT and SIGTERM held until it is done (a few renames): an
    interrupt then ends the run after the publish, not half-way through it. Held by a
    handler that notes the signal and raises it again afterwards (blocking the signal
    would not do: another thread, e.g. MPI's, takes it and Python runs the handler anyway)."""
    if threading.current_thread() is not threading.main_thread():
        publish(stage, out)
        return
    pending: list[int] = []
    held = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.signal(s, lambda signum, frame: pending.append(signum)) for s in held}
    try:
        publish(stage, out)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if pending:
            signal.raise_signal(pending[0])


OPEN_DIRS: list[OutputDir] = []
"""The output directories being written (innermost last), for
:func:`~fabricsurf.cli.interrupts.interrupted`."""


class OutputDir:
    """``with OutputDir(out, comm) as stage:`` write into ``stage``; published on exit.

    ``files``: names the command will write, checked now (an existing directory of that name
    in OUT is an error before any computation). ``inputs``: (label, path) of every input
    (module docstring). ``keep_on_error``: publish what was written
    even when the body raises (failed runs keep their converged steps and the failure report);
    otherwise a failure discards it all. Collective: an exception on some ranks only is raised
    on the others too (same message), so every rank ends the same way. After SIGINT or SIGTERM,
    :func:`~.interrupts.interrupted` publishes or removes it (``on_interrupt(stage)``: writes a
    report there and returns what to add to the message); no staging directory outlives the run.
    """

    def __init__(
        self,
        out: str | Path,
        comm: MPI.Comm = MPI.COMM_WORLD,
        keep_on_error: bool = False,
        files: tuple[str, ...] = (),
        inputs: tuple[tuple[str, Path], ...] = (),
    ) -> None:
        self.out, self.comm, self.keep = Path(out), comm, keep_on_error
        self.on_interrupt: Callable[[Path], str] | None = None
        checked = on_rank0(comm, _check, self.out, tuple(files), tuple(inputs))
        self._lock = checked[1] if comm.rank == 0 else None
        stage, lock_path = comm.bcast(checked and (checked[0], str(checked[1][1])), root=0)
        self.stage, self.lock_path = Path(stage), Path(lock_path)

    def __enter__(self) -> Path:
        OPEN_DIRS.append(self)
        return self.stage

    def __exit__(self, exc_type, exc, tb) -> bool:
        OPEN_DIRS.remove(self)
        mine = None if exc is None else (isinstance(exc, InputError), str(exc))
        first = next((m for m in self.comm.allgather(mine) if m is not None), None)
        try:
            publish = first is None or self.keep
            if publish and first is not None:  # a failed run with nothing to keep: no empty OUT
                publish = self.comm.bcast(self.comm.rank > 0 or any(self.stage.iterdir()))
            if publish:
                on_rank0(self.comm, _publish_whole, self.stage, self.out)
            elif self.comm.rank == 0:
                shutil.rmtree(self.stage, ignore_errors=True)
        finally:
            self.unlock()
        if first is not None and exc is None:
            raise (InputError if first[0] else RuntimeError)(first[1])
        return False

    def unlock(self) -> None:
        """Release the run's lock beside OUT (rank 0 holds it; nothing on the other ranks)."""
        release_lock(self._lock)
        self._lock = None
