"""From the camera's frame to the specimen's: scale (pixels or m to mm), image axes (y down)
to a right-handed frame, the origin, and the rotation that puts the specimen's X axis (from
the fixed grip to the moving one) along x.

``grip`` names the edge of the image (as seen, whatever the y direction of the export) where
the fixed grip is: "left" (X points right), "bottom" (X up), "right" (X left) or "top" (X down);
``angle_deg`` adds a counter-clockwise tilt of the specimen in the image. The specimen's Y axis
is X turned 90° counter-clockwise (as seen); ``origin`` is the point X = Y = 0 in the export's
own coordinates and unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fabricsurf.errors import DataError

GRIP_ANGLE = {"left": 0.0, "bottom": 90.0, "right": 180.0, "top": 270.0}
ANGLE_TOL_DEG = 1.0
"""A point cloud whose long axis is further than this from the specimen's axes, with no
``angle_deg`` given, is a camera tilt the user did not state (:meth:`Frame.check_tilt`)."""
MIN_ASPECT = 1.3
"""The long axis is taken from the cloud only when it is this much longer than wide (a square
cloud has no long axis)."""


@dataclass(frozen=True)
class Frame:
    """The camera-to-specimen map (module docstring). ``scale``: mm per export unit."""

    scale: float
    y_down: bool
    origin: tuple[float, float]
    grip: str = "left"
    tilt_deg: float | None = None

    @property
    def angle_rad(self) -> float:
        return math.radians(GRIP_ANGLE[self.grip] + (self.tilt_deg or 0.0))

    def _axes(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scaled, right-handed, rotated components of the vectors (a, b)."""
        a = a * self.scale
        b = (-self.scale if self.y_down else self.scale) * b
        c, s = math.cos(self.angle_rad), math.sin(self.angle_rad)
        return c * a + s * b, c * b - s * a

    def points(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Specimen coordinates (mm) of export coordinates."""
        ox, oy = self.origin
        return self._axes(x - ox, y - oy)

    def vectors(
        self, u: np.ndarray, v: np.ndarray, w: np.ndarray | None = None
    ) -> tuple[np.ndarray, ...]:
        """Specimen components (mm) of export displacements; w flips with y (right-handed)."""
        ux, uy = self._axes(u, v)
        if w is None:
            return ux, uy
        return ux, uy, (-self.scale if self.y_down else self.scale) * w

    def check_tilt(self, X: np.ndarray, Y: np.ndarray, name: str) -> None:
        """With no ``angle_deg`` given: a cloud (specimen coordinates) whose long axis is off
        the specimen's axes by more than ANGLE_TOL_DEG is a tilt the user did not state."""
        if self.tilt_deg is not None or len(X) < 3:
            return
        dx, dy = X - X.mean(), Y - Y.mean()
        cxx, cyy, cxy = float(dx @ dx), float(dy @ dy), float(dx @ dy)
        root = math.hypot(0.5 * (cxx - cyy), cxy)
        big, small = 0.5 * (cxx + cyy) + root, 0.5 * (cxx + cyy) - root
        if small <= 0 or math.sqrt(big / small) < MIN_ASPECT:
            return
        axis = math.degrees(0.5 * math.atan2(2 * cxy, cxx - cyy))
        off = (axis + 45.0) % 90.0 - 45.0
        if abs(off) > ANGLE_TOL_DEG:
            raise DataError(
                f"{name}: the point cloud's long axis lies {off:+.2f}° from the "
                f"specimen's axes in the frame given ([frame] grip = "
                f'"{self.grip}", no angle_deg): a rotated camera frame needs its '
                f"angle: give [frame] angle_deg = {off:.2f} (counter-clockwise, as "
                "seen in the image), or angle_deg = 0 to keep the frame as given"
            )

    def inverse_points(self, X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Export coordinates of specimen points (for writing synthetic exports)."""
        a, b = self.inverse_vectors(X, Y)
        return a + self.origin[0], b + self.origin[1]

    def inverse_vectors(self, ux: np.ndarray, uy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Export components of specimen vectors (the inverse of :meth:`vectors`, in-plane)."""
        c, s = math.cos(self.angle_rad), math.sin(self.angle_rad)
        a, b = c * ux - s * uy, s * ux + c * uy
        return a / self.scale, (-b if self.y_down else b) / self.scale
