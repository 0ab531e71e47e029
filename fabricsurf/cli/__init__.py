"""The command line: ``fabricsurf terms|bias|compare|fit|diagnose`` (also ``python -m
fabricsurf``; every command runs under ``mpirun -n P``).

Bad input ends with one message naming the file, key or option and exit status 2 on every rank;
an unexpected failure on one rank aborts all ranks instead of leaving the others waiting. The
JIT compiler's messages are hidden unless ``--verbose``.
"""

from __future__ import annotations

import argparse
import logging
import sys

from mpi4py import MPI

from fabricsurf.cli import bias as bias_cli
from fabricsurf.cli import measure
from fabricsurf.discretise.output import rank0_print
from fabricsurf.errors import InputError

COMM = MPI.COMM_WORLD
FORMATTER = argparse.ArgumentDefaultsHelpFormatter


def cmd_terms(args) -> int:
    """Print the vocabulary: names, formulas, moduli and units."""
    from fabricsurf.model.terms import EFFECTS

    for name, cls in EFFECTS.items():
        units = ", ".join(f"{p} ({cls.units.get(p, '?')})" for p in cls.parameters())
        doc = (cls.__doc__ or "").strip().splitlines()[0]
        rank0_print(COMM, f"{name:18s} {units}\n{'':18s} {doc}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="fabricsurf", formatter_class=FORMATTER,
                                 description="Fabric surface models vs measurements: solve, "
                                 "compare, fit, diagnose the missing effect. Lengths in mm, "
                                 "forces in N; moduli N/mm (first gradient) and N·mm (second).")
    ap.add_argument("--verbose", action="store_true", help="show the JIT compiler's messages")
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("terms", help="list the effects: names, moduli, units, formulas")
    p.set_defaults(func=cmd_terms)
    p = sub.add_parser("bias", formatter_class=FORMATTER,
                       help="continuum bias-extension test: XDMF, force curve, log")
    bias_cli.add_arguments(p)
    p.set_defaults(func=bias_cli.run)
    measure.add_parsers(sub, FORMATTER)
    return ap


def _quiet(verbose: bool) -> None:
    level = logging.INFO if verbose else logging.WARNING
    for name in ("ffcx", "UFL", "UFL_LEGACY", "dolfinx"):
        logging.getLogger(name).setLevel(level)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fabricsurf`` command; returns the exit status (same on all ranks)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as e:
        return int(e.code or 0) if isinstance(e.code, int) else 2
    _quiet(args.verbose)
    try:
        return args.func(args)
    except (InputError, OSError) as e:
        rank0_print(COMM, f"fabricsurf {args.command}: error: {e}")
        return 2
    except RuntimeError as e:
        rank0_print(COMM, f"fabricsurf {args.command}: failed: {e}")
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
