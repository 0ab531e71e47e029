"""Tools given as analytic shapes: exact signed distances (positive outside) and their
gradients, the outward normals, vectorised over points (m, 3), in mm.

The sphere |x − c| − R; the forming plug-in's punch, a hemisphere on a cylinder of the same
radius (experiments/forming/tools.py, Tools.punch: |x − c| − R above the centre, ρ − R below)
and its die (Tools._plate); a cone; and the rounded shapes as the distance to a shape shrunk
by the fillet radius r, minus r (the set of points within r of a convex shape, its Minkowski
sum with a ball of radius r, is the shape grown by r with every edge and corner rounded to
radius r): a box with fillet radius r is the distance to the box of half-sizes b − r, minus r;
a cylinder with fillet radius r on its end edges is the 2D box distance in the meridian plane
(ρ, axial coordinate), shrunk by r, minus r. The distance to a box of half-sizes b at p
(centred) is |max(q, 0)| + min(max_i q_i, 0) with q = |p| − b.
"""

from __future__ import annotations

import math

import numpy as np

from fabricsurf.experiments.forming.surfaces.opening import Opening

AXIS_EPS = 1e-12
"""Regularisation of the distance from an axis (relative to the shape's size), as in Tools._rho."""


def _rows(x) -> np.ndarray:
    return np.atleast_2d(np.asarray(x, float))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class AnalyticSurface:
    """Base of the analytic shapes: the smooth normal is the gradient of the distance."""

    name = "analytic surface"
    size = 1.0

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The bounding box, or None for an unbounded shape."""
        return None

    def smooth_normal(self, x: np.ndarray) -> np.ndarray:
        """The normal (the gradient of the exact distance is smooth here)."""
        return self.normal(x)


class Sphere(AnalyticSurface):
    """|x − c| − R."""

    def __init__(self, R: float, centre=(0.0, 0.0, 0.0)) -> None:
        self.R, self.centre = float(R), np.asarray(centre, float)
        self.name, self.size = f"sphere of radius {R:g} mm", 2.0 * self.R

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.centre - self.R, self.centre + self.R

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        return np.linalg.norm(_rows(x) - self.centre, axis=1) - self.R

    def normal(self, x: np.ndarray) -> np.ndarray:
        return _unit(_rows(x) - self.centre)


class HemispherePunch(AnalyticSurface):
    """The forming plug-in's punch: a hemisphere of radius R, pole at z = ``pole``, on an
    unbounded cylinder of the same radius about the z axis (Tools.punch)."""

    def __init__(self, R: float, pole: float = 0.0) -> None:
        self.R, self.pole = float(R), float(pole)
        self.name, self.size = f"hemispherical punch of radius {R:g} mm", 2.0 * self.R

    def _parts(self, x):
        x = _rows(x)
        dz = x[:, 2] - (self.pole - self.R)
        rho = np.sqrt(x[:, 0] ** 2 + x[:, 1] ** 2 + (AXIS_EPS * self.R) ** 2)
        return x, dz, rho

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        _, dz, rho = self._parts(x)
        return np.where(dz > 0, np.hypot(rho, dz) - self.R, rho - self.R)

    def normal(self, x: np.ndarray) -> np.ndarray:
        x, dz, rho = self._parts(x)
        cap = _unit(np.column_stack([x[:, 0], x[:, 1], dz]))
        side = np.column_stack([x[:, 0] / rho, x[:, 1] / rho, np.zeros(len(x))])
        return np.where((dz > 0)[:, None], cap, side)


class DiePlate(AnalyticSurface):
    """The forming plug-in's die (Tools._plate of experiments/forming/tools.py, above the
    blank) about an opening (opening.py: an Opening, or a float, a circle's radius) with σ its
    signed distance in the plate's plane: the half-space z ≥ ``face`` beyond σ = lip, and the
    lip, the tube of radius ``lip`` about the curve σ = lip at z = face + lip, which leaves the
    opening at the face. Its distance is the contact's: exact outside the die, measured to the
    face or the tube inside it."""

    def __init__(self, opening, lip: float, face: float = 0.0) -> None:
        self.outline = opening if isinstance(opening, Opening) else Opening.circle(opening)
        self.lip, self.face = float(lip), float(face)
        self.name = f"plate with a {self.outline.name} and a lip of {lip:g} mm"
        self.size = 2.0 * (self.outline.outer_reach + self.lip)

    def _parts(self, x):
        x = _rows(x)
        sigma, g = self.outline.evaluate(x)
        a, b = sigma - self.lip, x[:, 2] - (self.face + self.lip)
        return x, g, a, b, a > 0

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        x, _, a, b, flat = self._parts(x)
        return np.where(flat, self.face - x[:, 2], np.hypot(a, b) - self.lip)

    def normal(self, x: np.ndarray) -> np.ndarray:
        x, g, a, b, flat = self._parts(x)
        lip = _unit(np.column_stack([a * g[:, 0], a * g[:, 1], b]))
        return np.where(flat[:, None], np.array([0.0, 0.0, -1.0]), lip)


def _box2(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(distance, gradient in q) of a box from q = |p| − b (last axis the components)."""
    out = np.maximum(q, 0.0)
    n_out = np.linalg.norm(out, axis=-1)
    inside = np.minimum(q.max(axis=-1), 0.0)
    g_in = np.eye(q.shape[-1])[np.argmax(q, axis=-1)]
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where((n_out > 0)[:, None], out / n_out[:, None], g_in)
    return n_out + inside, g


class RoundedBox(AnalyticSurface):
    """A box of half-sizes ``half`` about ``centre``, axis-aligned, its edges and corners
    rounded to the fillet radius r ≤ min(half) (module docstring)."""

    def __init__(self, half, fillet: float = 0.0, centre=(0.0, 0.0, 0.0)) -> None:
        self.half, self.r = np.asarray(half, float), float(fillet)
        self.centre = np.asarray(centre, float)
        if not 0.0 <= self.r <= self.half.min():
            raise ValueError(f"rounded box: need 0 ≤ fillet ≤ min half-size, got {fillet}")
        self.name = f"box {2 * self.half} mm, fillet {self.r:g} mm"
        self.size = float(2.0 * self.half.max())

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.centre - self.half, self.centre + self.half

    def _eval(self, x):
        p = _rows(x) - self.centre
        d, g = _box2(np.abs(p) - (self.half - self.r))
        return d - self.r, g * np.where(p < 0, -1.0, 1.0)

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        return self._eval(x)[0]

    def normal(self, x: np.ndarray) -> np.ndarray:
        return self._eval(x)[1]


class Cylinder(AnalyticSurface):
    """A cylinder of radius R about the axis through ``origin`` along ``axis``: unbounded
    (``length`` None) or of that length centred on ``origin`` with its end edges rounded to the
    fillet radius r (module docstring)."""

    def __init__(
        self, R: float, origin=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), length=None, fillet=0.0
    ) -> None:
        self.R, self.origin = float(R), np.asarray(origin, float)
        self.axis = np.asarray(axis, float) / np.linalg.norm(axis)
        self.length, self.r = (None if length is None else float(length)), float(fillet)
        if self.length is not None and not 0 <= self.r <= min(self.R, 0.5 * self.length):
            raise ValueError(f"cylinder: need 0 ≤ fillet ≤ min(R, length/2), got {fillet}")
        self.name = f"cylinder of radius {R:g} mm" + (f", length {length:g} mm" if length else "")
        self.size = 2.0 * self.R if length is None else max(2.0 * self.R, self.length)

    def _meridian(self, x):
        p = _rows(x) - self.origin
        h = p @ self.axis
        radial = p - h[:, None] * self.axis
        rho = np.sqrt(np.einsum("ij,ij->i", radial, radial) + (AXIS_EPS * self.R) ** 2)
        return h, rho, radial / rho[:, None]

    def _eval(self, x):
        h, rho, e = self._meridian(x)
        if self.length is None:
            return rho - self.R, e
        q = np.column_stack([rho - (self.R - self.r), np.abs(h) - (0.5 * self.length - self.r)])
        d, g = _box2(q)
        n = g[:, :1] * e + (g[:, 1] * np.sign(h))[:, None] * self.axis
        return d - self.r, n

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        return self._eval(x)[0]

    def normal(self, x: np.ndarray) -> np.ndarray:
        return self._eval(x)[1]


