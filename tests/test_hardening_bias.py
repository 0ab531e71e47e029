"""Hardening of the bias test's inputs: steep fibres at the default h, meshes coarser than
asked. Runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``.

±80° fibres at the default h were refused with a traceback (exit 1; MPI_ABORT under mpirun) by
a check that meshes coarser than the unsheared grip zones cannot resolve them, which
measurement disproved (docs/theory.md, "Steep fibres"): the check is gone and the run works,
as tested below, rather than being turned into a message.
"""

import re
from pathlib import Path

import pytest
from mpi4py import MPI
from test_hardening import good_experiment, run_cli, write_experiment

COMM = MPI.COMM_WORLD


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """A directory shared by all ranks with ``good`` (the 40 × 20 mm experiment of
    tests/test_hardening.py) and ``steep`` (the same at ±80°)."""
    base = COMM.bcast(str(tmp_path_factory.mktemp("hardbias")) if COMM.rank == 0 else None)
    base = Path(base)
    if COMM.rank == 0:
        write_experiment(base / "good", good_experiment())
        steep = good_experiment()
        steep.setup.fibre_angles_deg = (80.0, -80.0)
        write_experiment(base / "steep", steep)
    COMM.barrier()
    return base


def test_steep_fibres_at_the_default_h_are_computed(root, capsys, monkeypatch):
    """``compare`` on a 40 × 20 mm bias experiment with fibres at ±80°: default h = 2 mm,
    longer than the unsheared grip zones ((W/2) cot 80° = 1.76 mm). Was: ValueError traceback,
    exit 1. Now: exit 0 on every rank, no traceback, a misfit printed."""
    monkeypatch.chdir(root)
    text = (root / "steep" / "experiment.toml").read_text()
    assert re.search(r"fibre_angles_deg = \[80\.0, -80\.0\]", text), text
    rc, out = run_cli(
        ["compare", "steep", "--terms", "fibre_stretch,shear", "--out", "out"], capsys
    )
    assert rc == 0, out
    assert "Traceback" not in out and "combined misfit" in out, out
