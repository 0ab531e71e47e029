"""Hardening, fourth round (issue 52): the process around a run. Its environment
(FABRICSURF_LOCAL_CELLS, a HOME under a file) is checked on every rank before computing; a
Ctrl-C of a serial run gives one line and status 130 also after a gmsh mesh; the package's
warnings print as one line ``warning: …``; a file in --out that no run wrote is not replaced;
number lists beginning with '-' reach the options' own checks.

``CASES`` (command lines) join those of tests/test_hardening.py in docs/input_errors.md.
``ENV_CASES`` are the same kind of case with an ``env`` of variables to set while it runs
(the table of docs/input_errors.md lists them too).
"""

import json
import logging
import os
import re
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import test_hardening as th
from mpi4py import MPI

import fabricsurf.cli as cli
import fabricsurf.log as flog
from fabricsurf.cli.outdir import MANIFEST, OutputDir
from fabricsurf.discretise.output import write_json
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.data import write_experiment

COMM = MPI.COMM_WORLD
TERMS = th.TERMS
BIAS = ["bias", "--length", "40", "--width", "20", "--h", "10", "--steps", "1", "--terms", TERMS]


def users_files(name: str, *files: str):
    """A directory ``name`` holding files of the user's (no run recorded them)."""

    def make(base: Path) -> None:
        (base / name).mkdir()
        for f in files:
            (base / name / f).write_text("mine\n")

    return make


def a_file(base: Path) -> None:
    (base / "afile").write_text("not a directory\n")


CASES = [
    dict(
        id="grip-depths-negative",
        klass="`--grip-depths` with a negative depth (a value that "
        "begins with '-' is the option's value, not another option)",
        make=th.nothing,
        argv=th.dgn("--grip-depths", "-1,0"),
        pattern=r"--grip-depths -1,0: grip depths \[-1.0, 0.0\] must be one or more finite "
        r"depths ≥ 0 mm",
    ),
    dict(
        id="h-negative-exponent",
        klass="`--h` a negative number in exponent notation",
        make=th.nothing,
        argv=th.cmp("good", "--h", "-1e-3"),
        pattern=r"--h -0.001: must be a positive element size in mm",
    ),
    dict(
        id="out-users-files",
        klass="`--out` holding files of the user's that the run would write (no run recorded them)",
        make=users_files("mine", "summary.json", "force.png"),
        argv=[*BIAS, "--out", "mine"],
        pattern=r"--out mine: mine/force.png \(and 1 more: summary.json\) is not the result of "
        r"a fabricsurf run \(the record \.fabricsurf-run\.json does not list it\) and this run "
        r"writes a file of that name; move it elsewhere or give another --out",
    ),
]

ENV_CASES = [
    dict(
        id="local-cells-not-a-number",
        klass="`FABRICSURF_LOCAL_CELLS` not a number",
        make=th.nothing,
        env={"FABRICSURF_LOCAL_CELLS": "abc"},
        argv=th.cmp("good"),
        pattern=r"environment variable FABRICSURF_LOCAL_CELLS='abc': give a number of cells "
        r">= 0 \(0: solve every mesh distributed over the ranks; unset: 1000\)",
    ),
    dict(
        id="home-under-a-file",
        klass="`HOME` under a regular file",
        make=a_file,
        env={"HOME": "afile/x", "XDG_CACHE_HOME": None, "XDG_CONFIG_HOME": None},
        argv=th.cmp("good"),
        pattern=r"HOME=afile/x: afile is a file, not a directory, so the JIT compiler can "
        r"neither create its cache of compiled forms afile/x/\.cache/fenics nor read its "
        r"settings file afile/x/\.config/ffcx/ffcx_parameters\.json; set HOME to a directory "
        r"you can write to \(or XDG_CACHE_HOME and XDG_CONFIG_HOME\)",
    ),
]


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return th.shared_root(tmp_path_factory, "hardproc", CASES + ENV_CASES)


@pytest.fixture
def in_root(root, monkeypatch):
    monkeypatch.chdir(root)
    for name in ("XDG_CACHE_HOME", "XDG_CONFIG_HOME", "FABRICSURF_LOCAL_CELLS"):
        monkeypatch.delenv(name, raising=False)
    return root


@pytest.mark.parametrize("case", CASES + ENV_CASES, ids=[c["id"] for c in CASES + ENV_CASES])
def test_rejected_before_any_solve(case, in_root, capsys, monkeypatch):
    """Exit 2 on every rank, one message naming the option, file or variable, nothing built or
    written. (Before: "expected one argument" for -1,0 and -1e-3; the user's summary.json and
    force.png replaced; FABRICSURF_LOCAL_CELLS ignored serially and a traceback with MPI_ABORT
    on 2 ranks; "Not a directory: …/ffcx_parameters.json" at the first compilation.)"""
    for name, value in case.get("env", {}).items():
        if value is None:
            monkeypatch.delenv(name, raising=False)
        else:
            monkeypatch.setenv(name, value)
    msg = th.rejected_message(case, in_root, capsys, monkeypatch)
    assert len(msg.splitlines()) == 1, msg


