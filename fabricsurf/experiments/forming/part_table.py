"""The formed part as a table for structural analysis (docs/forming.md, "What a forming run hands
on"): one row per element of the whole part with its deformed centroid, unit normal, the two
deformed fibre directions and the shear angle, in plain CSV that any mapping tool reads.

Each element's row is evaluated at its reference centroid X: the position x = X + u, the normal
n = FL × FM / |FL × FM| (Steigmann & dell'Isola 2015 eq. 16), the fibre directions
l = FL/|FL|, m = FM/|FM| and the shear angle γ (:mod:`fabricsurf.model.kinematics`). A blank
solved on one quarter (mirror symmetry about x = 0 and y = 0 of its mesh) is unfolded into the
whole part: the mirror image about x = 0 of the element at X has X' = R₂X, deformation gradient
F'(X') = R F(X) R₂ (R = diag(−1, 1, 1), R₂ = diag(−1, 1)), so its fibre directions are
R F(X) R₂L and R F(X) R₂M normalised, its normal R n (the mirror keeps n_z) and its shear
angle γ(X) (a mirror maps the pair of fibres onto itself); likewise about y = 0, and both.
"""

from __future__ import annotations

import csv
from pathlib import Path

import basix
import numpy as np
import ufl
from dolfinx import fem

COLUMNS = (
    "X",
    "Y",
    "x",
    "y",
    "z",
    "n_x",
    "n_y",
    "n_z",
    "l_x",
    "l_y",
    "l_z",
    "m_x",
    "m_y",
    "m_z",
    "shear_deg",
)
"""The table's columns: reference centroid (mm), deformed centroid (mm), unit normal, unit
fibre directions L and M deformed, shear angle (deg)."""


def _centroid_values(plugin) -> np.ndarray:
    """Per owned element: X (2), x (3), F (3×2 row-major), L (2), M (2), γ."""
    kin = plugin.problem.energy.kin
    msh = plugin.problem.msh
    X = ufl.SpatialCoordinate(msh)
    F = kin.F
    expr = ufl.as_vector(
        [X[0], X[1]]
        + [plugin.r[i] for i in range(3)]
        + [F[i, a] for i in range(3) for a in range(2)]
        + [kin.L[0], kin.L[1], kin.M[0], kin.M[1], kin.gamma]
    )
    cell = basix.cell.string_to_type(msh.topology.cell_name())
    e = fem.Expression(expr, basix.make_quadrature(cell, 0)[0])
    cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
    return np.asarray(e.eval(cells), float).reshape(len(cells), -1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _rows(v: np.ndarray, mirror: tuple[float, float]) -> np.ndarray:
    """The rows of the elements ``v`` (:func:`_centroid_values`) mirrored by R₂ = diag(mirror)."""
    R2 = np.diag(mirror)
    R = np.diag([*mirror, 1.0])
    X, x = v[:, 0:2] @ R2, v[:, 2:5] @ R
    F = v[:, 5:11].reshape(-1, 3, 2)
    L, M = v[0, 11:13], v[0, 13:15]
    FR = np.einsum("ij,njk,kl->nil", R, F, R2)
    fl, fm = FR @ L, FR @ M
    n = _unit(np.cross(F @ L, F @ M)) @ R
    return np.column_stack([X, x, n, _unit(fl), _unit(fm), np.degrees(v[:, 15])])


def part_rows(plugin) -> np.ndarray | None:
    """The table of the whole part (module docstring) on rank 0 (elements in the order of the
    ranks, then of the mirror images), None on the other ranks. Collective."""
    comm = plugin.problem.msh.comm
    parts = comm.gather(_centroid_values(plugin), root=0)
    if comm.rank != 0:
        return None
    v = np.vstack(parts)
    if getattr(plugin, "domain", "full") != "quarter":
        return _rows(v, (1.0, 1.0))
    mirrors = ((1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0))
    return np.vstack([_rows(v, m) for m in mirrors])


def write_part_table(plugin, path: str | Path) -> int:
    """Write :func:`part_rows` to the CSV ``path`` on rank 0 (a header of :data:`COLUMNS`;
    written whole, to a temporary name first); the number of rows, on every rank."""
    rows = part_rows(plugin)
    comm = plugin.problem.msh.comm
    n = 0
    if comm.rank == 0:
        path = Path(path)
        tmp = path.with_name(path.name + ".part")
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(COLUMNS)
            w.writerows([[f"{a:.9g}" for a in r] for r in rows])
        tmp.replace(path)
        n = len(rows)
    return comm.bcast(n, root=0)


def fibre_angle_deg(rows: np.ndarray) -> np.ndarray:
    """The angle between the two fibre directions of each row (deg): 90° − γ for fibres that
    start perpendicular (a check of a table against its own shear column)."""
    c = np.clip(np.sum(rows[:, 8:11] * rows[:, 11:14], axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(c))
