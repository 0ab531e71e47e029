"""One channel for the package's messages (fabricsurf/log.py): module loggers under
``fabricsurf`` that the library never configures (no handler, no level, propagation on, so an
application's logging and pytest's ``caplog`` see them); :func:`~fabricsurf.log.rank0` and
:func:`~fabricsurf.log.warn` say a message on rank 0 only, a warning once; the command line and
the demos configure the terminal output with :func:`~fabricsurf.log.configure`, which
``main()`` removes again when it returns; ``-q`` hides progress, never warnings. Runs on 1 and
on 2 ranks."""

import importlib
import io
import logging
import pkgutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from mpi4py import MPI

import fabricsurf
import fabricsurf.cli as cli
import fabricsurf.geometry
from fabricsurf.cli import main
from fabricsurf.errors import InputError
from fabricsurf.log import (
    PROGRESS,
    configure,
    detail,
    muted,
    rank0,
    warn,
)

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[1]
log = logging.getLogger("fabricsurf.tests")
serial = pytest.mark.skipif(
    COMM.size > 1,
    reason="starts a process of its own, which cannot "
    "initialise MPI inside an mpirun rank (serial session only)",
)


def every_module() -> list[str]:
    """The names of every module of the package (fabricsurf.geometry included), but
    ``fabricsurf.__main__`` (which runs the command line)."""
    names = []
    for pkg, prefix in ((fabricsurf, "fabricsurf."), (fabricsurf.geometry, "fabricsurf.geometry.")):
        names += [
            m.name
            for m in pkgutil.walk_packages(pkg.__path__, prefix)
            if not m.name.endswith("__main__")
        ]
    return names


def configured(names=("fabricsurf", "__main__")) -> list:
    """Every package logger's handlers, level and propagation (and the script's logger's)."""
    loggers = [
        n
        for n, lg in logging.root.manager.loggerDict.items()
        if isinstance(lg, logging.Logger) and n.split(".")[0] == "fabricsurf"
    ]
    return [
        (
            n,
            list(logging.getLogger(n).handlers),
            logging.getLogger(n).level,
            logging.getLogger(n).propagate,
        )
        for n in sorted({*names, *loggers})
    ]


def test_no_handler_no_level_after_importing_every_module():
    """In the test session (and after every CLI run before this test): nothing configured."""
    for name in every_module():
        importlib.import_module(name)
    reporting = [n for n, *_ in configured() if n.startswith("fabricsurf.")]
    assert len(reporting) > 10, reporting  # the modules that report have their loggers
    for name, handlers, level, propagate in configured():
        assert handlers == [] and propagate, (name, handlers, propagate)
        assert level == logging.NOTSET or name == "fabricsurf.tests", (name, level)


@serial
def test_import_configures_nothing():
    """A fresh interpreter: ``import fabricsurf`` adds no handler anywhere and sets no level;
    nor does importing every module of the package (FEniCSx included)."""
    code = textwrap.dedent("""
        import importlib, logging, sys
        sys.path.insert(0, "tests")
        import fabricsurf
        lg = logging.getLogger("fabricsurf")
        assert not lg.handlers and lg.level == 0 and lg.propagate, (lg.handlers, lg.level)
        assert not logging.root.handlers, logging.root.handlers
        from test_logging import configured, every_module
        for name in every_module():
            importlib.import_module(name)
        bad = [c for c in configured() if c[1] or c[2] or not c[3]]
        assert not bad, bad
    """)
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_rank0_on_rank_0_only_and_propagated(caplog):
    """A progress message reaches the root logger's handlers (pytest's here) from rank 0 only,
    under its module's name, formatted lazily as logging does."""
    caplog.set_level(PROGRESS, logger="fabricsurf")
    rank0(log, COMM, "step %d of %d", 1, 3)
    rank0(log, COMM, "a detail", level=logging.DEBUG)  # below the level set: not created
    got = [(r.name, r.levelno, r.getMessage()) for r in caplog.records]
    assert got == ([("fabricsurf.tests", PROGRESS, "step 1 of 3")] if COMM.rank == 0 else [])
    assert logging.getLogger("fabricsurf").propagate