def test_local_cells_is_an_input_error(monkeypatch):
    """The library's own check (rank-local solves) raises an InputError, which the command line
    turns into exit status 2, not a traceback."""
    from fabricsurf.inverse.forward import ranks as local

    monkeypatch.setenv(local.ENVIRONMENT, "-5")
    with pytest.raises(InputError, match=r"FABRICSURF_LOCAL_CELLS='-5'"):
        local.local_cells()


def test_number_lists_joined_to_their_option():
    """Only values that are numbers or lists of them, after an option that takes a value; an
    option without a value, a non-number and anything after "--" are left alone."""
    ap = cli.build_parser()
    argv = [
        "diagnose",
        "d",
        "--grip-depths",
        "-1,0",
        "--h",
        "-inf",
        "--steps",
        "-1, 2",
        "--out",
        "-x",
        "-q",
        "-1",
        "--",
        "--h",
        "-2",
    ]
    assert cli.numbers_joined(ap, argv) == [
        "diagnose",
        "d",
        "--grip-depths=-1,0",
        "--h=-inf",
        "--steps=-1, 2",
        "--out",
        "-x",
        "-q",
        "-1",
        "--",
        "--h",
        "-2",
    ]


# -- a file of the user's in --out ----------------------------------------------------------
def test_users_file_refused_before_computing(tmp_path):
    """A file the run names (``files``) that OUT holds and no run recorded: refused before
    any computation (no lock, no staging directory), the file untouched; a file an earlier
    run recorded is replaced as before."""
    base = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))
    out = base / "D"
    if COMM.rank == 0:
        out.mkdir()
        (out / "summary.json").write_text("mine")
    COMM.barrier()
    with pytest.raises(
        InputError,
        match=rf"--out {re.escape(str(out))}: {re.escape(str(out))}"
        r"/summary.json is not the result of a fabricsurf run .* move it "
        "elsewhere or give another --out",
    ):
        OutputDir(out, COMM, files=("summary.json", "bias.h5"))
    assert sorted(p.name for p in base.iterdir()) == ["D"]
    assert (out / "summary.json").read_text() == "mine"
    COMM.barrier()
    if COMM.rank == 0:
        (out / "summary.json").unlink()
    COMM.barrier()
    for run in (1, 2):  # the second run replaces the first one's summary.json
        with OutputDir(out, COMM, files=("summary.json",)) as stage:
            write_json(COMM, stage / "summary.json", {"run": run})
        COMM.barrier()
    assert json.loads((out / "summary.json").read_text()) == {"run": 2}


def test_users_file_not_named_in_advance_kept_at_publish(tmp_path):
    """A file the run writes without having named it (figures per experiment): the publish
    moves nothing, the user's file is unchanged, and the results are kept beside OUT, named,
    on every rank alike."""
    base = Path(COMM.bcast(str(tmp_path) if COMM.rank == 0 else None))
    out = base / "D"
    if COMM.rank == 0:
        out.mkdir()
        (out / "force.png").write_text("mine")
    COMM.barrier()
    with pytest.raises(
        InputError,
        match=r"D/force.png is not the result of a fabricsurf run .*"
        r"nothing was published, the results are in .*\.D\.unpublished-",
    ):
        with OutputDir(out, COMM) as stage:
            write_json(COMM, stage / "force.png", {"run": 1})
            write_json(COMM, stage / "misfit.json", {"run": 1})
    COMM.barrier()
    assert sorted(p.name for p in out.iterdir()) == ["force.png"]
    assert (out / "force.png").read_text() == "mine" and not (out / MANIFEST).exists()
    kept = [p for p in base.iterdir() if p.name.startswith(".D.unpublished-")]
    assert len(kept) == 1 and sorted(p.name for p in kept[0].iterdir()) == [
        "force.png",
        "misfit.json",
    ]


# -- warnings -----------------------------------------------------------------------------
TEXT = "hemisphere: h = 4 mm exceeds the die's clearance or lip (2, 2 mm)"


def _warn(args) -> int:
    """What a hemisphere plug-in built with h > clearance does, on every rank (its mesh is
    distributed), twice (a plug-in built again), and a warning of somebody else's."""
    flog.warn(logging.getLogger("fabricsurf.experiments.hemisphere"), COMM, TEXT)
    flog.warn(logging.getLogger("fabricsurf.experiments.hemisphere"), COMM, TEXT)
    warnings.warn("elsewhere", UserWarning, stacklevel=1)
    return 0


