"""One output directory belongs to one run (:mod:`fabricsurf.cli.outdir`, docs/usage.md
"Output directories"): the lock beside OUT against a concurrent run, the clean-up of staging
directories a killed run left, the record of the files a publish wrote (so the next publish
removes an earlier run's results), what is in OUT that no run recorded (the user's files,
which a run refuses to replace), and names beside OUT that fit NAME_MAX however long OUT's
name is."""

from __future__ import annotations

import fcntl
import glob
import hashlib
import json
import os
import shutil
import socket
from pathlib import Path

from fabricsurf.errors import InputError

MANIFEST = ".fabricsurf-run.json"
"""The record, in OUT, of the files its last publish wrote."""
SHORT_NAME_BYTES = 100


def short_name(name: str) -> str:
    """``name``, or when longer than SHORT_NAME_BYTES bytes its first 40 bytes and a hash: the
    stem of the lock and staging names beside OUT, which add up to 30 bytes to it."""
    raw = name.encode()
    if len(raw) <= SHORT_NAME_BYTES:
        return name
    return raw[:40].decode(errors="ignore") + "-" + hashlib.sha256(raw).hexdigest()[:16]


def take_lock(path: Path, out: Path) -> int:
    """An exclusive ``flock`` on ``path`` (created if missing), holding this process's PID;
    refused, naming the holder, while another run holds it. The kernel releases the lock of a
    process that dies, so a stale lock file is simply taken over."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "another process"
            os.close(fd)
            raise InputError(
                f"--out {out}: another fabricsurf run ({holder}) is writing to "
                "this directory; wait for it to end, or give another --out"
            ) from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:  # its holder removed it just before we locked it
            same = False
        if same:
            break
        os.close(fd)
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"PID {os.getpid()} on {socket.gethostname()}".encode(), 0)
    return fd


def release_lock(lock: tuple[int, Path] | None) -> None:
    """Remove the lock file (while still held: no other run locks a removed file), unless it
    is already another run's, then unlock."""
    if lock is None:
        return
    fd, path = lock
    try:
        if os.stat(path).st_ino == os.fstat(fd).st_ino:
            path.unlink()
    except FileNotFoundError:
        pass
    os.close(fd)


def remove_stale_stages(parent: Path, short: str) -> None:
    """Staging directories of OUT that outlived their run (killed): with the lock held, none
    belongs to a live run."""
    for stale in parent.glob(f".{glob.escape(short)}.partial-*"):
        shutil.rmtree(stale, ignore_errors=True)


def recorded(out: Path) -> list[Path]:
    """The files OUT's last publish recorded (:data:`MANIFEST`), those inside OUT only."""
    try:
        names = json.loads((out / MANIFEST).read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return []
    real = out.resolve()
    found = []
    for n in names if isinstance(names, list) else []:
        p = out / str(n)
        if p.is_file() and not p.is_symlink() and p.resolve().is_relative_to(real):
            found.append(p)
    return found


def unrecorded(out: Path, names) -> list[str]:
    """The ``names`` (relative to OUT) that are in OUT, as a file or a symbolic link, although
    OUT's record does not list them: files a run did not write (the user's own, or results of
    a version before the record), which a run must not replace (docs/usage.md)."""
    if not out.is_dir():
        return []
    mine = {str(p.relative_to(out)) for p in recorded(out)}
    return [
        n for n in names if n not in mine and os.path.lexists(out / n) and not (out / n).is_dir()
    ]


def unrecorded_message(out: Path, names: list[str]) -> str:
    """What :func:`unrecorded` found, for a message that goes on with the remedy."""
    more = f" (and {len(names) - 1} more: {', '.join(names[1:4])}{'…' if len(names) > 4 else ''})"
    return (
        f"{out / names[0]}{more if len(names) > 1 else ''} is not the result of a fabricsurf "
        f"run (the record {MANIFEST} does not list it) and this run writes a file of that "
        "name"
    )
