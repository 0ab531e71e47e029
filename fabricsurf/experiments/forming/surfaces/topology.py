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
    """(vertices, faces) with coincident points (within :data:`WELD` of the diagonal) merged."""
    points = np.asarray(points, float)
    diag = float(np.linalg.norm(np.ptp(points, axis=0))) or 1.0
    pairs = cKDTree(points).query_pairs(WELD * diag, output_type="ndarray")
    n = len(points)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    _, first = np.unique(label, return_index=True)
    return points[first], label[np.asarray(faces)]


def edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(unique undirected edges (m, 2) sorted, the edge of each face side (f, 3): side k from
    corner k to k + 1, how many face sides use each edge)."""
    sides = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    unique, inverse, counts = np.unique(
        np.sort(sides, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    return unique, inverse.reshape(-1, 3), counts


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


def check(vertices: np.ndarray, faces: np.ndarray, name: str, closed: bool = True) -> None:
    """Raise InputError naming ``name`` if a triangle is degenerate, an edge has more than two
    triangles, two triangles on an edge are oriented alike, or (``closed``) an edge has one
    triangle only or the enclosed volume is not positive (flipped normals)."""
    diag = float(np.linalg.norm(np.ptp(vertices, axis=0)))
    _, area2 = face_normals(vertices, faces)
    bad = np.flatnonzero(~(area2 > DEGENERATE * diag**2))
    if len(bad):
        raise InputError(
            f"{name}: {len(bad)} degenerate triangle(s) of zero area (first: triangle "
            f"{bad[0]}, vertices {vertices[faces[bad[0]]].round(6).tolist()}); remove them"
        )
    unique, _, counts = edges(faces)
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
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    _, dcounts = np.unique(directed, axis=0, return_counts=True)
    if (dcounts > 1).any():
        raise InputError(
            f"{name}: inconsistent normals: {int((dcounts > 1).sum())} edge(s) whose two "
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
    vertices: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(face normals (f, 3); edge pseudo-normals per face side (f, 3, 3), the normalised sum
    of the normals of the triangles on the edge; angle-weighted vertex normals (v, 3), Σ α_f
    n_f normalised, α_f the triangle's angle at the vertex)."""
    nf, _ = face_normals(vertices, faces)
    unique, side_edge, _ = edges(faces)
    acc = np.zeros((len(unique), 3))
    np.add.at(acc, side_edge.ravel(), np.repeat(nf, 3, axis=0))
    en = acc / np.linalg.norm(acc, axis=1, keepdims=True)
    vn = np.zeros_like(vertices)
    for k in range(3):
        p, q, r = (vertices[faces[:, (k + j) % 3]] for j in range(3))
        u, w = q - p, r - p
        cos = np.einsum("ij,ij->i", u, w) / (np.linalg.norm(u, axis=1) * np.linalg.norm(w, axis=1))
        np.add.at(vn, faces[:, k], np.arccos(np.clip(cos, -1.0, 1.0))[:, None] * nf)
    vn /= np.linalg.norm(vn, axis=1, keepdims=True)
    return nf, en[side_edge], vn
