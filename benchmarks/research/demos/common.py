"""The command line every demo shares: ``--out DIR``, ``--quick`` and ``--verbose``, and the
JIT compiler kept quiet for the rest of the run unless ``--verbose``, with the mechanism of the
``fabricsurf`` command (:func:`fabricsurf.cli.compiler_messages`)."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from fabricsurf.cli import compiler_messages

_QUIET = contextlib.ExitStack()  # held for the life of the process: the demo is one run


def demo_parser(description: str | None, out: str) -> argparse.ArgumentParser:
    """A parser with the options every demo has (default output directory ``out``)."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--out", type=Path, default=Path(out), help="output directory")
    ap.add_argument("--quick", action="store_true", help="small and fast (the test suite)")
    ap.add_argument("--verbose", action="store_true",
                    help="show the JIT compiler's messages (FFCx, UFL, C compiler)")
    return ap


def parse(ap: argparse.ArgumentParser, argv: list[str] | None = None) -> argparse.Namespace:
    """Parse the options and, unless ``--verbose``, hide the compiler from here on."""
    args = ap.parse_args(argv)
    _QUIET.enter_context(compiler_messages(args.verbose))
    return args
