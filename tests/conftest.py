"""Test configuration: per-rank pytest temporary directories under MPI, Agg backend, and the
``serial`` marker."""

import os
import tempfile

import matplotlib
import pytest

matplotlib.use("Agg")


def pytest_configure(config):
    """Under mpirun every rank runs pytest; give each its own basetemp so tmp_path never races.
    (Tests that need one shared directory broadcast rank 0's path.)

    pytest-xdist's controller runs no test and does not initialise MPI: an MPI singleton sets
    OMPI_* variables in its process's environment, its worker processes would inherit them, and
    an ``mpirun`` that a test starts with that environment exits 1 without a word."""
    if getattr(config.option, "numprocesses", None) and "PYTEST_XDIST_WORKER" not in os.environ:
        return
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    if comm.size > 1 and not config.option.basetemp:
        base = os.path.join(tempfile.gettempdir(), f"pytest-mpi-{os.getpid()}-rank{comm.rank}")
        config.option.basetemp = base


def pytest_runtest_setup(item):
    """A test marked ``serial(reason)`` skips in the 2-rank session. The reason names where its
    parallel path is exercised: a heavy study whose parallel code is another test's need not
    spend the 2-rank session's minutes on the same path again."""
    from mpi4py import MPI

    mark = item.get_closest_marker("serial")
    if mark is not None and MPI.COMM_WORLD.size > 1:
        pytest.skip(f"serial session only: {mark.args[0]}")


@pytest.fixture(autouse=True)
def _warnings_said_again():
    """The package says each warning once per run (fabricsurf.log.warn); every test is a run
    of its own, as pytest shows Python's warnings again in each test."""
    from fabricsurf.log import forget_warnings

    forget_warnings()
