"""Checks of a tool set before any computing: each raises InputError naming the tool and what
to change (docs/tool_surfaces.md, "Bad input").

* Units: a tool whose size is more than :data:`SCALE_LIMIT` times the blank's, or less than
  its inverse, is read in the wrong units (a file in mm read as m is 1000 times too large).
* Start: no point of the flat blank may lie inside a tool at the start of the stroke (a tool
  that starts inside the blank would push it out with the full penalty force at once).
* Symmetry (:func:`mirror_asymmetry`): a tool solved on a quarter of the blank must be its own
  mirror image in both mid-planes.
* Stroke: at the end of the stroke the punch may not enter the die: the points of the punch's
  surface, moved by the stroke, must all lie outside the die. The largest stroke that keeps
  them out is found by bisection and given in the message.

Points on a surface for the last check are the grid points of a box within one spacing of the
surface, projected onto it along the normal (x − d n, twice): any surface with a signed
distance gives them; on a triangle mesh, points of its triangles at that spacing.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from fabricsurf.errors import InputError
from fabricsurf.experiments.forming.surfaces import ToolSurface

SCALE_LIMIT = 50.0
"""Largest ratio of a tool's size to the blank's (either way) taken as the same units."""
BISECTION_TOLERANCE = 1e-7
"""The largest stroke's error in the stroke check's bisection, relative to the stroke (the
message gives six digits)."""


def check_scale(tool: ToolSurface, blank_size: float) -> None:
    """Refuse a tool ``SCALE_LIMIT`` times larger or smaller than the blank (module docstring)."""
    ratio = tool.size / blank_size
    if ratio > SCALE_LIMIT or ratio < 1.0 / SCALE_LIMIT:
        big = ratio > 1.0
        raise InputError(
            f"{tool.name}: the tool is {ratio if big else 1.0 / ratio:.3g} times "
            f"{'larger' if big else 'smaller'} than the blank ({tool.size:.6g} mm against "
            f"{blank_size:.6g} mm): are its units right? (units = 'mm', 'cm', 'm' or 'in'; a "
            "file in mm read as m is 1000 times too large)"
        )


def check_outside(
    tool: ToolSurface, points: np.ndarray, tolerance: float = 0.0, d: np.ndarray | None = None
) -> None:
    """Refuse a tool that holds points of the blank (rows, mm) deeper than ``tolerance``;
    ``d``: their signed distances, if the caller has them."""
    d = tool.signed_distance(np.asarray(points, float)) if d is None else d
    inside = d < -tolerance
    if inside.any():
        k = int(np.argmin(d))
        raise InputError(
            f"{tool.name}: the tool starts inside the blank: {int(inside.sum())} of {len(d)} "
            f"points of the blank lie inside it, up to {-d[k]:.6g} mm deep (at "
            f"{np.round(points[k], 6).tolist()}); place it so that it at most touches the blank"
        )


def surface_points(tool: ToolSurface, lower, upper, spacing: float) -> np.ndarray:
    """Points on the tool's surface within the box [lower, upper] (module docstring)."""
    if getattr(tool, "faces", None) is not None:
        return _triangle_points(tool.vertices[tool.faces], lower, upper, spacing)
    axes = [np.arange(lo, hi + 0.5 * spacing, spacing) for lo, hi in zip(lower, upper, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    near = grid[np.abs(tool.signed_distance(grid)) < spacing]
    for _ in range(2):
        near = near - tool.signed_distance(near)[:, None] * tool.normal(near)
    return near


def _triangle_points(corners: np.ndarray, lower, upper, spacing: float) -> np.ndarray:
    """Points on the triangles (corners (t, 3, 3)) within the box: on each triangle, the
    barycentric grid of n + 1 points a side, n the longest edge over ``spacing`` rounded up."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    keep = np.all((corners.max(axis=1) >= lower) & (corners.min(axis=1) <= upper), axis=1)
    corners = corners[keep]
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max(axis=1)
    counts = np.maximum(np.ceil(edges / spacing), 1).astype(int)
    points = [np.empty((0, 3))]
    for n in np.unique(counts):
        i, j = np.divmod(np.arange((n + 1) ** 2), n + 1)
        i, j = i[i + j <= n], j[i + j <= n]
        w = np.column_stack([n - i - j, i, j]) / n
        points.append(np.einsum("pk,tkd->tpd", w, corners[counts == n]).reshape(-1, 3))
    out = np.concatenate(points)
    return out[np.all((out >= lower) & (out <= upper), axis=1)]


def check_stroke(
    punch: ToolSurface,
    die: ToolSurface,
    points: np.ndarray,
    direction,
    stroke: float,
    near: float | None = None,
) -> None:
    """Refuse a stroke ``stroke`` (mm) along ``direction`` that takes the punch's surface
    ``points`` (at the start, rows) into the die (module docstring). With ``near`` (mm, more
    than the points' spacing) a triangle mesh's distances are exact only within ``near`` of
    it (TriangulatedSurface.near; the points far from the die cost nothing): a punch that
    enters the die has points within their spacing of its surface, exact there."""
    e = np.asarray(direction, float) / np.linalg.norm(direction)
    fast = near is not None and getattr(die, "near", None) is not None

    def distances(s: float, rows) -> np.ndarray:
        x = points[rows] + s * e
        return die.near(x, near)[0] if fast else die.signed_distance(x)

    everyone = slice(None)
    if -distances(0.0, everyone).min() > 0.0:
        raise InputError(f"{punch.name}: the punch starts inside the die {die.name}")
    last = distances(stroke, everyone)
    if -last.min() <= 0.0:
        return
    limit = _first_contact(distances, last, stroke)
    raise InputError(
        f"{punch.name}: the stroke of {stroke:.6g} mm passes through the die {die.name}: the "
        f"punch would be {-last.min():.6g} mm inside it; the die stops it at a stroke of "
        f"{limit:.6g} mm (less the blank's thickness)"
    )


def _first_contact(distances, at_stroke: np.ndarray, stroke: float) -> float:
    """The stroke in [0, ``stroke``] where the deepest point first reaches the die, by
    bisection to :data:`BISECTION_TOLERANCE` of the interval (``distances(s, rows)``: the
    points' distances at s, ``at_stroke`` all of them at ``stroke``, some inside). A point
    moves by |s − s′| between strokes s and s′, so its distance does too: one that is farther
    out at the interval's top than the interval is long stays out over all of it and is
    dropped (the same signs, so the same answer, from fewer and fewer points)."""
    rows, top = np.arange(len(at_stroke)), at_stroke
    lo, hi = 0.0, stroke
    tolerance = BISECTION_TOLERANCE * stroke
    while hi - lo > tolerance:
        keep = top <= hi - lo
        rows, top = rows[keep], top[keep]
        mid = 0.5 * (lo + hi)
        d = distances(mid, rows)
        if -d.min() <= 0.0:
            lo = mid
        else:
            hi, top = mid, d
    return lo


DIE_SPACING = 0.25
"""Spacing of the points sampled near an analytic punch for the die check, in die lip radii."""
GRID_POINTS = 2_000_000
"""Most grid points sampled near an analytic punch for the die check (the spacing grows)."""
E_Z = np.array([0.0, 0.0, 1.0])


def stroke_check(punch: ToolSurface, die: ToolSurface, face: float, lip: float, reach: float):
    """A function of the stroke that refuses one driving ``punch`` into ``die`` (face at z =
    ``face``, lip radius ``lip``; :func:`check_stroke`), for strokes up to ``reach``.

    The punch's points are sampled once (:func:`surface_points`), :data:`DIE_SPACING` lip radii
    apart: on a triangle mesh's triangles, or near an analytic punch on a grid (coarser if the
    box would hold more than :data:`GRID_POINTS`), in the layer of the punch that a stroke up
    to ``reach`` brings to the die (from its face less ``reach`` to the top of its lip, or of
    a die given as a surface). The first contact between samples is missed by at most about
    spacing² over the lip radius."""
    bounds = getattr(punch, "bounds", lambda: None)()
    lo, hi = (-punch.size, punch.size) if bounds is None else (bounds[0], bounds[1])
    if getattr(punch, "vertices", None) is not None:
        lo, hi = -np.inf, np.inf  # every vertex in the layer, wherever the mesh lies
    top = getattr(die, "bounds", lambda: None)()
    top = face + 2.0 * lip if top is None else top[1][2]
    lower = np.array([*np.broadcast_to(lo, 3)[:2], face - reach])
    upper = np.array([*np.broadcast_to(hi, 3)[:2], top])
    spacing = DIE_SPACING * lip
    if np.isfinite(lower).all() and np.isfinite(upper).all():
        spacing = max(spacing, (np.prod(upper - lower) / GRID_POINTS) ** (1 / 3))
    points = surface_points(punch, lower, upper, spacing)

    def check(stroke: float) -> None:
        check_stroke(punch, die, points, E_Z, stroke, near=2.0 * spacing)

    return check


MIRROR_TOLERANCE = 1e-6
"""How far (in the tool's sizes) the mirror image of an analytic tool's point may lie off it."""
MIRROR_EDGE_FRACTION = 0.1
"""The same for a triangle mesh, in its median edge length: a mirror-symmetric shape
triangulated without mirror symmetry puts a vertex's image on the other side's facets within
their sagitta L²/8R, below a tenth of an edge where edges are shorter than the radius (a flat
part's long edges have no sagitta, and the median leaves them out)."""


def mirror_asymmetry(tool: ToolSurface, samples: int = 4000) -> str | None:
    """Why the tool is not mirror-symmetric about the planes x = 0 and y = 0, or None: the
    mirror images of points on it (a triangle mesh's vertices; points projected onto an
    analytic shape) must lie on it, within :data:`MIRROR_TOLERANCE` of its size or
    :data:`MIRROR_EDGE_FRACTION` of a mesh's median edge (a vertex whose image is within that
    of a vertex is on it: a mesh triangulated symmetrically costs a k-d tree query)."""
    if getattr(tool, "vertices", None) is not None:
        points = tool.vertices
        corners = tool.vertices[tool.faces]
        edge = np.median(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2))
        tolerance = MIRROR_EDGE_FRACTION * edge
    else:
        bounds = getattr(tool, "bounds", lambda: None)()
        lo, hi = (-tool.size, tool.size) if bounds is None else bounds
        points = np.random.default_rng(0).uniform(lo, hi, (samples, 3))
        for _ in range(2):
            points = points - tool.signed_distance(points)[:, None] * tool.normal(points)
        tolerance = MIRROR_TOLERANCE * tool.size
    tree = cKDTree(points) if getattr(tool, "vertices", None) is not None else None
    for axis in (0, 1):
        image = points * np.where(np.arange(3) == axis, -1.0, 1.0)
        off = np.zeros(len(image))
        # a vertex whose image is a vertex lies on the mesh: only the others are measured
        rest = slice(None) if tree is None else tree.query(image)[0] > tolerance
        off[rest] = np.abs(tool.signed_distance(image[rest]))
        k = int(np.argmax(off))
        if off[k] > tolerance:
            return (
                f"{tool.name} is not mirror-symmetric about {'xy'[axis]} = 0: the image of its "
                f"point {np.round(points[k], 6).tolist()} lies {off[k]:.3g} mm off it"
            )
    return None
