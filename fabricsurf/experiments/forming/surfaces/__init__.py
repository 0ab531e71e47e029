"""Forming tools as surfaces: what the contact and the kinematic drape read of a punch, a die
or a blank holder is its signed distance (positive outside the tool) and outward normal at
any points (docs/tool_surfaces.md).

Analytic shapes (``analytic.py``: the sphere, the forming plug-in's hemispherical punch, the
cylinder and the box with fillet radii, the cone), triangle meshes (``triangulated.py``, with
their connectivity checks in ``topology.py`` and the closest point on a triangle in
``closest.py``) read from STL or OBJ files in stated units (``files.py``) or taken from a
gmsh model (``meshes.py``, which also triangulates the analytic shapes for checks), the
checks of a tool set against the blank and the stroke (``checks.py``), and the opening of the
die and the holder, a circle or a rectangle with rounded corners (``opening.py``, in UFL
``opening_form.py``).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class ToolSurface(Protocol):
    """A rigid tool's surface, in mm: ``name`` (for messages), ``size`` (its largest extent,
    or a characteristic length of an unbounded shape: the scale check compares it with the
    blank's), the signed distance (m,) and the
    outward unit normal (m, 3) at points (m, 3), vectorised, and the normal for geometric
    constructions (``smooth_normal``: the interpolated vertex normals of a triangle mesh, the
    normal itself for an analytic shape)."""

    name: str
    size: float

    def signed_distance(self, x: np.ndarray) -> np.ndarray: ...

    def normal(self, x: np.ndarray) -> np.ndarray: ...

    def smooth_normal(self, x: np.ndarray) -> np.ndarray: ...
