"""The mesh-size options of the command line, checked before any meshing: ``--h`` (positive, at
most half the narrowest specimen), ``--max-elements`` (the element count a ``--h``, or the
tests' default sizes, would give, estimated with the memory it would take) and diagnose's mesh
selection budget, ``--max-dofs`` and ``--time-budget``. Every message names the option."""

from __future__ import annotations

import argparse
import math

from fabricsurf.errors import InputError

MAX_ELEMENTS = 400_000
"""Default of ``--max-elements``: about 20 GB at KB_PER_ELEMENT, what a 24 GB machine holds."""


KB_PER_ELEMENT = 50.0
"""Memory per triangle, all ranks together (bias test, second-gradient model, MUMPS), with a
margin: it rises with the direct solver's fill-in (docs/uncertainty.md, costs)."""


def add_max_elements(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--max-elements",
        type=int,
        default=MAX_ELEMENTS,
        help="refuse a --h whose meshes would have more elements than this, "
        f"estimated before meshing (~{KB_PER_ELEMENT:g} kB of memory each)",
    )


def _elements(length: float, width: float, h: float) -> float:
    """2 triangles per h × h square; a float (inf for a denormal h), never an overflow."""
    cells = [math.ceil(x) if x < 1e15 else x for x in (length / h, width / h)]
    return 2.0 * cells[0] * cells[1]


def _count(n: float) -> str:
    return f"{n:,.0f}" if n < 1e15 else f"{n:.2g}"


REFINED = " (fit and diagnose also solve there: the mesh check)"


def check_size(
    h: float, specimens: list[tuple[str, float, float]], max_elements: int, refine: int = 1
) -> None:
    """Refuse ``--h`` when the meshes of ``specimens`` ((name, length, width) in mm) would
    have more than ``max_elements`` triangles in all, estimated as 2 per h × h square before
    any meshing, with the memory they would take. ``refine``: the finest mesh the command
    builds is at h/refine (fit and diagnose: 2, their mesh check)."""
    if max_elements < 1:
        raise InputError(f"--max-elements {max_elements}: must be at least 1")
    n = sum(_elements(L, W, h / refine) for _, L, W in specimens)
    what = ", ".join(f"{name} {L:g} x {W:g} mm" for name, L, W in specimens)
    if refine > 1:
        what += f"; at h/{refine} = {h / refine:g} mm{REFINED}"
    if not math.isfinite(n):
        raise InputError(
            f"--h {h:g}: far too small an element size for {what} (the element "
            "count overflows); give a larger --h"
        )
    if n > max_elements:
        gb = n * KB_PER_ELEMENT / 1e6
        gb = f"{gb:,.0f}" if 10 <= gb < 1e15 else f"{gb:.2g}"
        raise InputError(
            f"--h {h:g}: about {_count(n)} elements ({what}), more than "
            f"--max-elements {max_elements:,}; they would take about "
            f"{gb} GB of memory (~{KB_PER_ELEMENT:g} kB "
            "per element): give a larger --h, or raise --max-elements if the "
            "machine has the memory"
        )


def check_default_size(exps: list, max_elements: int, refine: int = 1) -> None:
    """Without ``--h``, each experiment's mesh has its test's default element size: the same
    guard as :func:`check_size`, before any meshing, naming the default and the remedy."""
    from fabricsurf.experiments import get_test

    if max_elements < 1:
        raise InputError(f"--max-elements {max_elements}: must be at least 1")
    hs = [get_test(e.test).default_h(e.setup) for e in exps]
    n = sum(_elements(e.length, e.width, h / refine) for e, h in zip(exps, hs))
    if n > max_elements:
        what = ", ".join(
            f"'{e.name}' {e.length:g} x {e.width:g} mm at h = {h:.3g} mm" for e, h in zip(exps, hs)
        )
        if refine > 1:
            what += f", and at h/{refine}{REFINED}"
        raise InputError(
            f"no --h given: the tests' default element sizes ({what}) give about "
            f"{_count(n)} elements, more than --max-elements {max_elements:,} (about "
            f"{n * KB_PER_ELEMENT / 1e6:.3g} GB of memory); give a larger --h, "
            "or raise --max-elements if the machine has the memory"
        )


def mesh_budget(args):
    """``--max-dofs`` and ``--time-budget`` of diagnose (with ``--max-elements``) as the mesh
    selection's budget (:class:`~fabricsurf.inverse.diagnosis.mesh_choice.Budget`)."""
    from fabricsurf.inverse.diagnosis.mesh_choice import Budget

    if args.max_dofs < 1:
        raise InputError(
            f"--max-dofs {args.max_dofs}: must be at least 1 (displacement "
            "unknowns of the finest mesh the diagnosis may fit on)"
        )
    t = args.time_budget
    if not (math.isfinite(t) and t > 0):
        raise InputError(f"--time-budget {t:g}: must be a finite time in seconds > 0")
    return Budget(max_dofs=args.max_dofs, max_cells=args.max_elements, seconds=t)


def check_h(h: float | None, exps: list | None = None) -> None:
    """``--h`` positive and at most half the smallest specimen side (two elements across)."""
    if h is None:
        return
    limit = 0.5 * min(min(e.length, e.width) for e in exps) if exps else float("inf")
    if not 0 < h <= limit:
        raise InputError(
            f"--h {h:g}: must be a positive element size in mm"
            + (f", at most {limit:g} (two elements across the narrowest specimen)" if exps else "")
        )