def test_package_warning_one_clean_line(capsys, monkeypatch):
    """Through the command line, the package's warning is one line ``warning: …``, once, on
    rank 0, with --quiet too; no ``WARNING:py.warnings:`` prefix, file, line or source line.
    Another module's warning still goes the way Python shows it (here: pytest's record)."""
    monkeypatch.setattr(cli, "cmd_terms", _warn)
    with pytest.warns(UserWarning) as record:
        rc, out = th.run_cli(["-q", "terms"], capsys)
    assert rc == 0 and out == f"warning: {TEXT}", out  # rank 0's; the others print nothing
    assert [str(w.message) for w in record] == ["elsewhere"]


# -- interrupts -----------------------------------------------------------------------------
def _gmsh_mesh(args) -> int:
    """A gmsh mesh (rank 0 meshes); the SIGINT handler in force after it is kept in
    ``_gmsh_mesh.seen``."""
    from fabricsurf.geometry.specimen import rectangle

    rectangle(10.0, 5.0, 2.5, COMM)
    _gmsh_mesh.seen = signal.getsignal(signal.SIGINT)
    return 0


def test_sigint_handler_kept_after_a_gmsh_mesh(capsys, monkeypatch):
    """gmsh.finalize() puts back the SIGINT handler gmsh found at import (Python's, which
    raises KeyboardInterrupt): inside a command the command line's own handler stays."""
    import gmsh

    monkeypatch.setattr(cli, "cmd_terms", _gmsh_mesh)
    before = signal.getsignal(signal.SIGINT), gmsh.oldsig
    assert th.run_cli(["terms"], capsys)[0] == 0
    assert _gmsh_mesh.seen is not signal.default_int_handler
    assert getattr(_gmsh_mesh.seen, "__qualname__", "").startswith("interruptible.")
    assert (signal.getsignal(signal.SIGINT), gmsh.oldsig) == before


@pytest.mark.skipif(COMM.size > 1, reason="starts a process of its own (serial session only)")
def test_serial_interrupt_after_a_gmsh_mesh_one_line(tmp_path):
    """Ctrl-C of a serial ``fit`` whose meshes gmsh makes (fibres at 30°/-60°: zone meshes):
    one line, status 130, no KeyboardInterrupt traceback, nothing published. (Before: about
    80 lines of traceback and no clean-up.)"""
    th.variant("zones", th.replace("experiment.toml", "[45.0, -45.0]", "[30.0, -60.0]"))(
        _good(tmp_path)
    )
    rc, out = th._interrupt(
        ["fit", "zones", "--terms", TERMS, "--h", "0.5", "--out", "D"],
        1,
        tmp_path,
        "fit iteration 1",
    )
    assert rc == 130 and "Traceback" not in out and "KeyboardInterrupt" not in out, out
    lines = [ln for ln in out.splitlines() if "interrupted" in ln]
    assert lines == ["fabricsurf fit: interrupted by SIGINT; nothing was published to D"], out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good", "zones"]


def _good(base: Path) -> Path:
    write_experiment(base / "good", th.good_experiment())
    return base


# -- HOME under a file, as a real process -----------------------------------------------------
@pytest.mark.skipif(COMM.size > 1, reason="starts a process of its own (serial session only)")
def test_home_under_a_file_refused_before_computing(tmp_path):
    """``HOME=FILE/x fabricsurf compare …``: status 2 and one line naming HOME, the cache
    directory and the remedy, before anything is computed or written. (Before: "[Errno 20] Not
    a directory: '…/.config/ffcx/ffcx_parameters.json'" at the first compilation.)"""
    _good(tmp_path)
    (tmp_path / "afile").write_text("x")
    home = tmp_path / "afile" / "x"
    env = {k: v for k, v in os.environ.items() if not k.startswith("XDG_")} | {"HOME": str(home)}
    p = subprocess.run(
        [sys.executable, "-m", "fabricsurf", "compare", "good", "--terms", TERMS, "--out", "D"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    out = (p.stdout + p.stderr).strip()
    assert p.returncode == 2 and len(out.splitlines()) == 1, out
    assert out.startswith(
        f"fabricsurf compare: error: HOME={home}: {tmp_path / 'afile'} is a "
        "file, not a directory, so the JIT compiler can neither create its "
        f"cache of compiled forms {home}/.cache/fenics"
    ), out
    assert sorted(q.name for q in tmp_path.iterdir()) == ["afile", "good"]
