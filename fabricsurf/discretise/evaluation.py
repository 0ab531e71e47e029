"""Evaluation of functions at points in parallel (owned cells only, gathered on every rank)."""

from __future__ import annotations

import basix
import numpy as np
import ufl
from dolfinx import fem, geometry, la
from mpi4py import MPI


def _owned_cells_at(msh, points3: np.ndarray) -> list[list[int]]:
    """For each point the local indices of the owned cells containing it (maybe none)."""
    tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
    candidates = geometry.compute_collisions(tree, points3)
    colliding = geometry.compute_colliding_cells(msh, candidates, points3)
    n_owned = msh.topology.index_map(msh.topology.dim).size_local
    return [[c for c in colliding.links(i) if c < n_owned] for i in range(len(points3))]


def eval_points(f: fem.Function, points: np.ndarray) -> np.ndarray:
    """Values of ``f`` at ``points`` (n×2), the same on every rank; NaN where outside the mesh.

    The value is the mean over all (owned) cells containing the point, over all ranks: for a
    continuous f the same value, for a cellwise field (DG, or a gradient) at a vertex or on a
    facet a partition-independent average, so 1 and P ranks agree.
    """
    msh = f.function_space.mesh
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"eval_points: points must be an (n, 2) array, got shape {pts.shape}")
    pts3 = np.zeros((len(pts), 3))
    pts3[:, :2] = pts
    cells = _owned_cells_at(msh, pts3)
    bs = f.function_space.dofmap.index_map_bs
    sums = np.zeros((len(pts), bs))
    counts = np.zeros(len(pts))
    rows = [i for i, cs in enumerate(cells) for _ in cs]
    if rows:
        flat = np.array([c for cs in cells for c in cs], dtype=np.int32)
        vals = f.eval(pts3[rows], flat).reshape(-1, bs)
        np.add.at(sums, rows, vals)
        np.add.at(counts, rows, 1.0)
    total, n = np.empty_like(sums), np.empty_like(counts)
    msh.comm.Allreduce(sums, total, op=MPI.SUM)
    msh.comm.Allreduce(counts, n, op=MPI.SUM)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n[:, None] > 0, total / n[:, None], np.nan)


def interpolate_expression(expr, V: fem.FunctionSpace, name: str = "") -> fem.Function:
    """Interpolate a UFL expression into V (e.g. a DG space for cellwise quantities)."""
    f = fem.Function(V, name=name)
    f.interpolate(fem.Expression(expr, V.element.interpolation_points()))
    return f


def quadrature_expression(expr, msh, degree: int) -> fem.Expression:
    """``expr`` compiled for evaluation at the degree-``degree`` quadrature points of a cell."""
    cell = basix.cell.string_to_type(msh.topology.cell_name())
    return fem.Expression(expr, basix.make_quadrature(cell, degree)[0])


def max_over_cells(expression: fem.Expression, msh) -> float:
    """The largest value of a scalar fem.Expression at its points in the owned cells of all
    ranks."""
    cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
    local = float(expression.eval(cells).max()) if len(cells) else -np.inf
    return msh.comm.allreduce(local, op=MPI.MAX)


def nodal_average(expr, msh, degree: int) -> fem.Function:
    """The lumped L² projection of a (cellwise) scalar UFL expression onto continuous P1:
    at each vertex ∫ expr φ_i dx / ∫ φ_i dx, the area-weighted average over the cells around
    it (``degree``: the quadrature degree). A field that is nearly constant per cell and jumps
    between cells (e.g. the shear of a stiff net) becomes the continuous field a post-processor
    shows; for a smooth field it is a second-order accurate recovery."""
    V = fem.FunctionSpace(msh, ("CG", 1))
    v = ufl.TestFunction(V)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": degree})
    num, den = (fem.assemble_vector(fem.form(f * v * dx)) for f in (expr, 1.0))
    for b in (num, den):
        b.scatter_reverse(la.ScatterMode.add)
        b.scatter_forward()
    out = fem.Function(V)
    out.x.array[:] = num.array / den.array
    return out
