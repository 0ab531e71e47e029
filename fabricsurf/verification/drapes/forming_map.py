"""The continuum forming result over the whole contact area, against both kinematic drapes
(drape_map.py): the recovered shear angle and the gap to the punch at a grid of reference points
of the solved quarter or full blank, the points on the punch compared with the fishnet and the
Goursat net drawn with the experiment's fibre directions from the pole, or with the
continuum's own generators (generator_drape.py) where those are not geodesics."""

from __future__ import annotations

import math

import numpy as np

from fabricsurf.discretise.evaluation import eval_points, nodal_average
from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE
from fabricsurf.experiments.forming import blank as forming_blank
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.verification.drapes import generator_drape
from fabricsurf.verification.drapes.drape_map import shear_difference_map

TOUCH_FRACTION = 0.01
"""Points within this fraction of R of the punch's cap count as on it (as along the diagonal,
fabricsurf/studies/hemisphere_forming.py)."""


def contact_map(e: HemispherePlugin, n: int = 41) -> dict[str, np.ndarray]:
    """On a grid of reference points of the solved domain, n points per half side (the quarter
    [0, B/2]², or the full blank, 2n − 1 per side, the points inside its outline): the recovered
    shear angle (deg, evaluation.nodal_average, the continuous field compared along the
    diagonal), the gap to the punch's cap (mm; inf below the punch centre), whether the point is
    on the punch (gap < TOUCH_FRACTION · R) and whether it lies within h of a mirror line that
    is a fibre (the quarter at 0/90°: the shear is odd across x = 0 and y = 0, zero on them, but
    the nodal average there sees the cells of one side only, an error of the size of the shear
    one cell away, docs/forming.md). The same on every rank."""
    pts = _grid(e, n)
    kin = e.problem.energy.kin
    rec = nodal_average(kin.gamma * (180.0 / math.pi), e.specimen.mesh, CELL_QUADRATURE_DEGREE)
    r = np.column_stack([pts, np.zeros(len(pts))]) + eval_points(e.problem.u, pts)
    r[:, 2] -= float(e.tools.stroke.value) - e.R
    dist = np.linalg.norm(r, axis=1)
    gap = np.where(r[:, 2] > 0, dist - e.R, np.inf)
    band = (e.domain == "quarter") & (e.theta == 0.0) & (pts.min(axis=1) < e.h)
    return {
        "points": pts,
        "shear_deg": eval_points(rec, pts)[:, 0],
        "gap": gap,
        "on": gap < TOUCH_FRACTION * e.R,
        "mirror_band": band,
    }


def _grid(e: HemispherePlugin, n: int) -> np.ndarray:
    """The reference points of :func:`contact_map`."""
    a, b = 0.5 * e.setup.length, 0.5 * e.setup.width
    if e.domain == "quarter":
        x = y = np.linspace(0.0, a, n)
    else:
        x, y = np.linspace(-a, a, 2 * n - 1), np.linspace(-b, b, 2 * n - 1)
    pts = np.column_stack([g.ravel() for g in np.meshgrid(x, y, indexing="ij")])
    if forming_blank.shape(e.setup) == "circle":
        pts = pts[np.hypot(*pts.T) <= a * (1 - 1e-9)]
    return pts


def compare_with_drapes(e: HemispherePlugin, n: int = 41, a: float | None = None) -> dict:
    """:func:`contact_map` against both drapes (drape_map.shear_difference_map) over the points
    on the punch outside the mirror band, the drapes' fibres at the experiment's angles;
    ``excluded``: the points on the punch in the band."""
    m = contact_map(e, n)
    out = shear_difference_map(
        e.R,
        m["points"],
        m["shear_deg"],
        tuple(e.setup.fibre_angles_deg),
        m["on"] & ~m["mirror_band"],
        a,
    )
    return {**out, "excluded": int((m["on"] & m["mirror_band"]).sum())}


def compare_with_generator_drape(e: HemispherePlugin, n: int = 41, a: float | None = None) -> dict:
    """:func:`contact_map` against the drape closed from the continuum's own fibres through
    the pole (generator_drape.compare), cell ``a`` (default R/40), over the points on the punch
    outside the mirror band that the generators' contact covers."""
    if e.domain == "quarter":
        raise ValueError(
            "generator drape: the quarter's fibres through the pole are mirror "
            "lines of the set-up, so geodesics: compare_with_drapes is the check"
        )
    m = contact_map(e, n)
    a = e.R / 40.0 if a is None else a
    return generator_drape.compare(
        m["points"],
        m["shear_deg"],
        m["on"] & ~m["mirror_band"],
        e.problem.u,
        float(e.tools.stroke.value),
        e.R,
        tuple(e.setup.fibre_angles_deg),
        a,
        TOUCH_FRACTION * e.R,
    )
