"""A whole forming blank (circle or rectangle, centred at the origin) meshed along its fibres,
for any pair of fibre directions: a lattice of parallelograms cut by the outline.

The vertices are the fibre crossings X_ij = d (i L + j M), L and M the unit fibre directions at
the two fibre angles to x, d ≈ h the length of a fibre edge, (0, 0) a vertex (the pole). A
parallelogram inside the blank is cut into two triangles along its shorter diagonal
(orthogonal fibres, whose diagonals are equal: the one more nearly along the ray from the pole
to the cell, so that the mesh is its own mirror image in both bisectors and in both fibre lines
through the pole and, at ±45° on a square, its interior is geometry.aligned.quarter_blank's
unfolded). A parallelogram the outline crosses keeps its part inside the blank (cut cells):
the convex polygon of its corners inside, the points where its fibre edges cross the outline
and the outline's corners inside it, triangulated by the fan that maximises the smallest angle
(geometry/cut_cells.py). No vertex is moved off its lattice parallelogram, so every triangle
lies in one: every piecewise-affine Chebyshev net of the lattice (x = a(s) + b(t), kinked at the
lattice lines) is a P1 deformation of the mesh that stretches no fibre, and stiff fibres lock
nowhere, the boundary row included. The mesh builder before snapped the boundary vertices onto
the outline; those triangles left their parallelograms, forbade the kinks of every fibre line
through them, and at K = 10⁵ N/mm the blank locked (docs/forming.md, "Blanks"). Slivers are
avoided by moving a crossing within :data:`MERGE` of an edge's length of the edge's end onto
that end (along the fibre: the outline moves by at most MERGE·h) and by cutting off an outline
corner that close to a crossing; a circle's arcs are chords.

The construction is symmetric under X → −X (the lattice, the cut rules and the crossings all
are, and the fan's ties are broken by a rule that is too), so the mesh of a centrally symmetric
outline is centrally symmetric: experiments/hemisphere.py relies on it to pin the pole.
:func:`mirrored_quarter` gives instead the four mirror images of
geometry.aligned.quarter_blank: the full square on the quarter's own mesh (the same mesh as the
clipped lattice whose outline passes through lattice vertices).

Built in memory on rank 0 and distributed with shared-facet ghosts; the outline's facets (every
exterior facet) are tagged ``edge``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .aligned import quarter_divisions, quarter_triangles
from .cut_cells import fan, min_angle, piece_inside
from .specimen import EDGE_TAGS as RECTANGLE_TAGS
from .specimen import Specimen, check_positive, distributed_mesh

EDGE_TAGS = {**RECTANGLE_TAGS, "edge": 5}
"""The outline is ``edge``; the rectangle's names stay declared (with no facets) so that a
problem may name them, as the hemisphere plug-in does to share the quarter's compiled forms."""
MERGE = 0.2
"""Where the outline crosses a lattice triangle's edge within MERGE·h of its end, the crossing
is moved onto that end (along the edge), so that no cut cell is a sliver; the outline moves by
at most MERGE·h there."""


def outline(shape: str, a: float, b: float) -> Callable:
    """The signed distance (negative inside) to the outline: ``circle`` of radius a or
    ``rectangle`` (a square too) [−a, a] × [−b, b]; X is (n, 2)."""
    if shape == "circle":
        return lambda X: np.linalg.norm(X, axis=1) - a

    def phi(X):
        q = np.abs(X) - [a, b]
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)

    return phi


def _lattice(L: np.ndarray, M: np.ndarray, d: float, reach: float):
    """Vertices d (i L + j M) within ``reach`` of the origin in fibre coordinates, and the
    corners (00, 10, 11, 01) of each lattice parallelogram."""
    n = math.ceil(reach / (d * abs(np.cross(L, M)))) + 2
    k = np.arange(-n, n + 1)
    i, j = (g.ravel() for g in np.meshgrid(k, k, indexing="ij"))
    X = d * (np.outer(i, L) + np.outer(j, M))
    idx = ((i + n) * (2 * n + 1) + (j + n)).reshape(2 * n + 1, 2 * n + 1)
    quads = np.column_stack(
        [idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()]
    )
    return X, quads


def _cut(X: np.ndarray, quads: np.ndarray, phi: Callable) -> np.ndarray:
    """Two triangles per parallelogram: along its shorter diagonal (orthogonal fibres: the one
    more nearly along the ray from the pole), and, where the outline crosses it, along the
    diagonal whose ends lie at the most nearly equal distance from the outline (the one most
    nearly parallel to it: a square's outline through lattice vertices is then a union of
    diagonals, as on the aligned quarter)."""
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
    along_11 = np.where(crossed & (np.abs(e1 - e2) > 1e-9 * (e1 + e2 + 1e-300)), e1 < e2, along_11)
    w = along_11[:, None]
    a = np.column_stack([q[:, 0], q[:, 1], q[:, 2]])
    b = np.column_stack([q[:, 0], q[:, 2], q[:, 3]])
    c = np.column_stack([q[:, 0], q[:, 1], q[:, 3]])
    e = np.column_stack([q[:, 1], q[:, 2], q[:, 3]])
    return np.concatenate([np.where(w, a, c), np.where(w, b, e)])


def _area(X: np.ndarray, tri: np.ndarray) -> np.ndarray:
    p, q, r = X[tri[:, 0]], X[tri[:, 1]], X[tri[:, 2]]
    return 0.5 * np.cross(q - p, r - p)


