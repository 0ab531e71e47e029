"""A whole forming blank (circle or rectangle, centred at the origin) meshed along its fibres,
for any pair of fibre directions: a lattice of parallelograms clipped to the outline.

The vertices are the fibre crossings X_ij = d (i L + j M), L and M the unit fibre directions at
the two fibre angles to x, d ≈ h the length of a fibre edge, (0, 0) a vertex (the pole). Each
parallelogram is cut into two triangles along one diagonal: the shorter one inside the blank
(orthogonal fibres, whose diagonals are equal: the one more nearly along the ray from the pole
to the cell, so that the mesh is its own mirror image in both bisectors and in both fibre lines
through the pole and, at ±45° on a square, its interior is geometry.aligned.quarter_blank's
unfolded), and, for a parallelogram the outline
crosses, the diagonal whose ends lie at the most nearly equal distance from the outline (the one
most nearly parallel to it). A triangle is kept if its centroid lies inside the outline; the
vertices on the boundary of the kept triangles are then moved onto the outline (their closest
point, a rectangle's corners first to the nearest boundary vertex), and a triangle that this
leaves with less than :data:`MIN_AREA_FRACTION` of its lattice area is dropped and the snap
redone. Every interior edge lies along a fibre or a diagonal of a fibre parallelogram, as in
geometry/aligned.py, so stiff fibres do not lock; only the boundary triangles are distorted
(what that costs: docs/forming.md, "Blanks").

The construction is symmetric under X → −X (the lattice, the cut rules and the closest point
all are, and ties between corner candidates are broken by a rule that is too), so the mesh of a
centrally symmetric outline is centrally symmetric: experiments/hemisphere.py relies on it to pin
the pole. :func:`mirrored_quarter` gives instead the four mirror images of
geometry.aligned.quarter_blank: the full square on the quarter's own mesh.

Built in memory on rank 0 and distributed with shared-facet ghosts; the outline's facets are
tagged ``edge``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from geometry.aligned import quarter_divisions, quarter_triangles
from geometry.specimen import EDGE_TAGS as RECTANGLE_TAGS
from geometry.specimen import Specimen, check_positive, distributed_mesh

EDGE_TAGS = {**RECTANGLE_TAGS, "edge": 5}
"""The outline is ``edge``; the rectangle's names stay declared (with no facets) so that a
problem may name them, as the hemisphere plug-in does to share the quarter's compiled forms."""
MIN_AREA_FRACTION = 0.3
"""A snapped boundary triangle keeps at least this fraction of its lattice triangle's area."""
SNAP_ROUNDS = 20


def _box(a: float, b: float) -> tuple[Callable, Callable]:
    """Signed distance (negative inside) and closest outline point of [−a, a] × [−b, b]."""
    def phi(X):
        q = np.abs(X) - [a, b]
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)

    def project(X):
        half = np.array([a, b])
        P = np.clip(X, -half, half)
        inside = (np.abs(X) < half).all(axis=1)
        k = (half - np.abs(X[inside])).argmin(axis=1)
        rows = np.flatnonzero(inside)
        P[rows, k] = np.where(X[rows, k] < 0, -1.0, 1.0) * half[k]
        return P
    return phi, project


def _circle(r: float) -> tuple[Callable, Callable]:
    def phi(X):
        return np.linalg.norm(X, axis=1) - r

    def project(X):
        n = np.linalg.norm(X, axis=1, keepdims=True)
        return r * X / np.where(n > 0, n, 1.0)
    return phi, project


def outline(shape: str, a: float, b: float) -> tuple[Callable, Callable]:
    """(signed distance, closest point) of the outline: ``circle`` of radius a or
    ``rectangle`` (a square too) of half-sides a, b."""
    return _circle(a) if shape == "circle" else _box(a, b)


