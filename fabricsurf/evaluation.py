"""Evaluation of functions at points in parallel (owned cells only, gathered on every rank)."""

from __future__ import annotations

import numpy as np
from dolfinx import fem, geometry
from mpi4py import MPI


def _owned_cells_at(msh, points3: np.ndarray) -> np.ndarray:
    """For each point the local index of an owned cell containing it, or -1."""
    tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
    candidates = geometry.compute_collisions(tree, points3)
    colliding = geometry.compute_colliding_cells(msh, candidates, points3)
    n_owned = msh.topology.index_map(msh.topology.dim).size_local
    cells = np.full(len(points3), -1, dtype=np.int32)
    for i in range(len(points3)):
        owned = [c for c in colliding.links(i) if c < n_owned]
        if owned:
            cells[i] = owned[0]
    return cells


def eval_points(f: fem.Function, points: np.ndarray) -> np.ndarray:
    """Values of ``f`` at ``points`` (n×2), the same on every rank; NaN where outside the mesh.

    A point on a facet shared by two ranks is taken from the lowest rank owning a cell there.
    """
    msh = f.function_space.mesh
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pts3 = np.zeros((len(pts), 3))
    pts3[:, :2] = pts
    cells = _owned_cells_at(msh, pts3)
    bs = f.function_space.dofmap.index_map_bs
    local = np.full((len(pts), bs), np.nan)
    found = cells >= 0
    if found.any():
        local[found] = f.eval(pts3[found], cells[found]).reshape(-1, bs)
    comm = msh.comm
    owner = np.where(found, comm.rank, comm.size).astype(np.int64)
    first = np.empty_like(owner)
    comm.Allreduce(owner, first, op=MPI.MIN)
    mine = found & (first == comm.rank)
    contrib = np.ascontiguousarray(np.where(mine[:, None], np.nan_to_num(local), 0.0))
    values = np.empty_like(contrib)
    comm.Allreduce(contrib, values, op=MPI.SUM)
    values[first == comm.size] = np.nan
    return values


def interpolate_expression(expr, V: fem.FunctionSpace, name: str = "") -> fem.Function:
    """Interpolate a UFL expression into V (e.g. a DG space for cellwise quantities)."""
    f = fem.Function(V, name=name)
    f.interpolate(fem.Expression(expr, V.element.interpolation_points()))
    return f