def test_an_application_s_logging_sees_the_messages():
    """``logging.basicConfig(level=logging.INFO)`` in an application (here its parts: a root
    handler and the root level) shows the package's progress, on rank 0."""
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    level = logging.root.level
    logging.root.addHandler(handler)
    logging.root.setLevel(logging.INFO)
    try:
        from fabricsurf.inverse.contract.checks import noise_keys

        rank0(logging.getLogger("fabricsurf.experiments.bias_extension"), COMM, "step 1/2")
        noise_keys({"noise_std": 0.01}, {"field": None})  # a warning of the loader
    finally:
        logging.root.removeHandler(handler)
        logging.root.setLevel(level)
    lines = stream.getvalue().splitlines()
    assert lines == (
        [
            "step 1/2",
            "experiment.toml: [data] noise_std is given but [data] field "
            "is not: the noise level is not used",
        ]
        if COMM.rank == 0
        else []
    ), lines


def test_a_warning_once_on_rank_0(capsys):
    """Every rank warns, three times: one line ``warning: …`` in all, on rank 0; a warning of
    several lines has the prefix on each."""
    with configure(PROGRESS, COMM):
        for _ in range(3):
            warn(log, COMM, "the mesh may lock")
        warn(log, COMM, "first line\nsecond line")
    out = capsys.readouterr()
    assert out.err == ""
    assert out.out == (
        "warning: the mesh may lock\nwarning: first line\nwarning: second line\n"
        if COMM.rank == 0
        else ""
    )
    assert sum(o.count("the mesh may lock") for o in COMM.allgather(out.out)) == 1


def test_configure_replaces_and_undo_restores(capsys):
    """A second configuration replaces the first's handler (not stacked); undoing it brings the
    first back, undoing that leaves the loggers as they were."""
    before = configured()
    with configure(PROGRESS, COMM):
        with configure(logging.WARNING, COMM):
            assert len(logging.getLogger("fabricsurf").handlers) == 1
            rank0(log, COMM, "hidden")
            warn(log, COMM, "shown")
        assert len(logging.getLogger("fabricsurf").handlers) == 1
        rank0(log, COMM, "progress again")
    assert configured() == before
    assert capsys.readouterr().out == ("warning: shown\nprogress again\n" if COMM.rank == 0 else "")


def test_detail_and_muted_change_no_level(caplog):
    """Inside detail() progress is DEBUG (warnings stay warnings), inside muted() nothing is
    said; neither changes a logger's level (ranks.one_voice is muted)."""
    from fabricsurf.inverse.forward import ranks

    caplog.set_level(logging.DEBUG, logger="fabricsurf")
    with detail():
        rank0(log, COMM, "a load step")
        warn(log, COMM, "still a warning")
    with muted():
        rank0(log, COMM, "nothing")
        warn(log, COMM, "nothing either")
    with ranks.one_voice(COMM, local=True):
        assert logging.getLogger("fabricsurf").level == logging.DEBUG
        rank0(log, COMM, "one voice")
    got = [(r.levelno, r.getMessage()) for r in caplog.records]
    want = [
        (logging.DEBUG, "a load step"),
        (logging.WARNING, "still a warning"),
        (PROGRESS, "one voice"),
    ]
    assert got == (want if COMM.rank == 0 else []), got


def _says(args) -> int:
    rank0(logging.getLogger("fabricsurf.experiments.bias_extension"), COMM, "a load step")
    rank0(logging.getLogger("fabricsurf.discretise.stepping"), COMM, "a cut", level=logging.DEBUG)
    warn(logging.getLogger("fabricsurf.experiments.hemisphere"), COMM, "a coarse mesh")
    return 0


def _fails(args) -> int:
    rank0(log, COMM, "before the error")
    raise InputError("no such file")


def run(argv, capsys) -> tuple[int, str]:
    rc = main(argv)
    out = capsys.readouterr()
    if COMM.rank > 0:
        assert out.out + out.err == "", out
    return rc, out.out


