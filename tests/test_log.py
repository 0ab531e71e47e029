"""The ``fabricsurf`` logger (fabricsurf/log.py): progress reaches the terminal as it is written,
also through a pipe (as under mpirun), and a library user can silence or redirect it."""

import io
import logging
import subprocess
import sys
import time

import pytest
from mpi4py import MPI

from fabricsurf.log import PROGRESS, StdoutHandler, logger, progress, rank0_print, use_handler

COMM = MPI.COMM_WORLD


def test_progress_goes_to_the_current_stdout(capsys):
    rank0_print(COMM, "step", 1, "of", 3)
    out = capsys.readouterr().out
    assert out == ("step 1 of 3\n" if COMM.rank == 0 else "")


def test_quiet_keeps_errors_only(capsys):
    with progress(False):
        rank0_print(COMM, "a load step")
        rank0_print(COMM, "an error", level=logging.ERROR)
    rank0_print(COMM, "progress again")
    out = capsys.readouterr().out
    want = "an error\nprogress again\n" if COMM.rank == 0 else ""
    assert out == want, out


def test_a_handler_of_the_users_choice_replaces_stdout(capsys):
    stream = io.StringIO()
    mine = logging.StreamHandler(stream)
    try:
        use_handler(mine)
        rank0_print(COMM, "to my log")
    finally:
        use_handler(StdoutHandler())
    assert capsys.readouterr().out == ""
    assert stream.getvalue() == ("to my log\n" if COMM.rank == 0 else "")
    assert logger.level == PROGRESS


@pytest.mark.skipif(COMM.size > 1, reason="starts a process of its own (serial session only)")
def test_each_message_is_flushed_through_a_pipe():
    """A message is readable from the pipe while the process still runs (block-buffered
    stdout would hold it until exit, as the forming demo's did under mpirun)."""
    code = ("from mpi4py import MPI; from fabricsurf.log import rank0_print; import time\n"
            "rank0_print(MPI.COMM_SELF, 'first step done'); time.sleep(60)\n")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        t0 = time.perf_counter()
        line = p.stdout.readline()
        assert line == "first step done\n"
        assert time.perf_counter() - t0 < 30 and p.poll() is None
    finally:
        p.kill()
        p.wait()
