"""The blank of the hemisphere forming plug-in (experiments/hemisphere.py): its shape, whether the
quarter or the full blank is solved, the checks of both against the tools and the mesh, all
before any computation, its mesh and the removal of the full blank's rigid motions
(docs/forming.md, "Blanks").

``[tooling] blank``: ``square`` (default; side ``length`` = ``width``), ``rectangle``
(``length`` along x × ``width``) or ``circle`` (diameter ``length`` = ``width``), centred on
the punch axis, fibres at ``fibre_angles_deg`` to x. ``[tooling] blank_domain``: ``auto``
(default), ``quarter`` or ``full``. A square or rectangle whose fibre pair each of its
mid-lines maps onto itself (±θ, or 0/90) is solved on one quarter with mirror conditions (4×
cheaper) when an aligned lattice fits its quarter at h (:func:`unfit`); every other set-up on
the full blank with its rigid motions removed (hemisphere.py). ``full`` on such a blank solves
the full blank on the quarter's mesh unfolded (a check of the two against each other);
``quarter`` where the set-up has no quarter is refused, saying why. A punch given as a
surface must be its own mirror image in both mid-planes for the quarter (checked on its
points), else ``auto`` solves the full blank.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import PluginSetup, choice_option
from fabricsurf.experiments.forming import options as forming_options
from fabricsurf.experiments.forming.surfaces import checks
from fabricsurf.experiments.forming.surfaces.files import TOOLS, given_surface
from fabricsurf.geometry.aligned import (
    blank_angle,
    canonical_angles,
    quarter_blank,
    quarter_divisions,
)
from fabricsurf.geometry.fibre_blank import fibre_blank, mirrored_quarter
from fabricsurf.log import rank0

logger = logging.getLogger(__name__)

SHAPES = ("square", "rectangle", "circle")
DOMAINS = ("auto", "quarter", "full")
KEYS = {
    "blank": "outline of the blank: square | rectangle | circle (default square; a circle's "
    "diameter is length = width)",
    "blank_domain": "auto | quarter | full: the quarter with mirror conditions (squares and "
    "rectangles with fibres at ±θ or 0/90 only) or the full blank (default auto)",
}
MIN_FIBRE_ANGLE_DEG = 30.0
"""The fibre lines must be at least this far apart: the fibre lattice of edge h spaces the
fibres of one family h sin α apart, and below h/2 its triangles are slivers (aspect ratio above
2/sin α ≈ 4) that do not resolve the sheet at the element size asked for."""


def parse(tables: dict, where: str) -> dict:
    """``[tooling] blank`` and ``blank_domain``, checked (unknown values name key and value)."""
    return {
        "blank": choice_option(tables, "tooling", "blank", SHAPES, "square", where),
        "blank_domain": choice_option(tables, "tooling", "blank_domain", DOMAINS, "auto", where),
    }


def shape(setup: PluginSetup) -> str:
    return setup.options.get("blank", "square")


def inner_half(setup: PluginSetup) -> float:
    """The shortest distance from the blank's centre to its edge (mm)."""
    return 0.5 * min(setup.length, setup.width)


def area(setup: PluginSetup) -> float:
    """The blank's reference area (mm²)."""
    if shape(setup) == "circle":
        return math.pi * (0.5 * setup.length) ** 2
    return setup.length * setup.width


def fibre_line_gap_deg(angles: tuple[float, float]) -> float:
    """The angle between the two fibre lines, in [0, 90]."""
    a, b = canonical_angles(angles)
    gap = abs(a - b) % 180.0
    return min(gap, 180.0 - gap)


def bisector_deg(angles: tuple[float, float]) -> float:
    """A bisector of the fibre lines (the diagonal of the benchmarks: 0 for ±θ, 45 for 0/90)."""
    a, b = canonical_angles(angles)
    if abs(a - b) > 90.0:
        b += 180.0 if b < a else -180.0
    return 0.5 * (a + b)


def unfit(setup: PluginSetup, h: float) -> str | None:
    """Why the blank has no aligned quarter at h (None: it has one): a circle, a fibre pair
    that is not ±θ or 0/90, or a rectangle whose sides fit no lattice at ±θ near h."""
    theta = blank_angle(tuple(setup.fibre_angles_deg))
    if shape(setup) == "circle" or theta is None:
        return (
            f"a {shape(setup)} with fibre_angles_deg = {list(setup.fibre_angles_deg)} is not "
            "mirror-symmetric about both mid-lines with an aligned mesh (a square or rectangle "
            "with fibres at ±θ or [0, 90] is)"
        )
    try:
        quarter_divisions(0.5 * setup.length, 0.5 * setup.width, h, theta)
    except ValueError as e:
        return str(e).removeprefix("geometry: ")
    return None