def _lattice(L: np.ndarray, M: np.ndarray, d: float, reach: float):
    """Vertices d (i L + j M) within ``reach`` of the origin in fibre coordinates, and the
    corners (00, 10, 11, 01) of each lattice parallelogram."""
    n = math.ceil(reach / (d * abs(np.cross(L, M)))) + 2
    k = np.arange(-n, n + 1)
    i, j = (g.ravel() for g in np.meshgrid(k, k, indexing="ij"))
    X = d * (np.outer(i, L) + np.outer(j, M))
    idx = ((i + n) * (2 * n + 1) + (j + n)).reshape(2 * n + 1, 2 * n + 1)
    quads = np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(),
                             idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()])
    return X, quads


def _cut(X: np.ndarray, quads: np.ndarray, phi: Callable) -> np.ndarray:
    """Two triangles per parallelogram (module docstring's rules)."""
    f = phi(X)
    q = quads
    d1 = np.linalg.norm(X[q[:, 2]] - X[q[:, 0]], axis=1)
    d2 = np.linalg.norm(X[q[:, 3]] - X[q[:, 1]], axis=1)
    c = X[q].mean(axis=1)
    radial = np.abs(c @ (X[q[0, 2]] - X[q[0, 0]])) > np.abs(c @ (X[q[0, 3]] - X[q[0, 1]]))
    tie = np.abs(d1 - d2) <= 1e-9 * d2
    along_11 = np.where(tie, radial, d1 < d2)
    crossed = (f[q].min(axis=1) < 0) & (f[q].max(axis=1) > 0)
    e1, e2 = np.abs(f[q[:, 2]] - f[q[:, 0]]), np.abs(f[q[:, 3]] - f[q[:, 1]])
    along_11 = np.where(crossed & (np.abs(e1 - e2) > 1e-9 * (e1 + e2 + 1e-300)), e1 < e2,
                        along_11)
    a = np.column_stack([q[:, 0], q[:, 1], q[:, 2]])
    b = np.column_stack([q[:, 0], q[:, 2], q[:, 3]])
    c = np.column_stack([q[:, 0], q[:, 1], q[:, 3]])
    e = np.column_stack([q[:, 1], q[:, 2], q[:, 3]])
    w = along_11[:, None]
    return np.concatenate([np.where(w, a, c), np.where(w, b, e)])


def _boundary_vertices(tri: np.ndarray) -> np.ndarray:
    """Vertices on edges that belong to one triangle only."""
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    return np.unique(uniq[count == 1])


def _area(X: np.ndarray, tri: np.ndarray) -> np.ndarray:
    p, q, r = X[tri[:, 0]], X[tri[:, 1]], X[tri[:, 2]]
    return 0.5 * np.cross(q - p, r - p)


def _snap(X0: np.ndarray, tri: np.ndarray, project: Callable, corners: np.ndarray
          ) -> np.ndarray:
    """The lattice with the boundary vertices of ``tri`` on the outline, each corner taken by
    the nearest boundary vertex (ties broken symmetrically under X → −X)."""
    X = X0.copy()
    bv = _boundary_vertices(tri)
    X[bv] = project(X0[bv])
    for c in corners:
        dist = np.round(np.linalg.norm(X0[bv] - c, axis=1), 9)
        tie = np.cross(X0[bv] - c, c)
        X[bv[np.lexsort((tie, dist))[0]]] = c
    return X


