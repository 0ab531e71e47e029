"""A tool given as a triangulated surface: the signed distance and normal of its closed,
outward-oriented triangle mesh at any points.

The distance is exact (to round-off) for the triangle mesh: the closest triangle is looked for
among the triangles of the k search points nearest (scipy's cKDTree; the points are the
centroids of the triangles, the larger ones cut into pieces first: closest.search_points), and
where that cannot be certain (the k-th point nearer than the best distance found plus the
reach, the largest distance from a point of a triangle to the nearest of its search points)
among all the triangles whose bounding boxes come nearer than the best distance found. Cutting
the large triangles keeps the reach near the size of the small ones, so the bound stays tight
on a CAD file's mix of long flat facets and small fillets.
The sign is that of (x − c)·N, c the closest point and N the angle-weighted pseudo-normal of
the feature that holds c (the face's normal, an edge's or a vertex's pseudo-normal): Bærentzen
& Aanæs 2005 prove it is the sign of the inside/outside for a closed, consistently oriented
mesh.

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
    search_points,
)

NEAREST = (8, 64, 512)
"""Search points examined per point, more for the points where fewer left the closest triangle
uncertain (module docstring); the rest look at the triangles whose bounding boxes are near
enough (:data:`GROUP_WORK`)."""
GROUP_WORK = 1_000_000
"""Most point–triangle pairs examined at once for the points the nearest search points leave
uncertain (a point at the centre of a ring, as on a die's axis, is as far from every triangle
of the ring): they are taken in groups of neighbours, each triangle's bounding box giving a
lower bound of its distance."""
PAIRS = 1 << 17
"""Most point–candidate pairs of the nearest search examined at once: the arrays of a stage
are about this times 3 doubles each, whatever the number of points."""
SEARCH_POINTS = 2_000_000
"""Most search points of a mesh (closest.search_points), beyond one a triangle."""


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
        table = topology.edges(self.faces)
        topology.check(self.vertices, self.faces, name, closed, table)
        self.face_normal, self.edge_normal, self.vertex_normal = topology.pseudo_normals(
            self.vertices, self.faces, table
        )
        self.points, self.owner, self.reach = search_points(
            self.vertices[self.faces], SEARCH_POINTS
        )
        self.tree = cKDTree(self.points)
        corners = self.vertices[self.faces]
        self.box = (corners.min(axis=1), corners.max(axis=1))
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
        todo, nearest = np.arange(len(x)), np.zeros(0, dtype=np.int64)
        for k in NEAREST if len(x) else ():
            k = min(k, len(self.points))
            parts = np.array_split(todo, -(-len(todo) * k // PAIRS))
            left = [self._by_nearest(x, part, k, point, face, kind, index) for part in parts]
            todo = np.concatenate([t for t, _ in left])
            nearest = np.concatenate([n for _, n in left])
            if len(todo) == 0 or k == len(self.points):
                break
        if len(todo):  # neighbours together: they share candidates
            todo = todo[np.argsort(nearest)]
        step = max(1, GROUP_WORK // len(self.faces))
        for start in range(0, len(todo), step):
            self._settle(x, todo[start : start + step], point, face, kind, index)
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

    def _by_nearest(self, x, part, k, point, face, kind, index):
        """The closest triangle of the points ``part`` among those of their k nearest search
        points, in place; returns (the points it leaves uncertain, the nearest candidate of
        each) (module docstring)."""
        dist_c, cand = self.tree.query(x[part], k=k)
        dist_c = dist_c.reshape(len(part), k)
        cand = _distinct(self.owner[cand.reshape(len(part), k)])
        q, d2, kd, ix = self._closest_among(x[part], cand)
        j, rows = np.argmin(d2, axis=1), np.arange(len(part))
        point[part], face[part] = q[rows, j], cand[rows, j]
        kind[part], index[part] = kd[rows, j], ix[rows, j]
        sure = (dist_c[:, -1] >= np.sqrt(d2[rows, j]) + self.reach) | (k == len(self.points))
        return part[~sure], cand[~sure, 0]

    def _settle(self, x, group, point, face, kind, index) -> None:
        """The closest triangle of the points ``group`` that the search points left uncertain,
        in place: for each point, among the triangles whose bounding boxes come nearer than the
        best found (a lower bound of each triangle's distance)."""
        best2 = ((x[group] - point[group]) ** 2).sum(axis=1)
        gap = np.maximum(self.box[0][None] - x[group, None], 0.0)
        gap += np.maximum(x[group, None] - self.box[1][None], 0.0)
        slack = (1e-12 * self.size) ** 2  # a point on a triangle may round off its box
        rows, cols = np.nonzero((gap**2).sum(axis=2) <= best2[:, None] * (1 + 1e-12) + slack)
        counts = np.bincount(rows, minlength=len(group))
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        cand = np.repeat(cols[first][:, None], counts.max(), axis=1)  # padded with a repeat
        cand[rows, np.arange(len(rows)) - first[rows]] = cols
        q, d2, kd, ix = self._closest_among(x[group], cand)
        j, r = np.argmin(d2, axis=1), np.arange(len(group))
        point[group], face[group] = q[r, j], cand[r, j]
        kind[group], index[group] = kd[r, j], ix[r, j]

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
        within ``cutoff`` (> 0) of the surface, inside or out: those with a search point within
        ``cutoff`` plus the reach are projected. The others carry the lower bound ``cutoff``
        of their distance, with the normal e_z and the foot below them: a contact needs
        nothing more of them, if none lies deeper than ``cutoff`` inside. Their tree search
        stops at that bound, so points far from the tool cost little."""
        x = np.atleast_2d(np.asarray(x, float))
        dist, _ = self.tree.query(x, k=1, distance_upper_bound=cutoff + self.reach)
        d, n = np.full(len(x), float(cutoff)), np.tile([0.0, 0.0, 1.0], (len(x), 1))
        foot = x - d[:, None] * n
        close = np.flatnonzero(np.isfinite(dist))
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


def _distinct(cand: np.ndarray) -> np.ndarray:
    """The distinct entries of each row of ``cand`` (m, k), padded with repeats of the row's
    first to the most any row has (the pieces of a cut triangle share their owner)."""
    cand = np.sort(cand, axis=1)
    new = np.ones(cand.shape, dtype=bool)
    new[:, 1:] = cand[:, 1:] != cand[:, :-1]
    rows, cols = np.nonzero(new)
    counts = new.sum(axis=1)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    out = np.repeat(cand[:, :1], counts.max(), axis=1)
    out[rows, np.arange(len(rows)) - first[rows]] = cand[rows, cols]
    return out


class Tracked:
    """The frame (signed distance, foot, normal) of points that move a little between calls,
    as a contact table needs it at every Newton iteration: exact within ``exact`` of the
    surface ``surface`` (with ``near``), and at most as exact as ``near(x, bound)`` beyond.
    The distance is 1-Lipschitz: a point that was d₀ from the surface when it was last
    projected and has moved δ since is at least d₀ − δ outside. Where that bound exceeds
    ``exact`` the point keeps its normal and takes the bound as its distance, without a search;
    the others are projected again (``near`` with ``bound``)."""

    def __init__(self, surface, exact: float, bound: float) -> None:
        self.surface, self.exact, self.bound = surface, float(exact), float(bound)
        self._x = self._d = self._n = None

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = np.atleast_2d(np.asarray(x, float))
        if self._x is None or len(self._x) != len(x):
            self._x, self._d = np.full(x.shape, np.nan), np.zeros(len(x))
            self._n = np.zeros(x.shape)
        with np.errstate(invalid="ignore"):
            d = self._d - np.linalg.norm(x - self._x, axis=1)
            todo = np.flatnonzero(~(d > self.exact))  # never projected: NaN
        n = self._n.copy()
        if len(todo):
            d[todo], _, n[todo] = self.surface.near(x[todo], self.bound)
            self._x[todo], self._d[todo], self._n[todo] = x[todo], d[todo], n[todo]
        return d, x - d[:, None] * n, n
