"""Profiles of a formed hemisphere (experiments/hemisphere.py): the shear along a reference ray
from the pole, with the arc length over the punch and the gap to it, and the element midpoints
on the diagonal of the aligned quarter (where a stiff net's per-element shear is read)."""

from __future__ import annotations

import math

import numpy as np

from fabricsurf.discretise.evaluation import eval_points, interpolate_expression, nodal_average
from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE
from fabricsurf.experiments.forming import blank as forming_blank
from fabricsurf.geometry.aligned import lattice_divisions, square_divisions


def element_centres(e) -> np.ndarray:
    """Reference distances from the pole of the midpoints of the mesh edges on the diagonal
    (the fibres' bisector, the ray at the plug-in's ``diagonal_deg``). With stiff fibres the
    shear of the discrete sheet is nearly constant on each element of the aligned mesh (it
    behaves as a pin-jointed net of cell size h) and jumps between elements: there an
    element's value stands for its mean."""
    if e.theta is None or forming_blank.shape(e.setup) != "square":
        raise ValueError(
            "element_centres: only on the aligned quarter's mesh (a square "
            "blank with fibres at ±θ or 0/90)"
        )
    half = 0.5 * e.setup.length
    if e.theta == 0.0:
        d = half / square_divisions(half, e.h)
        return np.arange(0.5 * d, half, d) * math.sqrt(2.0)
    dx = half / lattice_divisions(half, half, e.h, e.theta)[0]
    return np.arange(dx, half, 2.0 * dx)


def profile(
    e, direction_deg: float, X: np.ndarray | None = None, n: int = 40
) -> dict[str, np.ndarray]:
    """Along the reference ray from the pole at ``direction_deg`` (``diagonal_deg``:
    the fibres' bisector, the benchmarks' diagonal; a fibre's angle: that fibre), at
    reference distances ``X`` (default n points to the blank's edge): X, the arc length
    from the pole over the deformed sheet's polar angle about the punch centre, R·φ, the
    shear angle γ (deg), the recovered shear angle (deg: its area-weighted nodal average,
    evaluation.nodal_average, the continuous field a post-processor shows in place of the
    per-element staircase of a stiff net), and the gap to the punch's cap (mm; negative:
    penetration). The same on every rank."""
    t = math.radians(direction_deg)
    reach = forming_blank.reach(e.setup, direction_deg)
    X = np.linspace(0.0, reach, n) if X is None else np.asarray(X, dtype=float)
    n = len(X)
    pts = np.column_stack([X * math.cos(t), X * math.sin(t)])
    kin = e.problem.energy.kin
    gam = interpolate_expression(kin.gamma * (180.0 / math.pi), e._S)
    rec = nodal_average(kin.gamma * (180.0 / math.pi), e.specimen.mesh, CELL_QUADRATURE_DEGREE)
    r = np.column_stack([pts, np.zeros(n)]) + eval_points(e.problem.u, pts)
    r[:, 2] -= float(e.tools.stroke.value) - e.R
    dist = np.linalg.norm(r, axis=1)
    phi = np.arccos(np.clip(r[:, 2] / dist, -1.0, 1.0))
    return {
        "X": X,
        "arc": e.R * phi,
        "shear_deg": eval_points(gam, pts)[:, 0],
        "shear_recovered_deg": eval_points(rec, pts)[:, 0],
        "gap": np.where(r[:, 2] > 0, dist - e.R, np.inf),
    }
