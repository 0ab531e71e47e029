"""The bias test's own variants that may separate two tied effects (docs/diagnosis.md,
"Separating a tie"): other fibre angles, a narrower specimen and, for a tie between
first-gradient effects, a picture-frame test to the shear angle the bias test reaches in its
zone C (Cao et al. 2008, eq. 13). The frame's exact solution is a homogeneous shear, in which
every second-gradient energy vanishes, so it cannot separate two of those."""

from __future__ import annotations

import math

import numpy as np

from fabricsurf.experiments.base import PluginSetup, Variant
from fabricsurf.experiments.picture_frame import frame_displacement
from fabricsurf.experiments.three_zone import zone_c_shear_angle

PAIRED_ANGLE_TOLERANCE = 7.5
"""Fibres within this many degrees of ±45° are tried at ±30°; others at ±45°."""


def bias_variants(setup: PluginSetup, path, first_gradient: bool) -> list[Variant]:
    """Other fibre angles, half the width and (``first_gradient``) the picture frame."""
    L, W, ang = setup.length, setup.width, setup.fibre_angles_deg
    path = np.asarray(path, float)
    near_45 = abs(abs(ang[0]) - 45.0) < PAIRED_ANGLE_TOLERANCE
    other = (30.0, -30.0) if near_45 else (45.0, -45.0)
    out = [
        Variant(
            "other_fibre_angle",
            f"the same bias test with the fibres at ±{other[0]:g}°",
            L,
            W,
            path,
            other,
        ),
        Variant(
            "narrower_specimen",
            f"the same bias test on a specimen half as wide ({L:g} × {W / 2:g} mm)",
            L,
            W / 2,
            path,
            ang,
        ),
    ]
    if first_gradient:
        gamma = (
            float(np.nan_to_num(zone_c_shear_angle(path[-1], L, W), nan=math.pi / 2))
            if L > W
            else 0.2
        )  # beyond the lock: 90°
        d = frame_displacement(max(gamma, 0.05), W)
        out.append(
            Variant(
                "picture_frame",
                f"a picture-frame test (clamped frame, side {W:g} "
                f"mm, fibres along the bars) to the same shear angle "
                f"({math.degrees(gamma):.3g}°, crosshead {d:.3g} mm)",
                W,
                W,
                path / path[-1] * d,
                (0.0, 90.0),
                "picture_frame",
                {"frame": "clamped"},
            )
        )
    return out
