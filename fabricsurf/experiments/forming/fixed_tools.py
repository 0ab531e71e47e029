"""The fixed tools given as surfaces, the die and the blank holder: placed, checked against the
blank and tabulated (tabulated_tools.TabulatedTool, fixed: d(r) = n · (r − c)); and the check
of the punch against the die (docs/tool_surfaces.md).

A die given as a surface (``die_file``: a plate with any opening, a matched die's cavity) is
given with its face, where the holder presses the flange, at z = 0, and placed at −p_h/k_c as
the analytic die's face is (tools.Tools). Before computing it is checked
(:func:`check_die_face`): its units, no node of the flat blank inside it, and its face at z = 0
wherever the holder presses.

A holder given as a surface (``holder_file``: a triangle mesh) is given with its face, where it
presses the flange, at z = 0 facing up, and placed at −g (g the holder's gap) as the analytic
holder's face is. Its face's footprint says where it presses (surfaces/holder.py). Before
computing it is checked (:func:`tabulated_holder`): its units, a face at z = 0, and no node of
the flat blank inside it at its place. Without one, the holder is the analytic plate about the
opening of the options, pressing from one lip radius beyond the end of the die's lip.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.errors import InputError
from fabricsurf.experiments.forming import options as forming_options
from fabricsurf.experiments.forming.surfaces import ToolSurface, analytic, checks
from fabricsurf.experiments.forming.surfaces.files import given_surface, punch_surface
from fabricsurf.experiments.forming.surfaces.holder import Footprint, footprint_of
from fabricsurf.experiments.forming.tabulated_tools import (
    START_TOLERANCE,
    TabulatedTool,
    blank_size,
    same_error,
)

FACE_TOLERANCE = 0.01
"""How far a die given as a surface may leave z = 0 where the holder presses, in lip radii."""


def die_surface(o: dict) -> ToolSurface:
    """The plug-in's die as a surface, its face at −p_h/k_c (Tools): the one the options give
    (``die_file``, ``die_surface``; its face at z = 0) moved there, else the plate with the
    opening and lip of the options."""
    face = -o["holder_pressure"] / o["contact_stiffness"]
    given = given_surface(o, "die")
    if given is not None:
        return analytic.Moved(given, (0.0, 0.0, face))
    return analytic.DiePlate(forming_options.opening(o), o["die_lip"], face)


def tabulated_die(msh, surface: ToolSurface, o: dict) -> TabulatedTool:
    """The die given as a surface (face at z = 0), checked against the blank
    (:func:`check_die_face`), tabulated at its place, the face at −p_h/k_c."""
    check_die_face(surface, msh, o)
    face = -o["holder_pressure"] / o["contact_stiffness"]
    return TabulatedTool(msh, surface, moving=False, offset=(0.0, 0.0, face))


def holder_footprint(o: dict) -> Footprint | None:
    """The footprint of the holder given as a surface, or None (the analytic holder)."""
    surface = given_surface(o, "holder")
    return None if surface is None else footprint_of(surface)


def pressed(o: dict, xy: np.ndarray) -> np.ndarray:
    """Where the holder presses the flange (its pressure's weight w > 0) at the in-plane points
    ``xy``: one lip radius inside its face (surfaces/holder.py), the analytic holder's from
    σ = 2 r_d beyond the opening's outline."""
    footprint = holder_footprint(o)
    if footprint is None:
        return forming_options.opening(o).evaluate(xy)[0] >= 2.0 * o["die_lip"]
    return footprint(xy[:, :2])[0] > o["die_lip"]


def tabulated_holder(msh, o: dict) -> tuple[TabulatedTool, Footprint] | None:
    """The holder given as a surface (face at z = 0), checked against the blank (its units, its
    face, no node of the flat blank inside it at its place), tabulated at its place, the face
    at −g; with its footprint. None for the analytic holder. The same verdict on every rank."""
    surface = given_surface(o, "holder")
    if surface is None:
        return None
    offset = (0.0, 0.0, -o["holder_gap"])
    X = msh.geometry.x
    footprint, error = None, None
    try:
        checks.check_scale(surface, blank_size(msh))
        footprint = footprint_of(surface)
        flat = np.column_stack([X[:, 0], X[:, 1], np.zeros(len(X))])
        placed = analytic.Moved(surface, offset)
        checks.check_outside(placed, flat, START_TOLERANCE * surface.size)
    except InputError as e:
        error = str(e)
    same_error(msh, error)
    return TabulatedTool(msh, surface, moving=False, offset=offset), footprint


def check_die_face(surface: ToolSurface, msh, o: dict) -> None:
    """Refuse a die given as a surface whose size is far from the blank's (its units), that
    holds a node of the flat blank, or whose face is not at z = 0 where the holder presses the
    flange (:func:`pressed`: the pressure would lift the flange into nothing), within
    :data:`FACE_TOLERANCE` lip radii; the same verdict on every rank."""
    X = msh.geometry.x
    flat = np.column_stack([X[:, 0], X[:, 1], np.zeros(len(X))])
    tol = FACE_TOLERANCE * o["die_lip"]
    error = None
    try:
        checks.check_scale(surface, blank_size(msh))
        d = surface.signed_distance(flat) if len(flat) else np.zeros(0)
        checks.check_outside(surface, flat, tol, d)
        held = pressed(o, flat) if len(flat) else np.zeros(0, bool)
        gap = np.where(held, d, 0.0) if len(flat) else np.zeros(1)
        k = int(np.argmax(gap))
        if gap[k] > tol:
            raise InputError(
                f"{surface.name}: the die's face is {gap[k]:.3g} mm above the blank at "
                f"{np.round(flat[k, :2], 6).tolist()}, where the holder presses the flange "
                f"against it; the die's face must lie at z = 0 there (within {tol:.3g} mm) "
                "and cover the flange"
            )
    except InputError as e:
        error = str(e)
    same_error(msh, error)


def checked_punch(o: dict) -> ToolSurface | None:
    """The punch to check against the die (:func:`die_check`): the one given as a surface, the
    analytic hemisphere in an opening that is not the circle about it or under a die given as
    a surface, else None (that circle is wider than the punch by the clearance)."""
    surface = punch_surface(o)
    plate = forming_options.opening(o).kind == "circle" and given_surface(o, "die") is None
    if surface is None and not plate:
        return analytic.HemispherePunch(o["punch_radius"])
    return surface


def die_check(surface: ToolSurface, o: dict, reach: float):
    """A function of the stroke that refuses one driving the punch ``surface`` into the die
    (:func:`die_surface`), for strokes up to ``reach`` (checks.stroke_check)."""
    face = -o["holder_pressure"] / o["contact_stiffness"]
    return checks.stroke_check(surface, die_surface(o), face, o["die_lip"], reach)