def domain(setup: PluginSetup, h: float) -> str:
    """``quarter`` or ``full`` at mesh size h (module docstring); a punch or a die given as a
    surface must also be its own mirror image in both mid-planes (checks.mirror_asymmetry) for
    the quarter."""
    why = unfit(setup, h)
    symmetric = why is None
    asked = setup.options.get("blank_domain", "auto")
    if asked == "quarter" and not symmetric:
        raise DataError(
            f"hemisphere: [tooling] blank_domain = 'quarter': {why}; use 'full' or 'auto'"
        )
    given = (
        (given_surface(setup.options, t) for t in TOOLS) if symmetric and asked != "full" else ()
    )
    lopsided = next(
        (why for t in given if t is not None and (why := checks.mirror_asymmetry(t))), None
    )
    if asked == "quarter" and lopsided:
        raise DataError(f"hemisphere: [tooling] blank_domain = 'quarter': {lopsided}")
    return "quarter" if symmetric and asked != "full" and not lopsided else "full"


def check_specimen(setup: PluginSetup, where: str) -> None:
    """The blank's outline and size against the die, and the fibre pair against the mesh."""
    o, s = setup.options, shape(setup)
    if s == "circle" and setup.length != setup.width:
        raise DataError(
            f"{where}: [tooling] blank = 'circle' needs length = width (its "
            f"diameter), not {setup.length:g} × {setup.width:g} mm"
        )
    if s == "square":
        forming_options.check_specimen(setup, where)
    else:
        R = o["punch_radius"]
        short = forming_options.uncovered(o, *_halves(setup), s == "circle")
        if short is not None:
            raise DataError(
                f"{where}: the {s} blank {setup.length:g} × {setup.width:g} mm "
                f"must be wider everywhere than {short}"
            )
        if max(setup.length, setup.width) > forming_options.MAX_BLANK_RATIO * R:
            raise DataError(
                f"{where}: [tooling] punch_radius = {R:g} mm is implausibly small "
                f"for a {max(setup.length, setup.width):g} mm blank (at most "
                f"{forming_options.MAX_BLANK_RATIO:g} punch radii wide)"
            )
    gap = fibre_line_gap_deg(tuple(setup.fibre_angles_deg))
    if gap < MIN_FIBRE_ANGLE_DEG:
        raise DataError(
            f"{where}: fibre_angles_deg = {list(setup.fibre_angles_deg)}: the fibre "
            f"lines are {gap:g}° apart, closer than the fibre-aligned mesh resolves "
            f"(its cells would be slivers of width h·sin {gap:g}° < h/2); the "
            f"fibres must be at least {MIN_FIBRE_ANGLE_DEG:g}° apart"
        )


MAX_H_PER_R = 0.5
"""Largest element size in punch radii: the quarter of the cap is then two elements across."""


def check_mesh(setup: PluginSetup, h: float, default: bool) -> None:
    """Refuse a mesh of more cells than forming_options.MAX_ELEMENTS: the quarter's estimate
    (forming_options.check_mesh) or, for the full blank, 2 triangles per lattice cell
    h² sin α; and an h too coarse to follow the punch's cap (more than :data:`MAX_H_PER_R`
    of its radius)."""
    R = setup.options["punch_radius"]
    if h > MAX_H_PER_R * R:
        raise DataError(
            f"hemisphere: h = {h:g} mm is more than {MAX_H_PER_R:g} of the punch "
            f"radius ({R:g} mm): the mesh cannot follow the punch's cap; give "
            f"h ≤ {MAX_H_PER_R * R:g} mm (default R/6; R/10 resolves the tools)"
        )
    if domain(setup, h) == "quarter":
        forming_options.check_mesh(setup, h, default)
        return
    sin_a = math.sin(math.radians(fibre_line_gap_deg(tuple(setup.fibre_angles_deg))))
    n = int(2 * area(setup) / (h * h * sin_a))
    if n > forming_options.MAX_ELEMENTS:
        what = f"the default h = R/6 = {h:g} mm" if default else f"h = {h:g} mm"
        raise DataError(
            f"hemisphere: {what} would mesh the full {shape(setup)} blank with "
            f"about {n:,} cells, more than {forming_options.MAX_ELEMENTS:,}: give a "
            f"larger h (at least "
            f"{math.sqrt(2 * area(setup) / (sin_a * forming_options.MAX_ELEMENTS)):.3g}"
            " mm)"
        )


def check_stroke(setup: PluginSetup, stroke: float) -> None:
    """forming_options.check_stroke with the blank's shortest reach from the centre (every
    reference path to the edge is at least that long)."""
    forming_options.check_stroke(setup.options, 2.0 * inner_half(setup), stroke)


def _halves(setup: PluginSetup) -> tuple[float, float]:
    return 0.5 * setup.length, 0.5 * setup.width


