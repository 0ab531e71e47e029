"""Rewrite docs/input_errors.md from the real messages of today's code.

Every rejected input of the hardening tests (the ``CASES`` of the modules named in
:data:`CASE_MODULES`: a defective data directory, params file or option each) goes through the
``fabricsurf`` command line in a scratch directory, and its last line of output becomes a row
of the table. The test ``test_errors_table_is_up_to_date`` (test_hardening_outputs.py) builds
the same text with :func:`errors_table` and fails
when the file differs: this command is how the file is brought up to date, not a mode of the
test.

Run serially from the repository root: ``python benchmarks/regenerate_input_errors.py``
(``--check`` only reports whether the file is up to date, exit status 1 if not).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "input_errors.md"
COMMAND = "python benchmarks/regenerate_input_errors.py"
CASE_MODULES = (
    "test_hardening",
    "test_hardening_outputs",
    "test_hardening_process",
    "test_hardening_inputs",
    "test_hardening_dic",
    "test_user_effects",
)
"""The test modules (in tests/) whose ``CASES`` make the table, in its order."""


def all_cases() -> list[dict]:
    """Every rejected input of :data:`CASE_MODULES`, in order: each module's ``CASES``, then
    its ``ENV_CASES`` (cases that also set environment variables, their ``env``)."""
    tests = str(ROOT / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    modules = [importlib.import_module(name) for name in CASE_MODULES]
    return [c for m in modules for c in m.CASES + getattr(m, "ENV_CASES", [])]


@contextlib.contextmanager
def case_env(case: dict):
    """The environment variables of ``case["env"]`` set (a value None: unset) while it runs,
    then restored."""
    env = case.get("env", {})
    saved = {k: os.environ.get(k) for k in env}
    for k, v in env.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def table_row(case: dict, message: str) -> str:
    """One row: the input class, the command and its last line of output."""
    cmd = " ".join(str(a) for a in case["argv"])
    return f"| {case['klass']} | `fabricsurf {cmd}` | `{message.splitlines()[-1]}` |"


def errors_table(rows: list[str]) -> str:
    """The whole of docs/input_errors.md around its ``rows``."""
    return "\n".join(
        [
            "# Inputs that are rejected, and the message each gives",
            "",
            "Generated from the real messages of the cases of the hardening tests",
            f"(`tests/test_hardening*.py`; regenerate with `{COMMAND}`). Every rejection",
            "ends with exit status 2 on every MPI rank, prints one message (rank 0), and happens",
            "before any solve; nothing is written to `--out`. DATA directories hold the",
            "`experiment.toml`, `field.csv` and `force.csv` of measurement contract 2; `good` is a",
            "valid one and each other name a copy with one defect.",
            "",
            "| input | command | message |",
            "|---|---|---|",
            *rows,
            "",
            "Accepted as they are (same values as the plain file): a UTF-8 byte-order mark in",
            "`experiment.toml` or a CSV; UTF-16 CSV files with their byte-order mark; blank lines",
            "(e.g. a trailing one) in a CSV; CRLF line ends; semicolon-separated CSV with a",
            "decimal comma or a decimal point. Experiment names in any script (the file prefixes",
            "of several experiments are ASCII, with a hash of the name when it is not); an `--out`",
            "name of any length the file system allows.",
            "",
            "Refused outside this table (their messages name a process or a path that differs",
            "from run to run): a second run into an `--out` another run is writing",
            "(`--out D: another fabricsurf run (PID n on HOST) is writing to this directory; wait",
            "for it to end, or give another --out`). What an `--out` holds after a run, and what",
            'an interrupted run keeps: `docs/usage.md`, "Output directories".',
            "",
        ]
    )


def run_cli(argv: list) -> tuple[int, str]:
    """Exit status and output (stdout and stderr) of ``fabricsurf ARGV`` in this process."""
    from fabricsurf.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        rc = main([str(a) for a in argv])
    return rc, buf.getvalue().strip()


def current_table() -> str:
    """The table of today's messages, made in a scratch directory (the working directory while
    the cases run, so that messages hold relative names only)."""
    cases = all_cases()
    import test_hardening as th  # the valid experiment the cases are copies of

    from fabricsurf.inverse.contract.data import write_experiment

    rows, cwd = [], Path.cwd()
    with tempfile.TemporaryDirectory(prefix="input_errors-") as tmp:
        base = Path(tmp)
        write_experiment(base / "good", th.good_experiment())
        for case in cases:
            case["make"](base)
        os.chdir(base)
        try:
            for case in cases:
                with case_env(case):
                    rc, msg = run_cli(case["argv"])
                if rc != 2:
                    raise SystemExit(f"case {case['id']}: exit status {rc}, not 2:\n{msg}")
                rows.append(table_row(case, msg))
        finally:
            os.chdir(cwd)
    return errors_table(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="only report whether it is stale")
    args = ap.parse_args(argv)
    from mpi4py import MPI

    if MPI.COMM_WORLD.size > 1:
        raise SystemExit("run serially: the messages are those of rank 0 anyway")
    text = current_table()
    stale = not DOC.exists() or DOC.read_text() != text
    if args.check:
        print(f"{DOC.relative_to(ROOT)}: {'stale' if stale else 'up to date'}")
        return int(stale)
    if stale:
        DOC.write_text(text)
    print(f"{DOC.relative_to(ROOT)}: {'rewritten' if stale else 'already up to date'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
