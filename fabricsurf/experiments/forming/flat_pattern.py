"""The flat pattern of a formed part (docs/forming.md, "What a forming run hands on"): the outline
in the flat blank of the material that ends on a trim line of the part, i.e. the blank a cutter
would need to make the trimmed part with no waste.

A trim line is a level set of a function of the deformed position r = X + u: a height above
the blank's plane (``height``: the part is kept where r_z ≥ z_t) or a distance from the punch
axis (``radius``: kept where √(r_x² + r_y²) ≤ ρ_t). Its pull-back φ(X) = trim(r(X)) is
interpolated at the vertices of the reference mesh (continuous P1) and the outline is φ's zero
contour, piecewise linear over each cell (marching triangles): the image of every outline
point lies on the trim line to the P1 interpolation error of φ, O(h²) times its curvature. A
blank solved on one quarter is unfolded by mirroring the outline about both mid-lines. The
inextensible drape gives a check: a fibre through the pole of a hemisphere lies on a meridian,
unstretched and unsheared, so along it the pattern reaches the arc length R φ_t to the trim
(Mack & Taylor 1956).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem

from fabricsurf.discretise.evaluation import interpolate_expression

TRIMS = ("height", "radius")
"""The kinds of trim line (module docstring)."""


def trim_field(plugin, kind: str, value: float) -> fem.Function:
    """φ (P1 on the reference mesh): ≥ 0 where the part is kept (module docstring)."""
    if kind not in TRIMS:
        raise ValueError(f"flat pattern: trim {kind!r} is not one of {', '.join(TRIMS)}")
    r = plugin.r
    phi = r[2] - value if kind == "height" else value - ufl.sqrt(r[0] ** 2 + r[1] ** 2)
    V = fem.FunctionSpace(plugin.problem.msh, ("CG", 1))
    return interpolate_expression(phi, V, "trim")


def _segments(phi: fem.Function) -> np.ndarray:
    """The zero contour of ``phi`` over this rank's owned cells: k × 2 × 2 (segment, end, X)."""
    msh = phi.function_space.mesh
    dofs = phi.function_space.dofmap.list.array.reshape(-1, 3)
    x = phi.function_space.tabulate_dof_coordinates()[:, :2]
    owned = msh.topology.index_map(msh.topology.dim).size_local
    out = []
    for cell in dofs[:owned]:
        v = phi.x.array[cell]
        if v.min() >= 0.0 or v.max() < 0.0:
            continue
        ends = []
        for a, b in ((0, 1), (1, 2), (2, 0)):
            i, j = sorted((cell[a], cell[b]), key=lambda k: tuple(x[k]))  # same on every rank
            if (phi.x.array[i] >= 0.0) != (phi.x.array[j] >= 0.0):
                t = phi.x.array[i] / (phi.x.array[i] - phi.x.array[j])
                ends.append(x[i] + t * (x[j] - x[i]))
        if len(ends) == 2:
            out.append(ends)
    return np.array(out, float).reshape(-1, 2, 2)


def flat_pattern(plugin, kind: str = "height", value: float = 0.0) -> np.ndarray:
    """The outline's segments (k × 2 × 2, reference X in mm) of the whole blank, the same on
    every rank: the quarter's mirrored about both mid-lines when a quarter was solved.
    Collective."""
    comm = plugin.problem.msh.comm
    seg = np.vstack(comm.allgather(_segments(trim_field(plugin, kind, value))))
    if getattr(plugin, "domain", "full") == "quarter":
        seg = np.vstack([seg * m for m in ((1, 1), (-1, 1), (1, -1), (-1, -1))])
    return seg


def reach(seg: np.ndarray, direction_deg: float, width_deg: float = 5.0) -> float:
    """The largest distance from the centre of the outline's points within ``width_deg`` of
    the reference direction ``direction_deg`` (mm; NaN if none)."""
    p = seg.reshape(-1, 2)
    ang = np.degrees(np.arctan2(p[:, 1], p[:, 0]))
    near = np.abs((ang - direction_deg + 180.0) % 360.0 - 180.0) <= width_deg
    return float(np.linalg.norm(p[near], axis=1).max()) if near.any() else float("nan")


def write_pattern(seg: np.ndarray, path: str | Path, comm) -> None:
    """The segments as CSV rows X0, Y0, X1, Y1 (mm), written on rank 0."""
    if comm.rank != 0:
        return
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["X0_mm", "Y0_mm", "X1_mm", "Y1_mm"])
        w.writerows([[f"{a:.9g}" for a in s.ravel()] for s in seg])
