"""Evaluation of functions at points in parallel (owned cells only, gathered on every rank)."""

from __future__ import annotations

import basix
import numpy as np
import ufl
from dolfinx import fem, geometry, la
from mpi4py import MPI
from scipy import sparse

from fabricsurf.model.kinematics import Kinematics


def _owned_cells_at(msh, points3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(row, cell): every pair of a point (its row in ``points3``) and a local owned cell
    containing it (a point on a facet or vertex has several, one outside the mesh none), from
    the collision lists' flat arrays (no Python loop over the points)."""
    tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
    candidates = geometry.compute_collisions(tree, points3)
    colliding = geometry.compute_colliding_cells(msh, candidates, points3)
    n_owned = msh.topology.index_map(msh.topology.dim).size_local
    rows = np.repeat(np.arange(len(points3)), np.diff(colliding.offsets))
    cells = np.asarray(colliding.array, dtype=np.int32)
    keep = cells < n_owned
    return rows[keep], cells[keep]


def _basis_matrix(
    V: fem.FunctionSpace, points3: np.ndarray, rows: np.ndarray, cells: np.ndarray, n: int
) -> sparse.csr_matrix | None:
    """B (n points × local nodes of ``V``, each node a block of ``bs`` dofs): the sum over the
    (point ``rows``, owned ``cells``) pairs of the cell's scalar basis functions at the point,
    so that B U (U: nodes × bs) is the sum of a function's values over the pairs, which
    ``Function.eval`` computes by tabulating the element anew at every call. None where that
    shortcut does not hold: a mesh not made of straight-sided triangles in the plane, an
    element with dof transformations or a non-scalar base element (``eval`` is used)."""
    msh = V.mesh
    if (
        msh.topology.cell_name() != "triangle"
        or msh.geometry.cmap.degree != 1
        or V.element.needs_dof_transformations
    ):
        return None
    e = V.element.basix_element
    if len(e.value_shape) != 0:
        return None
    xg = msh.geometry.x
    if np.any(xg[:, 2] != 0.0):
        return None
    n_nodes = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    if not len(cells):
        return sparse.csr_matrix((n, n_nodes))
    geo = msh.geometry.dofmap.array.reshape(-1, 3)[cells]
    v = xg[geo][:, :, :2]
    J = np.stack([v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]], axis=2)
    X = np.linalg.solve(J, (points3[:, :2] - v[:, 0])[..., None])[..., 0]
    phi = e.tabulate(0, X)[0, :, :, 0]
    nodes = V.dofmap.list.array.reshape(-1, e.dim)[cells]
    return sparse.csr_matrix(
        (phi.ravel(), (np.repeat(rows, e.dim), nodes.ravel())), shape=(n, n_nodes)
    )


class PointLocator:
    """The owned cells containing each of a fixed set of points (n×2) of one mesh, found once:
    every function on that mesh is then evaluated there by :meth:`__call__` at the cost of one
    ``eval`` and one reduction (a load step's displacement and all its sensitivities share the
    points; locating them was most of the evaluation). For Lagrange-type elements on
    straight-sided triangles the basis values at the points are kept too, per function space,
    and a function is evaluated by one sparse product (:func:`_basis_matrix`)."""

    def __init__(self, msh, points: np.ndarray) -> None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"eval_points: points must be an (n, 2) array, got shape {pts.shape}")
        self.msh, self.n = msh, len(pts)
        self.pts3 = np.zeros((len(pts), 3))
        self.pts3[:, :2] = pts
        self.rows, self.cells = _owned_cells_at(msh, self.pts3)
        counts = np.bincount(self.rows, minlength=self.n).astype(float)
        self.counts = np.empty_like(counts)
        msh.comm.Allreduce(counts, self.counts, op=MPI.SUM)
        self._tables: dict[int, tuple] = {}

    def _sums(self, f: fem.Function, bs: int) -> np.ndarray:
        """Σ of ``f`` over the (point, owned cell) pairs of this rank, per point (n × bs)."""
        V = f.function_space
        if id(V) not in self._tables:  # V kept with its matrix: its id is not reused
            self._tables[id(V)] = (
                V,
                _basis_matrix(V, self.pts3[self.rows], self.rows, self.cells, self.n),
            )
        B = self._tables[id(V)][1]
        if B is not None:
            return B @ f.x.array.reshape(-1, bs)
        sums = np.zeros((self.n, bs))
        if len(self.rows):
            vals = f.eval(self.pts3[self.rows], self.cells).reshape(-1, bs)
            for k in range(bs):
                sums[:, k] = np.bincount(self.rows, weights=vals[:, k], minlength=self.n)
        return sums

    def __call__(self, f: fem.Function) -> np.ndarray:
        """Values of ``f`` at the points, the same on every rank; NaN outside the mesh (the
        mean over the owned cells containing a point, over all ranks: :func:`eval_points`)."""
        bs = f.function_space.dofmap.index_map_bs
        sums = np.ascontiguousarray(self._sums(f, bs), dtype=float)
        total = np.empty_like(sums)
        self.msh.comm.Allreduce(sums, total, op=MPI.SUM)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.counts[:, None] > 0, total / self.counts[:, None], np.nan)


def eval_points(f: fem.Function, points: np.ndarray) -> np.ndarray:
    """Values of ``f`` at ``points`` (n×2), the same on every rank; NaN where outside the mesh.

    The value is the mean over all (owned) cells containing the point, over all ranks: for a
    continuous f the same value, for a cellwise field (DG, or a gradient) at a vertex or on a
    facet a partition-independent average, so 1 and P ranks agree. Several functions at the
    same points: :class:`PointLocator`.
    """
    return PointLocator(f.function_space.mesh, points)(f)


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


def fibre_states(u: fem.Function, L, M) -> np.ndarray:
    """(λ, μ, γ) at the midpoint of every owned cell of the placement X + u (n×3; the fibre
    stretches and the shear angle of :mod:`fabricsurf.model.kinematics`): the states whose
    tangent :func:`fabricsurf.model.stability.check_tangent` checks."""
    msh = u.function_space.mesh
    x, d = ufl.SpatialCoordinate(msh), ufl.shape(u)[0]
    r = ufl.as_vector([x[0], x[1]] + [0.0] * (d - 2)) + u  # the placement X + u
    kin = Kinematics(ufl.grad(r), None, L, M)
    expr = fem.Expression(
        ufl.as_vector([kin.lam, kin.mu, kin.gamma]),
        basix.make_quadrature(basix.cell.string_to_type(msh.topology.cell_name()), 0)[0],
    )
    cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
    return np.asarray(expr.eval(cells), float).reshape(len(cells), 3)
