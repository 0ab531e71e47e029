"""A triangulated surface's connectivity and what a signed distance needs of it: welded
vertices, the checks that it bounds a solid (closed, consistently oriented, outward, no
degenerate triangle), and its normals (face, angle-weighted vertex and edge pseudo-normals of
Bærentzen & Aanæs 2005; the vertex normals of Thürmer & Wüthrich 1998).

A surface bounds a solid when every edge is shared by exactly two triangles (no boundary edge,
no fin of three or more) that traverse it in opposite senses (consistent orientation); its
triangles then face outwards when the enclosed volume, the sum over the triangles of
det(a, b, c)/6 (the divergence theorem), is positive.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from fabricsurf.errors import InputError

WELD = 1e-9
"""Vertices closer than this times the bounding-box diagonal are one vertex (an STL file
repeats each vertex in every triangle that has it)."""
DEGENERATE = 1e-12
"""A triangle whose doubled area is below this times the squared diagonal has no normal."""


def weld(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) with coincident points (within :data:`WELD` of the diagonal) merged.
    Points repeated exactly (an STL file's) are merged first, so that the search for near
    pairs runs over the distinct points only."""
    points = np.ascontiguousarray(points, dtype=float)
    diag = float(np.linalg.norm(np.ptp(points, axis=0))) or 1.0
    distinct, exact = _exact_repeats(points)
    pairs = cKDTree(distinct).query_pairs(WELD * diag, output_type="ndarray")
    n = len(distinct)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    _, keep = np.unique(label, return_index=True)
    return distinct[keep], label[exact][np.asarray(faces)]


