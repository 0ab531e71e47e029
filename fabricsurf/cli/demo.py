"""What every demo in demos/ shares: its command line and the checks it declares on its
summary.json.

**Command line.** ``--out DIR``, ``--quick``, ``-v/--verbose`` and ``-q/--quiet``
(:func:`demo_parser`); :func:`parse` configures the messages for the rest of the run as the
``fabricsurf`` command does (:func:`fabricsurf.log.configure`: the demo's own, logged through
``logging.getLogger(__name__)``, and the package's, on rank 0, flushed; details with
``--verbose``, warnings only with ``--quiet``) and keeps the JIT compiler quiet unless
``--verbose`` (:func:`fabricsurf.cli.compiler_messages`).

**Checks.** One module-level ``CHECKS`` dict of the demo script, read both by the demo itself
(at its end, :func:`verify`) and by tests/test_demos.py (from the source, :func:`declared`,
without running or importing the demo). A key is a path into the summary, segments separated
by ``/``; the segment ``*`` stands for every element of a list or every value of a dict. A
value is

* ``...``: the entry exists;
* a tuple ``(low, high)``: a number with low ≤ value ≤ high (``None`` for an open end);
* anything else: equal to the entry (strings, integers, booleans, ``None``, lists).

Numbers only: importing this module loads no FEniCSx module (tests/test_layout.py)."""

from __future__ import annotations

import argparse
import ast
import contextlib
import inspect
from pathlib import Path
from typing import Any

_QUIET = contextlib.ExitStack()  # held for the life of the process: the demo is one run


def demo_parser(description: str | None, out: str) -> argparse.ArgumentParser:
    """A parser with the options every demo has (default output directory ``out``)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--out", type=Path, default=Path(out), help="output directory")
    ap.add_argument("--quick", action="store_true", help="small and fast (the test suite)")
    ap.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="details too, and the JIT compiler's messages (FFCx, UFL, C compiler)",
    )
    ap.add_argument(
        "-q", "--quiet", action="store_true", help="no progress messages, only warnings and errors"
    )
    return ap


def parse(ap: argparse.ArgumentParser, argv: list[str] | None = None) -> argparse.Namespace:
    """Parse the options, configure the messages (:func:`fabricsurf.log.configure`) and,
    unless ``--verbose``, hide the compiler, from here on."""
    from fabricsurf.cli import compiler_messages
    from fabricsurf.log import configure, level_of

    args = ap.parse_args(argv)
    _QUIET.enter_context(configure(level_of(args.verbose, args.quiet)))
    _QUIET.enter_context(compiler_messages(args.verbose))
    return args


def declared(script: Path) -> dict:
    """The ``CHECKS = {...}`` literal of a demo script, read from its source."""
    tree = ast.parse(Path(script).read_text(), filename=str(script))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "CHECKS" for t in node.targets
        ):
            return ast.literal_eval(node.value)
    raise LookupError(f"{script}: no module-level CHECKS dict")


def entries(summary: Any, path: str) -> list[tuple[str, Any]]:
    """The (concrete path, value) pairs that ``path`` names in ``summary``."""
    found = [("", summary)]
    for seg in path.split("/"):
        nxt = []
        for where, node in found:
            if seg == "*":
                items = node.items() if isinstance(node, dict) else enumerate(node)
                nxt += [(f"{where}/{k}", v) for k, v in items]
            elif isinstance(node, dict) and seg in node:
                nxt.append((f"{where}/{seg}", node[seg]))
            else:
                raise KeyError(f"summary.json has no {where}/{seg} (check {path!r})")
        found = nxt
    return [(where.lstrip("/"), v) for where, v in found]


def failures(summary: dict, checks: dict) -> list[str]:
    """One line per declared check that ``summary`` does not meet (empty: all met)."""
    bad = []
    for path, want in checks.items():
        try:
            found = entries(summary, path)
        except (KeyError, TypeError) as e:
            bad.append(str(e))
            continue
        if not found:
            bad.append(f"{path}: matches nothing")
        for where, value in found:
            if want is ...:
                continue
            if isinstance(want, tuple):
                low, high = want
                ok = (
                    isinstance(value, (int, float))
                    and not isinstance(value, bool)
                    and ((low is None or value >= low) and (high is None or value <= high))
                )
            else:
                ok = value == want
            if not ok:
                bad.append(f"{where} = {value!r}, declared {want!r}")
    return bad


class DemoCheckError(RuntimeError):
    """A demo's own check failed (raised by :func:`require` and :func:`verify`)."""


def require(condition: object, message: object = None) -> None:
    """A demo's check: raise :class:`DemoCheckError` with ``message`` (default: the file and
    line of the check) unless ``condition``. Unlike ``assert`` it holds under ``python -O``,
    which strips asserts."""
    if not condition:
        if message is None:
            caller = inspect.stack()[1]
            message = f"the check at {Path(caller.filename).name}:{caller.lineno}"
        raise DemoCheckError(f"failed: {message}")


def verify(summary: dict, checks: dict) -> None:
    """Raise :class:`DemoCheckError` naming every declared check that ``summary`` does not
    meet."""
    bad = failures(summary, checks)
    require(not bad, "summary.json breaks its declared checks:\n  " + "\n  ".join(bad))