@pytest.mark.parametrize(
    "flags, want",
    [
        ([], "a load step\nwarning: a coarse mesh\n"),
        (["-q"], "warning: a coarse mesh\n"),
        (["-v"], "a load step\na cut\nwarning: a coarse mesh\n"),
        (["--quiet"], "warning: a coarse mesh\n"),
    ],
)
def test_quiet_hides_progress_never_warnings(flags, want, capsys, monkeypatch):
    monkeypatch.setattr(cli, "cmd_terms", _says)
    rc, out = run([*flags, "terms"], capsys)
    assert rc == 0 and out == (want if COMM.rank == 0 else "")
    rc, out = run(["terms", *flags], capsys)  # after the command as well
    assert rc == 0 and out == (want if COMM.rank == 0 else "")


def test_main_leaves_no_configuration(capsys, monkeypatch):
    """Run after run, in one process: the messages are configured while a command runs (its
    error message included) and removed when main() returns; the handlers are not stacked."""
    before = configured(), logging.root.manager.disable
    monkeypatch.setattr(cli, "cmd_terms", _says)
    for _ in range(3):
        assert run(["terms"], capsys) == (
            0,
            "a load step\nwarning: a coarse mesh\n" if COMM.rank == 0 else "",
        )
        assert (configured(), logging.root.manager.disable) == before
    monkeypatch.setattr(cli, "cmd_terms", _fails)
    rc, out = run(["-q", "terms"], capsys)
    assert rc == 2 and out == ("fabricsurf terms: error: no such file\n" if COMM.rank == 0 else "")
    assert (configured(), logging.root.manager.disable) == before


def test_each_message_once_beside_a_root_handler(capsys, monkeypatch):
    """FFCx calls logging.basicConfig() when imported: every FEniCSx program has a handler on
    the root logger. While the command runs its messages go to standard output only, not a
    second time through that handler; afterwards they propagate to it again."""
    stream = io.StringIO()
    root = logging.StreamHandler(stream)
    logging.root.addHandler(root)
    monkeypatch.setattr(cli, "cmd_terms", _says)
    try:
        rc, out = run(["terms"], capsys)
        assert stream.getvalue() == ""
        warn(log, COMM, "after the command")
    finally:
        logging.root.removeHandler(root)
    assert rc == 0 and out == ("a load step\nwarning: a coarse mesh\n" if COMM.rank == 0 else "")
    assert stream.getvalue() == ("after the command\n" if COMM.rank == 0 else "")


# -- programs: a demo, and the terminal under a pipe ----------------------------------------
DEMO = textwrap.dedent("""
    import logging
    from mpi4py import MPI
    from fabricsurf.cli.demo import demo_parser, parse
    from fabricsurf.log import rank0, warn
    args = parse(demo_parser("a demo", "out/x"))
    logger = logging.getLogger(__name__)
    rank0(logger, MPI.COMM_WORLD, "the demo's result")
    rank0(logging.getLogger("fabricsurf.inverse.fitting.fit"), MPI.COMM_WORLD, "fit iteration 1")
    warn(logging.getLogger("fabricsurf.experiments.cantilever"), MPI.COMM_WORLD, "a mechanism")
""")


@serial
@pytest.mark.parametrize(
    "flags, want",
    [
        ([], "the demo's result\nfit iteration 1\nwarning: a mechanism\n"),
        (["-q"], "warning: a mechanism\n"),
    ],
)
def test_a_demo_configures_through_parse(flags, want, tmp_path):
    """A demo's own messages (its ``__main__`` logger) and the package's reach standard output
    through parse(); --quiet keeps the warnings."""
    script = tmp_path / "demo_x.py"
    script.write_text(DEMO)
    r = subprocess.run(
        [sys.executable, str(script), *flags], cwd=ROOT, capture_output=True, text=True
    )
    assert r.returncode == 0 and r.stdout == want and r.stderr == "", r


@serial
def test_each_message_is_flushed_through_a_pipe():
    """A message is readable from the pipe while the process still runs (block-buffered
    stdout would hold it until exit, as the forming demo's did under mpirun)."""
    code = (
        "import logging, time\nfrom mpi4py import MPI\n"
        "from fabricsurf.log import configure, rank0\nconfigure()\n"
        "rank0(logging.getLogger('fabricsurf.x'), MPI.COMM_SELF, 'first step done')\n"
        "time.sleep(60)\n"
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        t0 = time.perf_counter()
        line = p.stdout.readline()
        assert line == "first step done\n"
        assert time.perf_counter() - t0 < 30 and p.poll() is None
    finally:
        p.kill()
        p.wait()