def clip_lattice(shape: str, a: float, b: float, angles_deg: tuple[float, float], d: float
                 ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Vertices and triangles of the fibre lattice clipped to the outline (module docstring),
    and its quality: the smallest area fraction of a boundary triangle and how many lattice
    triangles were dropped by the snap."""
    L, M = (np.array([math.cos(math.radians(t)), math.sin(math.radians(t))]) for t in angles_deg)
    phi, project = outline(shape, a, b)
    corners = (np.array([[a, b], [-a, b], [-a, -b], [a, -b]]) if shape != "circle"
               else np.zeros((0, 2)))
    X0, quads = _lattice(L, M, d, math.hypot(a, b) + 2 * d)
    tri = _cut(X0, quads, phi)
    keep = phi(X0[tri].mean(axis=1)) < 0
    ref = abs(_area(X0, tri[:1]))[0]
    sign = np.sign(_area(X0, tri))
    dropped = 0
    for _ in range(SNAP_ROUNDS):
        X = _snap(X0, tri[keep], project, corners)
        frac = _area(X, tri) * sign / ref
        bad = keep & (frac < MIN_AREA_FRACTION)
        if not bad.any():
            break
        keep &= ~bad
        dropped += int(bad.sum())
    else:
        raise ValueError(f"geometry: the fibre lattice (d = {d:g}) could not be snapped to "
                         f"the {shape} outline in {SNAP_ROUNDS} rounds")
    used, tri = np.unique(tri[keep], return_inverse=True)
    tri = tri.reshape(-1, 3)
    return X[used], tri, {"min_area_fraction": float(frac[keep].min()), "dropped": dropped}


def _tag_outline(msh, shape: str, a: float, b: float):
    phi, _ = outline(shape, a, b)
    facets = dmesh.locate_entities_boundary(
        msh, 1, lambda x: np.abs(phi(x[:2].T)) < 1e-8 * max(a, b))
    return dmesh.meshtags(msh, 1, facets, np.full(len(facets), EDGE_TAGS["edge"], dtype=np.int32))


def fibre_blank(shape: str, a: float, b: float, angles_deg: tuple[float, float], h: float,
                comm: MPI.Comm = MPI.COMM_WORLD) -> Specimen:
    """The blank (``circle`` of radius a, ``rectangle`` of half-sides a × b) centred at the
    origin, meshed along fibres at ``angles_deg`` to x with fibre edges h (module docstring).
    ``length``, ``width`` of the Specimen are its extents 2a × 2b; ``note`` records the
    snap's quality."""
    check_positive(a=a, b=b, h=h)
    if comm.rank == 0:
        x, tri, quality = clip_lattice(shape, a, b, angles_deg, h)
    else:
        x, tri, quality = np.zeros((0, 2)), np.zeros((0, 3), np.int64), None
    quality = comm.bcast(quality, root=0)
    msh = distributed_mesh(comm, x, tri)
    ft = _tag_outline(msh, shape, a, b)
    msh.topology.create_connectivity(1, 2)
    return Specimen(msh, ft, 2.0 * a, 2.0 * b, edge_tags=dict(EDGE_TAGS), points={"pole": (0, 0)},
                    kind="aligned", h=float(h),
                    note=(f"fibre lattice clipped to the {shape}: smallest boundary triangle "
                          f"{quality['min_area_fraction']:.2f} of a lattice triangle, "
                          f"{quality['dropped']} dropped by the snap"))


def mirrored_quarter(half: float, h: float, theta_deg: float, comm: MPI.Comm = MPI.COMM_WORLD
                     ) -> Specimen:
    """The square [−half, half]² as the four mirror images of
    geometry.aligned.quarter_blank(half, h, θ): the quarter's own mesh, unfolded (to check the
    full blank against the quarter with mirror conditions on the same discretisation)."""
    P, Q = quarter_divisions(half, h, theta_deg)
    if comm.rank == 0:
        verts, tri = quarter_triangles(P, Q, theta_deg)
        ts, key = [], {}
        for sx in (1, -1):
            for sy in (1, -1):
                for v in verts:
                    k = (int(sx * v[0]), int(sy * v[1]))
                    key.setdefault(k, len(key))
                ts.append(np.array([[key[(int(sx * verts[n][0]), int(sy * verts[n][1]))]
                                     for n in t] for t in tri]))
        ij = np.array(list(key), dtype=float)
        x = np.column_stack([ij[:, 0] * half / P, ij[:, 1] * half / Q])
        tri = np.concatenate(ts).astype(np.int64)
    else:
        x, tri = np.zeros((0, 2)), np.zeros((0, 3), np.int64)
    msh = distributed_mesh(comm, x, tri)
    ft = _tag_outline(msh, "rectangle", half, half)
    msh.topology.create_connectivity(1, 2)
    return Specimen(msh, ft, 2.0 * half, 2.0 * half, edge_tags=dict(EDGE_TAGS),
                    points={"pole": (0, 0)}, kind="aligned",
                    h=math.hypot(half / P, half / Q) if theta_deg else half / P,
                    note="the aligned quarter's mesh mirrored into the four quadrants")
