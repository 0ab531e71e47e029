"""The command line: ``fabricsurf terms|bias|compare|fit|diagnose|import-dic`` (also ``python -m
fabricsurf``; every command runs under ``mpirun -n P``).

Bad input ends with one message naming the file, key or option and exit status 2 on every rank
(usage errors too); SIGINT or SIGTERM (what ``mpirun`` sends every rank on a Ctrl-C) ends
every rank at once with one message and status 130, the output directory published (``bias``:
its step log and a failure.json, not the fields) or removed
(:mod:`fabricsurf.cli.interrupts`). Under ``mpirun`` the status the shell sees is
mpirun's own: Open MPI 4.1 returns 1 when it is itself interrupted, whatever its ranks return
(a job whose ranks exit with 130 by themselves gives 130), so 130 holds for serial runs only;
an unexpected failure on one rank aborts all ranks instead of leaving the
others waiting. Messages go to standard output on rank 0 through
:func:`fabricsurf.log.configure` while a command runs: progress by default, details too with
``-v/--verbose`` (which also shows the JIT compiler's messages: FFCx, UFL and the C compiler
lines that cffi logs through the root logger), warnings and errors only with ``-q/--quiet``;
a warning is one line ``warning: …``, with ``--quiet`` too. The environment (the JIT
compiler's directories under HOME, FABRICSURF_LOCAL_CELLS) is checked before any computation
(:mod:`fabricsurf.cli.environment`).

The commands' modules are imported when the parser is built (the interrupt handling when a
command starts), so that importing :mod:`fabricsurf.cli` (and :mod:`fabricsurf.cli.demo`, what
every demo shares) loads no FEniCSx module.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import re
import sys
from collections.abc import Iterator

from mpi4py import MPI

from fabricsurf.cli.effects import add_effects, user_effects
from fabricsurf.cli.environment import check_environment
from fabricsurf.errors import InputError
from fabricsurf.log import configure, level_of, rank0

logger = logging.getLogger(__name__)
COMM = MPI.COMM_WORLD
JIT_LOGGERS = ("ffcx", "UFL", "UFL_LEGACY", "dolfinx")


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows "(default: …)" for every option that has a default not already in its help."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if action.default is None or action.default is False or "default" in text:
            return text
        return super()._get_help_string(action)


def cmd_terms(args) -> int:
    """Print the vocabulary: names, moduli with units, and energy densities; a user's effects
    (--effects) after the built-ins, each with the file it comes from."""
    from fabricsurf.model.registry import BUILTIN
    from fabricsurf.model.terms import EFFECTS

    rank0(
        logger,
        COMM,
        "Effects (energy densities per unit reference area, N/mm; symbols in "
        "docs/vocabulary.md). Use the names in --terms and --params.",
    )
    for name, cls in EFFECTS.items():
        units = ", ".join(
            f"{p} ({cls.units.get(p, '?')}{', signed' * (p in cls.signed)})"
            for p in cls.parameters()
        )
        doc = ((cls.__doc__ or "").strip().splitlines() or [""])[0]
        origin = EFFECTS.origin(name)
        where = "" if origin == BUILTIN else f"\n{'':18s} (your effect, from {origin})"
        rank0(logger, COMM, f"{name:18s} {units}\n{'':18s} {doc}{where}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from fabricsurf.cli import bias as bias_cli
    from fabricsurf.cli import diagnose_command, measure
    from fabricsurf.cli import dic as dic_cli

    ap = argparse.ArgumentParser(
        prog="fabricsurf",
        formatter_class=HelpFormatter,
        description="Fabric surface models vs measurements: solve, "
        "compare, fit, diagnose the missing effect. Lengths in mm, "
        "forces in N; moduli N/mm (first gradient) and N·mm (second).",
    )
    _verbose(ap, False)
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser(
        "terms",
        formatter_class=HelpFormatter,
        help="list the effects: names, moduli, units, formulas",
    )
    add_effects(p)
    p.set_defaults(func=cmd_terms)
    p = sub.add_parser(
        "bias",
        formatter_class=HelpFormatter,
        help="continuum bias-extension test: XDMF, force curve, log",
    )
    bias_cli.add_arguments(p)
    p.set_defaults(func=bias_cli.run)
    measure.add_parsers(sub, HelpFormatter)
    diagnose_command.add_parser(sub, HelpFormatter)
    dic_cli.add_parser(sub, HelpFormatter)
    for p in sub.choices.values():
        _verbose(p, argparse.SUPPRESS)
    return ap


def _verbose(p: argparse.ArgumentParser, default) -> None:
    """``--verbose`` and ``--quiet`` before or after the command (SUPPRESS: the command's copy
    does not overwrite the value given before it)."""
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=default,
        help="details too (the 'fabricsurf' logger at DEBUG) and the JIT "
        "compiler's messages (FFCx, UFL, C compiler)",
    )
    p.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        default=default,
        help="no progress messages, only warnings and errors (the 'fabricsurf' logger at WARNING)",
    )


@contextlib.contextmanager
def compiler_messages(verbose: bool) -> Iterator[None]:
    """Hide INFO messages (default) or show the JIT loggers' INFO (``verbose``), then restore.

    Quiet uses ``logging.disable``: cffi resets the root logger to INFO on every compilation
    (distutils' set_threshold), so a level set beforehand would not hold."""
    disabled = logging.root.manager.disable
    levels = {n: logging.getLogger(n).level for n in JIT_LOGGERS}
    logging.disable(logging.NOTSET if verbose else logging.INFO)
    for n in JIT_LOGGERS:
        logging.getLogger(n).setLevel(logging.INFO if verbose else logging.WARNING)
    try:
        yield
    finally:
        logging.disable(disabled)
        for n, level in levels.items():
            logging.getLogger(n).setLevel(level)


NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?|[-+]?(?:inf|infinity|nan)"
NUMBERS = re.compile(rf"(?:{NUMBER})(?:\s*,\s*(?:{NUMBER}))*", re.IGNORECASE)
"""A number or a comma-separated list of them (``-1,0``, ``-1e-3``, ``-inf``)."""


def numbers_joined(ap: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with every option that takes a value joined to a value that begins with '-' and
    is a number or a list of them (``--grip-depths -1,0`` → ``--grip-depths=-1,0``).

    argparse reads such a token as an option, unless it is a plain negative number ("-1",
    "-.5"), and stops with "expected one argument"; joined, the value reaches the option's own
    check, which names what is wrong with it. Nothing after "--" is touched."""
    parsers = [ap] + [
        p
        for a in ap._actions
        if isinstance(a, argparse._SubParsersAction)
        for p in a.choices.values()
    ]
    takes_value = {
        o for p in parsers for a in p._actions if a.nargs is None for o in a.option_strings
    }
    out: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        if token == "--":
            return out + argv[i:]
        value = argv[i + 1] if i + 1 < len(argv) else ""
        if token in takes_value and value.startswith("-") and NUMBERS.fullmatch(value):
            out.append(f"{token}={value}")
            i += 2
        else:
            out.append(token)
            i += 1
    return out


def _command(argv: list[str]) -> str:
    """The command named in ``argv`` (its first word that is not an option), for messages
    given before the arguments are parsed; "" if none."""
    return next((a for a in argv if not a.startswith("-")), "")


def _parse(argv: list[str]) -> argparse.Namespace | int:
    """The arguments, or the exit status of --help / a usage error (printed by rank 0 only)."""
    quiet = contextlib.ExitStack()
    if COMM.rank > 0:
        quiet.enter_context(contextlib.redirect_stdout(io.StringIO()))
        quiet.enter_context(contextlib.redirect_stderr(io.StringIO()))
    with quiet:
        try:
            ap = build_parser()
            return ap.parse_args(numbers_joined(ap, argv))
        except SystemExit as e:
            return e.code if isinstance(e.code, int) else 2


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fabricsurf`` command; returns the exit status (same on all ranks).
    Interrupts are handled from the start (building the parser imports the libraries, which
    takes about a second)."""
    from fabricsurf.cli.interrupts import interruptible

    argv = [str(a) for a in (sys.argv[1:] if argv is None else argv)]
    with interruptible(_command(argv)):
        args = _parse(argv)
        if isinstance(args, int):
            return args
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """The command, its errors turned into one message and the exit status; the messages
    configured (:func:`fabricsurf.log.configure`) for the command only."""
    with configure(level_of(args.verbose, args.quiet), COMM):
        try:
            with compiler_messages(args.verbose):
                check_environment(COMM, args.command)
                with user_effects(args):
                    return args.func(args)
        except (InputError, OSError) as e:
            rank0(logger, COMM, f"fabricsurf {args.command}: error: {e}", level=logging.ERROR)
            return 2
        except RuntimeError as e:
            rank0(logger, COMM, f"fabricsurf {args.command}: failed: {e}", level=logging.ERROR)
            return 2
        except Exception:
            if COMM.size > 1:
                import traceback

                traceback.print_exc()
                sys.stderr.flush()
                COMM.Abort(1)
            raise


if __name__ == "__main__":
    sys.exit(main())