def _exact_repeats(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points with exact repeats merged, the index of each point among them): equal rows are
    neighbours once sorted by a hash of their bits. A hash shared by unequal rows can split a
    repeat in two, which the search for near pairs then merges, so the result is exact."""
    bits = points.view(np.uint64)
    mix = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9], np.uint64)
    order = np.argsort(np.bitwise_xor.reduce(bits * mix, axis=1), kind="stable")
    sorted_bits = bits[order]
    new = np.r_[True, (sorted_bits[1:] != sorted_bits[:-1]).any(axis=1)]
    index = np.empty(len(points), np.int64)
    index[order] = np.cumsum(new) - 1
    return points[order[new]], index


def edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(unique undirected edges (m, 2) sorted, the edge of each face side (f, 3): side k from
    corner k to k + 1, how many face sides use each edge)."""
    sides = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    n = int(faces.max()) + 1
    keys, inverse, counts = np.unique(
        sides.min(axis=1) * n + sides.max(axis=1), return_inverse=True, return_counts=True
    )
    return np.column_stack([keys // n, keys % n]), inverse.reshape(-1, 3), counts


def repeated_directed_sides(faces: np.ndarray) -> int:
    """How many directed edges (a → b) more than one face side traverses: 0 for a consistently
    oriented mesh."""
    n = int(faces.max()) + 1
    keys = np.sort((faces * n + np.roll(faces, -1, axis=1)).ravel())
    return int(np.count_nonzero(np.diff(keys) == 0))


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit normals (f, 3) by the right-hand rule, doubled areas (f,))."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    cross = np.cross(b - a, c - a)
    area2 = np.linalg.norm(cross, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return cross / area2[:, None], area2


def enclosed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Σ det(a, b, c)/6 over the triangles (module docstring)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij", a, np.cross(b, c)) / 6.0)


def check(
    vertices: np.ndarray, faces: np.ndarray, name: str, closed: bool = True, table=None
) -> None:
    """Raise InputError naming ``name`` if a triangle is degenerate, an edge has more than two
    triangles, two triangles on an edge are oriented alike, or (``closed``) an edge has one
    triangle only or the enclosed volume is not positive (flipped normals). ``table``: the
    faces' :func:`edges`, if known."""
    diag = float(np.linalg.norm(np.ptp(vertices, axis=0)))
    _, area2 = face_normals(vertices, faces)
    bad = np.flatnonzero(~(area2 > DEGENERATE * diag**2))
    if len(bad):
        raise InputError(
            f"{name}: {len(bad)} degenerate triangle(s) of zero area (first: triangle "
            f"{bad[0]}, vertices {vertices[faces[bad[0]]].round(6).tolist()}); remove them"
        )
    unique, _, counts = edges(faces) if table is None else table
    if (counts > 2).any():
        e = unique[np.argmax(counts > 2)]
        raise InputError(
            f"{name}: {int((counts > 2).sum())} edge(s) shared by more than two triangles "
            f"(first at {vertices[e[0]].round(6).tolist()}): not the surface of one solid"
        )
    if closed and (counts == 1).any():
        e = unique[np.argmax(counts == 1)]
        raise InputError(
            f"{name}: the surface is not closed: {int((counts == 1).sum())} boundary edge(s) "
            f"(first at {vertices[e[0]].round(6).tolist()}); a tool must be a closed surface "
            "(a watertight STL/OBJ), so that its inside is defined"
        )
    repeated = repeated_directed_sides(faces)
    if repeated:
        raise InputError(
            f"{name}: inconsistent normals: {repeated} edge(s) whose two "
            "triangles are oriented alike (some triangles are flipped); orient all triangles "
            "the same way (outward normals, counter-clockwise seen from outside)"
        )
    if closed:
        volume = enclosed_volume(vertices, faces)
        if not volume > 0:
            raise InputError(
                f"{name}: flipped normals: the triangles face inwards (enclosed volume "
                f"{volume:.6g} < 0); reverse the vertex order of every triangle"
            )


def orient(faces: np.ndarray, vertices: np.ndarray | None = None) -> np.ndarray:
    """Faces reordered so that neighbours traverse their shared edges in opposite senses (a
    breadth-first walk over each connected piece), and, given the vertices, each closed piece
    facing outwards; for meshes whose triangles come oriented piece by piece (gmsh)."""
    faces = np.array(faces)
    _, side_edge, _ = edges(faces)
    owners: dict[int, list[tuple[int, int]]] = {}
    for f in range(len(faces)):
        for k in range(3):
            owners.setdefault(int(side_edge[f, k]), []).append((f, k))
    done = np.zeros(len(faces), bool)
    piece = np.full(len(faces), -1)
    for start in range(len(faces)):
        if done[start]:
            continue
        done[start], piece[start], queue = True, start, [start]
        while queue:
            f = queue.pop()
            for k in range(3):
                a, b = faces[f, k], faces[f, (k + 1) % 3]
                for g, _ in owners[int(side_edge[f, k])]:
                    if done[g]:
                        continue
                    row = list(faces[g])
                    i = row.index(a)
                    if row[(i + 1) % 3] == b:  # same sense: flip g
                        faces[g] = faces[g][::-1]
                    done[g], piece[g] = True, start
                    queue.append(g)
    if vertices is not None:
        for p in np.unique(piece):
            sel = piece == p
            if enclosed_volume(vertices, faces[sel]) < 0:
                faces[sel] = faces[sel][:, ::-1]
    return faces


def pseudo_normals(
    vertices: np.ndarray, faces: np.ndarray, table=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(face normals (f, 3); edge pseudo-normals per face side (f, 3, 3), the normalised sum
    of the normals of the triangles on the edge; angle-weighted vertex normals (v, 3), Σ α_f
    n_f normalised, α_f the triangle's angle at the vertex). ``table``: as for :func:`check`."""
    nf, _ = face_normals(vertices, faces)
    unique, side_edge, _ = edges(faces) if table is None else table
    acc = _summed(side_edge.ravel(), np.repeat(nf, 3, axis=0), len(unique))
    en = acc / np.linalg.norm(acc, axis=1, keepdims=True)
    vn = np.zeros_like(vertices)
    for k in range(3):
        p, q, r = (vertices[faces[:, (k + j) % 3]] for j in range(3))
        u, w = q - p, r - p
        cos = np.einsum("ij,ij->i", u, w) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
        vn += _summed(faces[:, k], np.arccos(np.clip(cos, -1.0, 1.0))[:, None] * nf, len(vn))
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    return nf, en[side_edge], vn


def _summed(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Rows of ``values`` (m, 3) summed into n rows by ``index`` (np.add.at, by bincount)."""
    return np.column_stack([np.bincount(index, values[:, j], minlength=n) for j in range(3)])
