"""Test configuration: per-rank pytest temporary directories under MPI, Agg backend."""

import os
import tempfile

import matplotlib

matplotlib.use("Agg")


def pytest_configure(config):
    """Under mpirun every rank runs pytest; give each its own basetemp so tmp_path never races.
    (Tests that need one shared directory broadcast rank 0's path.)"""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    if comm.size > 1 and not config.option.basetemp:
        base = os.path.join(tempfile.gettempdir(), f"pytest-mpi-{os.getpid()}-rank{comm.rank}")
        config.option.basetemp = base
