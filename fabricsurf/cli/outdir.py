"""Output directories of the command line: checked before any computation, written atomically.

Everything a command writes goes to a staging directory beside OUT (``.OUT.partial-…``); only
when the command ends (successfully, or with the converged part of a failed run) are the files
moved into OUT, one atomic rename each. A command that fails before that leaves OUT untouched.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

from fabricsurf.discretise.output import on_rank0
from fabricsurf.errors import InputError


def _check(out: Path) -> str:
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a directory")
    parent = out.parent if not out.exists() else out
    probe = parent
    while not probe.exists():
        probe = probe.parent
    if not os.access(probe, os.W_OK | os.X_OK):
        raise InputError(f"--out {out}: {probe} is not writable")
    out.parent.mkdir(parents=True, exist_ok=True)
    return tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent)


def _publish(stage: Path, out: Path) -> None:
    if not out.exists():
        os.replace(stage, out)
        return
    for src in sorted(stage.rglob("*")):
        dst = out / src.relative_to(stage)
        if src.is_dir():
            dst.mkdir(parents=True, exist_ok=True)
        else:
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dst)
    shutil.rmtree(stage)


class OutputDir:
    """``with OutputDir(out, comm) as stage:`` write into ``stage``; published on exit.

    ``keep_on_error``: publish what was written even when the body raises (failed runs keep
    their converged steps and the failure report); otherwise a failure discards it all.
    """

    def __init__(self, out: str | Path, comm: MPI.Comm = MPI.COMM_WORLD,
                 keep_on_error: bool = False) -> None:
        self.out, self.comm, self.keep = Path(out), comm, keep_on_error
        self.stage = Path(comm.bcast(on_rank0(comm, _check, self.out), root=0))

    def __enter__(self) -> Path:
        return self.stage

    def __exit__(self, exc_type, exc, tb) -> bool:
        self.comm.barrier()
        if exc_type is None or self.keep:
            on_rank0(self.comm, _publish, self.stage, self.out)
        elif self.comm.rank == 0:
            shutil.rmtree(self.stage, ignore_errors=True)
        return False
