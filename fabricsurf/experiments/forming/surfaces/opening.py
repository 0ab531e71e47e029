"""The opening of the die and the blank holder: a planar outline about the punch axis, given by
its signed distance σ(x, y) in the plane of the plates (negative inside the opening), in numpy
for the checks (the same in UFL for the contact forms: opening_form.py).

Every part of the two plates is a function of σ (docs/tool_surfaces.md, "The die's opening"):
the flat face lies beyond σ = r_d (r_d the lip radius), the lip is the tube of radius r_d about
the curve σ = r_d one lip radius off the face, and the holder's pressure rises from σ = 2 r_d to
3 r_d. With the gradient g = ∇σ (a unit vector), the lip's distance √((σ − r_d)² + Δz²) − r_d and
its normal ((σ − r_d) g, Δz) / √((σ − r_d)² + Δz²) are exact wherever σ − r_d is the distance to
that curve, i.e. outside the opening and inside it short of its medial axis (for a convex
outline, of its centre lines), farther from the lip than any sheet reaches.

Two outlines:

* a circle of radius R_o: σ = ρ − R_o (ρ the distance from the axis, regularised on it as the
  punch's);
* a rectangle of sides 2a (along x) × 2b (along y) with corner radius r_c ≤ min(a, b), the
  distance to the rectangle of half-sides (a − r_c, b − r_c), minus r_c (analytic.py's rounded
  shapes): with q = (|x| − (a − r_c), |y| − (b − r_c)), σ = |max(q, 0)| + min(max(q_x, q_y), 0)
  − r_c. r_c = min(a, b) gives a slot with round ends; a = b = r_c the circle again, by the
  rectangle's formula. |max(q, 0)| is regularised as √(|max(q, 0)|² + δ²), δ = 10⁻⁹ (a + b):
  off by at most δ where it is zero, and with a finite gradient there.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.errors import InputError

AXIS_EPS = 1e-12
"""Regularisation of the distance from the axis, relative to the circle's radius squared."""
CORNER_EPS = 1e-9
"""Regularisation δ of the rectangle's outer distance, relative to a + b."""
KINDS = ("circle", "rectangle")


class Opening:
    """The opening's outline (module docstring): ``kind`` "circle" (radius ``half_length`` =
    ``half_width`` = ``corner``) or "rectangle" (half-sides ``half_length`` along x and
    ``half_width`` along y, corner radius ``corner``), centred on the punch axis, in mm."""

    def __init__(self, kind: str, half_length: float, half_width: float, corner: float) -> None:
        a, b, c = float(half_length), float(half_width), float(corner)
        if kind not in KINDS:
            raise InputError(f"die opening: kind {kind!r} is not one of {', '.join(KINDS)}")
        if not (a > 0 and b > 0 and 0 <= c <= min(a, b)):
            raise InputError(
                f"die opening {2 * a:g} × {2 * b:g} mm with corner radius {c:g} mm: the sides "
                "must be positive and the corner radius between 0 and half the shorter side"
            )
        if kind == "circle" and not a == b == c:
            raise InputError(f"die opening: a circle has one radius, not {a:g}, {b:g}, {c:g}")
        self.kind, self.half_length, self.half_width, self.corner = kind, a, b, c

    @classmethod
    def circle(cls, radius: float) -> Opening:
        return cls("circle", radius, radius, radius)

    @property
    def name(self) -> str:
        if self.kind == "circle":
            return f"circular opening of radius {self.half_length:g} mm"
        return (
            f"opening {2 * self.half_length:g} × {2 * self.half_width:g} mm with corner "
            f"radius {self.corner:g} mm"
        )

    @property
    def inner_reach(self) -> float:
        """The distance from the axis to the nearest point of the outline (mm)."""
        return min(self.half_length, self.half_width)

    @property
    def outer_reach(self) -> float:
        """The distance from the axis to the farthest point of the outline (mm)."""
        a, b, c = self.half_length, self.half_width, self.corner
        return float(np.hypot(a - c, b - c) + c)

    def sigma(self, xy) -> np.ndarray:
        """σ at points (m, ≥ 2; the first two columns are x, y)."""
        return self.evaluate(xy)[0]

    def gradient(self, xy) -> np.ndarray:
        """∇σ (m, 2), a unit vector."""
        return self.evaluate(xy)[1]

    def evaluate(self, xy) -> tuple[np.ndarray, np.ndarray]:
        """(σ, ∇σ) at points (m, ≥ 2)."""
        xy = np.atleast_2d(np.asarray(xy, float))[:, :2]
        if self.kind == "circle":
            rho = np.sqrt((xy**2).sum(axis=1) + AXIS_EPS * self.corner**2)
            return rho - self.corner, xy / rho[:, None]
        a, b, c = self.half_length, self.half_width, self.corner
        delta = CORNER_EPS * (a + b)
        q = np.abs(xy) - np.array([a - c, b - c])
        m = np.maximum(q, 0.0)
        out = np.sqrt((m**2).sum(axis=1) + delta**2)
        sigma = out + np.minimum(q.max(axis=1), 0.0) - c
        inner = np.where((q[:, 0] > q[:, 1])[:, None], [1.0, 0.0], [0.0, 1.0])
        g = np.where(((m**2).sum(axis=1) > 0)[:, None], m / out[:, None], inner)
        return sigma, g * np.where(xy < 0, -1.0, 1.0)