class Cone(AnalyticSurface):
    """The unbounded cone of half-angle α with its apex at ``apex``, opening along ``axis``;
    the distance in the meridian plane to its generatrix, or to the apex behind it."""

    def __init__(self, alpha: float, apex=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0)) -> None:
        self.alpha, self.apex = float(alpha), np.asarray(apex, float)
        self.axis = np.asarray(axis, float) / np.linalg.norm(axis)
        self.name = f"cone of half-angle {math.degrees(alpha):g} deg"
        self.size = 1.0

    def _eval(self, x):
        p = _rows(x) - self.apex
        h = p @ self.axis
        radial = p - h[:, None] * self.axis
        rho = np.sqrt(np.einsum("ij,ij->i", radial, radial) + AXIS_EPS**2)
        e = radial / rho[:, None]
        s, c = math.sin(self.alpha), math.cos(self.alpha)
        side = (rho * s + h * c) >= 0
        n_side = c * e - s * self.axis
        d = np.where(side, rho * c - h * s, np.linalg.norm(p, axis=1))
        return d, np.where(side[:, None], n_side, _unit(p))

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        return self._eval(x)[0]

    def normal(self, x: np.ndarray) -> np.ndarray:
        return self._eval(x)[1]


class Moved:
    """A surface translated by ``offset`` (mm): a tool at a stroke."""

    def __init__(self, surface, offset) -> None:
        self.surface, self.offset = surface, np.asarray(offset, float)
        self.name, self.size = surface.name, surface.size
        if getattr(surface, "near", None) is not None:
            self.near = self._near

    def _near(self, x: np.ndarray, cutoff: float):
        """The moved surface's ``near`` (TriangulatedSurface.near), for a mesh."""
        d, foot, n = self.surface.near(_rows(x) - self.offset, cutoff)
        return d, foot + self.offset, n

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        b = self.surface.bounds()
        return None if b is None else (b[0] + self.offset, b[1] + self.offset)

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        return self.surface.signed_distance(_rows(x) - self.offset)

    def normal(self, x: np.ndarray) -> np.ndarray:
        return self.surface.normal(_rows(x) - self.offset)

    def smooth_normal(self, x: np.ndarray) -> np.ndarray:
        return self.surface.smooth_normal(_rows(x) - self.offset)
