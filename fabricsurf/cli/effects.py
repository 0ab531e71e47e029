"""``--effects FILE.py`` of ``fabricsurf terms|bias|compare|fit|diagnose``: a user's own effects,
registered for the duration of one command (:mod:`fabricsurf.model.user_effects`; docs/usage.md,
"Adding your own effect"). A refused file is an InputError naming it: exit 2 on every rank,
before any solve (every rank imports and checks the same file, and the checks are serial)."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator

from fabricsurf.errors import InputError


def add_effects(p: argparse.ArgumentParser) -> None:
    """``--effects FILE.py``: a user's own effects, usable in --terms and --params
    (docs/usage.md, "Adding your own effect"); repeatable, or comma-separated."""
    p.add_argument(
        "--effects",
        action="append",
        default=None,
        metavar="FILE.py",
        help="Python file(s) defining your own effects (Term subclasses with a "
        "name), checked and then usable in --terms and --params like the built-ins; "
        "repeatable or comma-separated (docs/usage.md, 'Adding your own effect'; "
        "default: none, the built-in effects only)",
    )


@contextlib.contextmanager
def user_effects(args) -> Iterator[list[str]]:
    """The effects of ``--effects`` registered for the duration of the command, a refused
    file (import error, name clash, density not linear in its moduli, ...) as an InputError
    naming it (:mod:`fabricsurf.model.user_effects`)."""
    specs = getattr(args, "effects", None) or []
    paths = [s.strip() for spec in specs for s in spec.split(",") if s.strip()]
    if not paths:
        yield []
        return
    from fabricsurf.model.user_effects import effects_from

    try:
        ctx = effects_from(paths)
        names = ctx.__enter__()
    except ValueError as e:
        raise InputError(str(e)) from None
    try:
        yield names
    finally:
        ctx.__exit__(None, None, None)