def lattice_triangulation(
    shape: str, a: float, b: float, angles_deg: tuple[float, float], d: float
) -> tuple[np.ndarray, np.ndarray]:
    """The fibre lattice of edge d at ``angles_deg`` over the blank and its triangles (each
    parallelogram cut by :func:`_cut`): the triangulation whose P1
    deformations include every discrete Chebyshev net of the lattice, in the plane and in 3D
    (each triangle has one edge along each fibre), and in which every triangle of
    :func:`clip_lattice` lies."""
    L, M = (np.array([math.cos(math.radians(t)), math.sin(math.radians(t))]) for t in angles_deg)
    X0, quads = _lattice(L, M, d, math.hypot(a, b) + 2 * d)
    return X0, _cut(X0, quads, outline(shape, a, b))


def clip_lattice(
    shape: str, a: float, b: float, angles_deg: tuple[float, float], d: float
) -> tuple[np.ndarray, np.ndarray, dict]:
    """Vertices and triangles of the fibre lattice clipped to the outline (module docstring),
    and its quality: the smallest triangle's area over a lattice triangle's, the smallest
    angle (deg), and the meshed area over the blank's."""
    phi = outline(shape, a, b)
    corners = (
        np.array([[a, b], [-a, b], [-a, -b], [a, -b]]) if shape != "circle" else np.zeros((0, 2))
    )
    X0, tri0 = lattice_triangulation(shape, a, b, angles_deg, d)
    f = phi(X0)
    inside = f <= 1e-12 * max(a, b)
    full = inside[tri0].all(axis=1)
    near = ~full & (f[tri0].min(axis=1) < d)
    tri, pts, count = [tri0[full]], [X0], len(X0)
    for t0 in tri0[near]:
        piece = piece_inside(shape, a, b, X0[t0], corners, inside[t0], MERGE * d)
        if len(piece) < 3:
            continue
        for t in fan(piece):
            tri.append(np.array([t]) + count)
        pts.append(piece)
        count += len(piece)
    X = np.concatenate(pts)
    tri = np.concatenate(tri)
    key = np.round(X / (1e-9 * d)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    tri = inverse.reshape(-1)[tri]
    used, tri = np.unique(tri, return_inverse=True)
    X, tri = X[first[used]], tri.reshape(-1, 3)
    area = np.abs(_area(X, tri))
    ref = abs(_area(X0, tri0[:1])[0])
    exact = math.pi * a * a if shape == "circle" else 4.0 * a * b
    return (
        X,
        tri,
        {
            "min_area_fraction": float(area.min() / ref),
            "min_angle_deg": math.degrees(min(min_angle(X[t]) for t in tri)),
            "area_fraction": float(area.sum() / exact),
        },
    )


def _tag_outline(msh):
    """Every exterior facet is the outline's (a crossing moved onto a lattice vertex lies up to
    MERGE·h inside the exact outline)."""
    msh.topology.create_connectivity(1, 2)
    facets = dmesh.exterior_facet_indices(msh.topology)
    return dmesh.meshtags(msh, 1, facets, np.full(len(facets), EDGE_TAGS["edge"], dtype=np.int32))


def fibre_blank(
    shape: str,
    a: float,
    b: float,
    angles_deg: tuple[float, float],
    h: float,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> Specimen:
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
    ft = _tag_outline(msh)
    return Specimen(
        msh,
        ft,
        2.0 * a,
        2.0 * b,
        edge_tags=dict(EDGE_TAGS),
        points={"pole": (0, 0)},
        kind="aligned",
        h=float(h),
        note=(
            f"fibre lattice cut by the {shape}: smallest cut triangle "
            f"{quality['min_area_fraction']:.2f} of a lattice triangle, smallest "
            f"angle {quality['min_angle_deg']:.1f}°, meshed area "
            f"{quality['area_fraction']:.4f} of the blank's"
        ),
    )


def mirrored_quarter(
    half_x: float, half_y: float, h: float, theta_deg: float, comm: MPI.Comm = MPI.COMM_WORLD
) -> Specimen:
    """The rectangle [−half_x, half_x] × [−half_y, half_y] as the four mirror images of
    geometry.aligned.quarter_blank(half_x, half_y, h, θ): the quarter's own mesh, unfolded (to
    check the full blank against the quarter with mirror conditions on the same
    discretisation)."""
    P, Q = quarter_divisions(half_x, half_y, h, theta_deg)
    if comm.rank == 0:
        verts, tri = quarter_triangles(P, Q, theta_deg)
        ts, key = [], {}
        for sx in (1, -1):
            for sy in (1, -1):
                for v in verts:
                    k = (int(sx * v[0]), int(sy * v[1]))
                    key.setdefault(k, len(key))
                ts.append(
                    np.array(
                        [
                            [key[(int(sx * verts[n][0]), int(sy * verts[n][1]))] for n in t]
                            for t in tri
                        ]
                    )
                )
        ij = np.array(list(key), dtype=float)
        x = np.column_stack([ij[:, 0] * half_x / P, ij[:, 1] * half_y / Q])
        tri = np.concatenate(ts).astype(np.int64)
    else:
        x, tri = np.zeros((0, 2)), np.zeros((0, 3), np.int64)
    msh = distributed_mesh(comm, x, tri)
    ft = _tag_outline(msh)
    return Specimen(
        msh,
        ft,
        2.0 * half_x,
        2.0 * half_y,
        edge_tags=dict(EDGE_TAGS),
        points={"pole": (0, 0)},
        kind="aligned",
        h=math.hypot(half_x / P, half_y / Q) if theta_deg else max(half_x / P, half_y / Q),
        note="the aligned quarter's mesh mirrored into the four quadrants",
    )