def unheld_edge(setup: PluginSetup) -> str | None:
    """forming_options.unheld_edge at the blank's edges."""
    return forming_options.unheld_edge(setup.options, *_halves(setup), shape(setup) == "circle")


def reach(setup: PluginSetup, direction_deg: float) -> float:
    """Distance from the centre to the blank's edge along the reference ray at
    ``direction_deg``."""
    a, b = 0.5 * setup.length, 0.5 * setup.width
    if shape(setup) == "circle":
        return a
    t = math.radians(direction_deg)
    c, s = abs(math.cos(t)), abs(math.sin(t))
    return min(a / c if c > 1e-12 else math.inf, b / s if s > 1e-12 else math.inf)


def blank_mesh(setup: PluginSetup, domain_: str, theta: float | None, h: float, comm: MPI.Comm):
    """The quarter's aligned mesh (geometry.aligned.quarter_blank); for the full blank of a
    blank that has one (:func:`unfit`) the quarter's unfolded
    (geometry.fibre_blank.mirrored_quarter); else the fibre lattice clipped to the blank
    (geometry.fibre_blank.fibre_blank)."""
    a, b = 0.5 * setup.length, 0.5 * setup.width
    if domain_ == "quarter":
        return quarter_blank(a, b, h, theta, comm)
    why = unfit(setup, h)
    if why is None:
        return mirrored_quarter(a, b, h, theta, comm)
    if theta is not None and shape(setup) != "circle":  # mirror-symmetric, but no quarter at h
        rank0(logger, comm, f"hemisphere: solved on the full blank, 4× the cells: {why}")
    outline = "circle" if shape(setup) == "circle" else "rectangle"
    return fibre_blank(outline, a, b, tuple(setup.fibre_angles_deg), h, comm)


def pin_rigid_motions(p, R: float, rotation: bool) -> tuple[dict, tuple | None]:
    """Remove the full blank's rigid motions from the problem ``p`` (a ContactProblem, before
    its solver is built; docs/forming.md "Blanks"): u_x = u_y = 0 at the pole, and, if
    ``rotation`` (frictionless tools: the rotation about the punch axis is then a symmetry of
    the whole problem), u_x = 0 at the vertex nearest (0, R/2).

    Why the answer is unchanged: every accepted blank (centred square, rectangle, circle) and
    fibre pair (lines, so X → −X maps each family onto itself) is invariant under the half turn
    about the punch axis, as are the tools and the mesh (geometry/fibre_blank.py), so the
    answer's pole does not move in-plane; and the second pin only chooses one of the copies of
    the answer rotated about the axis (reachable for any rotation: the vertex lies on the y
    axis to within a cell). Either way the pins carry no load, which
    HemispherePlugin.pin_reactions measures. With friction the rotation is resisted and not
    a symmetry, so it is left free. Returns the pinned dofs by name and the second pin's
    vertex (None without it)."""
    bs = p.V.dofmap.index_map_bs
    pole = p.vertex_nodes((0.0, 0.0))
    pins = {"pole_x": (pole * bs, 0), "pole_y": (pole * bs + 1, 1)}
    vertex = None
    if rotation:
        x = p.msh.geometry.x[:, :2]
        dist = np.hypot(x[:, 0], x[:, 1] - 0.5 * R)
        k = int(dist.argmin()) if len(dist) else -1
        mine = (float(dist[k]), tuple(float(c) for c in x[k])) if k >= 0 else (math.inf, ())
        vertex = min(p.comm.allgather(mine))[1]
        pins["rotation_x"] = (p.vertex_nodes(vertex) * bs, 0)
    zero = fem.Constant(p.msh, 0.0)
    for dofs, i in pins.values():
        p.bcs.append(fem.dirichletbc(zero, dofs.astype(np.int32), p.V.sub(i)))
    return {k: d for k, (d, _) in pins.items()}, vertex


def record(
    setup: PluginSetup, specimen, domain_: str, rotation_vertex: tuple | None, h: float
) -> dict:
    """What a run computed on: mesh kind, h asked and used, blank, domain, how the rigid
    motions were removed, cells (the experiment's ``discretisation``)."""
    how = (
        "mirror conditions on x = 0 and y = 0"
        if domain_ == "quarter"
        else "pole pinned in-plane"
        + ("" if rotation_vertex is None else ", u_x = 0 at (%.6g, %.6g)" % tuple(rotation_vertex))
    )
    return {
        "mesh_kind": specimen.kind,
        "h_requested": float(h),
        "h_used": float(specimen.h),
        "blank": shape(setup),
        "domain": domain_,
        "rigid_motions": how,
        "mesh_note": specimen.note,
        "cells": int(specimen.mesh.topology.index_map(2).size_global),
    }
