"""A tool given as a triangulated surface: the signed distance and normal of its closed,
outward-oriented triangle mesh at any points.

The distance is exact (to round-off) for the triangle mesh: the closest triangle is looked for
among the k triangles whose centroids are nearest (scipy's cKDTree), and where that cannot be
certain (the k-th centroid nearer than the best distance found plus the largest
centroid-to-corner distance, the bound on how far a closer triangle's centroid can be) among all
the triangles whose centroids lie within that bound. The sign is that of (x − c)·N, c the
closest point and N the angle-weighted pseudo-normal of the feature that holds c (the face's
normal, an edge's or a vertex's pseudo-normal): Bærentzen & Aanæs 2005 prove it is the sign of
the inside/outside for a closed, consistently oriented mesh.

Two normals: :meth:`TriangulatedSurface.normal` is the gradient of the signed distance
(±(x − c)/|x − c|, the pseudo-normal on the surface), the direction a penalty contact pushes
along; it is a face normal over most of the surface, and a face normal of a triangulation of a
smooth surface with triangles of size h errs by O(h) from the smooth normal.
:meth:`TriangulatedSurface.smooth_normal` interpolates the angle-weighted vertex normals
linearly over the closest triangle (Phong 1975's normal interpolation), which errs by O(h²) on a
regular triangulation; the drape's geodesic steps use it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from fabricsurf.experiments.forming.surfaces import topology
from fabricsurf.experiments.forming.surfaces.closest import (
    EDGE,
    FACE,
    barycentric,
    closest_on_triangles,
)

NEAREST = (8, 64, 512)
"""Triangles examined per point, more for the points where fewer left the closest one
uncertain (module docstring); the rest look at all the triangles within the bound."""


class TriangulatedSurface:
    """A closed (or, with ``closed=False``, open but consistently oriented) triangle mesh in mm:
    ``vertices`` (v, 3), ``faces`` (f, 3) of vertex indices counter-clockwise seen from outside.
    ``name`` names it in error messages (the file it came from). Checked on construction
    (topology.check)."""

    def __init__(
        self, vertices: np.ndarray, faces: np.ndarray, name: str = "surface", closed: bool = True
    ) -> None:
        self.vertices = np.asarray(vertices, float)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.name, self.closed = name, closed
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or len(self.faces) == 0:
            raise ValueError(f"{name}: need faces of shape (f, 3), got {self.faces.shape}")
        topology.check(self.vertices, self.faces, name, closed)
        self.face_normal, self.edge_normal, self.vertex_normal = topology.pseudo_normals(
            self.vertices, self.faces
        )
        corners = self.vertices[self.faces]
        self.centroid = corners.mean(axis=1)
        self.reach = float(np.linalg.norm(corners - self.centroid[:, None], axis=2).max())
        self.tree = cKDTree(self.centroid)
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        self.size = float((hi - lo).max())

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The bounding box (lower corner, upper corner), mm."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def edge_length(self) -> float:
        """The longest triangle edge h, mm (the triangulation's size)."""
        c = self.vertices[self.faces]
        return float(np.linalg.norm(c - np.roll(c, 1, axis=1), axis=2).max())

    def _closest_among(self, x: np.ndarray, cand: np.ndarray):
        a, b, c = (self.vertices[self.faces[cand, k]] for k in range(3))
        return closest_on_triangles(x[:, None, :], a, b, c)

    def closest(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(closest points (m, 3), the triangle holding each, the pseudo-normal of the feature
        that holds it (m, 3)) of points x (m, 3) (module docstring)."""
        x = np.atleast_2d(np.asarray(x, float))
        point, face = np.empty_like(x), np.zeros(len(x), dtype=np.int64)
        kind, index = np.zeros(len(x), dtype=int), np.zeros(len(x), dtype=int)
        todo = np.arange(len(x))
        for k in NEAREST:
            k = min(k, len(self.faces))
            dist_c, cand = self.tree.query(x[todo], k=k)
            cand, dist_c = cand.reshape(len(todo), k), dist_c.reshape(len(todo), k)
            q, d2, kd, ix = self._closest_among(x[todo], cand)
            j = np.argmin(d2, axis=1)
            rows = np.arange(len(todo))
            point[todo], face[todo] = q[rows, j], cand[rows, j]
            kind[todo], index[todo] = kd[rows, j], ix[rows, j]
            sure = (dist_c[:, -1] >= np.sqrt(d2[rows, j]) + self.reach) | (k == len(self.faces))
            todo = todo[~sure]
            if len(todo) == 0:
                break
        for i in todo:
            best = float(np.linalg.norm(x[i] - point[i]))
            more = np.asarray(self.tree.query_ball_point(x[i], best + self.reach), dtype=int)
            qi, di, ki, ii = self._closest_among(x[i : i + 1], more[None, :])
            m = int(np.argmin(di[0]))
            point[i], face[i], kind[i], index[i] = qi[0, m], more[m], ki[0, m], ii[0, m]
        pseudo = np.where(
            (kind == FACE)[:, None],
            self.face_normal[face],
            np.where(
                (kind == EDGE)[:, None],
                self.edge_normal[face, index],
                self.vertex_normal[self.faces[face, index]],
            ),
        )
        return point, face, pseudo

    def frame(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(signed distance (m,), closest point (m, 3), normal (m, 3)) of points x (m, 3): the
        distance positive outside, the normal the distance's gradient ±(x − c)/|x − c|, the
        feature's pseudo-normal for points on the surface (module docstring)."""
        x = np.atleast_2d(np.asarray(x, float))
        c, _, pseudo = self.closest(x)
        w = x - c
        d = np.linalg.norm(w, axis=1)
        sign = np.where(np.einsum("ij,ij->i", w, pseudo) < 0, -1.0, 1.0)
        on = d <= 1e-12 * max(self.size, 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = np.where(on[:, None], pseudo, sign[:, None] * w / d[:, None])
        return sign * d, c, n

    def signed_distance(self, x: np.ndarray) -> np.ndarray:
        """Signed distance (m,) of points x (m, 3), mm: positive outside."""
        return self.frame(x)[0]

    def normal(self, x: np.ndarray) -> np.ndarray:
        """The gradient of the signed distance (m, 3) (:meth:`frame`)."""
        return self.frame(x)[2]

    def near(self, x: np.ndarray, cutoff: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(signed distance, closest point, normal) of points x (m, 3), exact for the points
        that may lie within ``cutoff`` of the surface; for the others (nearest centroid farther
        than cutoff plus the largest centroid-to-corner distance) a lower bound of the distance
        above ``cutoff``, along the direction from the nearest centroid (a contact needs no
        more of them)."""
        x = np.atleast_2d(np.asarray(x, float))
        dist, nearest = self.tree.query(x, k=1)
        v = x - self.centroid[nearest]
        n = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)
        d = dist - self.reach
        foot = x - d[:, None] * n
        close = np.flatnonzero(dist <= cutoff + self.reach)
        if len(close):
            d[close], foot[close], n[close] = self.frame(x[close])
        return d, foot, n

    def smooth_normal(self, x: np.ndarray) -> np.ndarray:
        """The vertex normals interpolated linearly over the closest triangle at the closest
        point (m, 3), normalised (module docstring)."""
        x = np.atleast_2d(np.asarray(x, float))
        c, face, _ = self.closest(x)
        corners = [self.vertices[self.faces[face, k]] for k in range(3)]
        w = np.clip(barycentric(c, *corners), 0.0, 1.0)
        n = np.einsum("ik,ikj->ij", w, self.vertex_normal[self.faces[face]])
        return n / np.linalg.norm(n, axis=1, keepdims=True)
