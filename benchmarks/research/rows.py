"""The rows of the calibration benchmarks as JSON files: read back for ``--table``, and written
on rank 0 after every row so a long run can be stopped without losing what it measured."""

from __future__ import annotations

import json

from mpi4py import MPI


def read_rows(names: list[str]) -> list[dict]:
    """The rows of every JSON file of ``names``, in order."""
    rows = []
    for name in names:
        with open(name) as f:
            rows += json.load(f)
    return rows


def save_rows(path: str | None, rows: list[dict], comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """``rows`` to ``path`` (rank 0; nothing without a path)."""
    if path and comm.rank == 0:
        with open(path, "w") as f:
            json.dump(rows, f, indent=1)
