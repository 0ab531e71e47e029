"""Closest points on triangles, vectorised: the exact Euclidean distance from points to
triangles and which feature (the face, one of its edges, one of its vertices) holds the
closest point, as the angle-weighted pseudo-normal sign test needs it (Bærentzen & Aanæs
2005).

The closest point of a triangle to a point P is the foot of the perpendicular on the
triangle's plane when that foot lies inside the triangle (barycentric coordinates all ≥ 0);
otherwise it lies on the triangle's boundary, and is the nearest of the three closest points
of the edges, each the foot on the segment clamped to its ends (Ericson 2005, §5.1.5).
"""

from __future__ import annotations

import numpy as np

FACE, EDGE, VERTEX = 0, 1, 2
"""Feature kinds of a closest point."""
END_TOLERANCE = 1e-12
"""An edge parameter within this of 0 or 1 puts the closest point on the vertex."""


def closest_on_triangles(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Closest points of triangles (a, b, c) (arrays (..., 3)) to points p (broadcast
    against them): (closest points (..., 3), squared distances (...), feature kind (FACE, EDGE
    or VERTEX), local index: 0 for the face, the edge k (from corner k to corner k + 1 mod 3),
    or the vertex k)."""
    p, a, b, c = np.broadcast_arrays(p, a, b, c)
    e0, e1 = b - a, c - a
    v, s, den = _plane_coordinates(p, a, e0, e1)
    inside = (v >= 0) & (s >= 0) & (v + s <= 1) & (den > 0)
    foot = a + v[..., None] * e0 + s[..., None] * e1
    best = np.where(inside[..., None], foot, np.nan)
    best_d2 = np.where(inside, np.einsum("...i,...i", p - foot, p - foot), np.inf)
    kind = np.where(inside, FACE, -1)
    index = np.zeros(kind.shape, dtype=int)
    corners = (a, b, c)
    for k in range(3):
        s0, s1 = corners[k], corners[(k + 1) % 3]
        d = s1 - s0
        dd = np.einsum("...i,...i", d, d)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip(np.einsum("...i,...i", p - s0, d) / dd, 0.0, 1.0)
        t = np.where(dd > 0, t, 0.0)
        q = s0 + t[..., None] * d
        d2 = np.einsum("...i,...i", p - q, p - q)
        better = ~inside & (d2 < best_d2)
        best = np.where(better[..., None], q, best)
        best_d2 = np.where(better, d2, best_d2)
        at_start, at_end = t <= END_TOLERANCE, t >= 1.0 - END_TOLERANCE
        kind = np.where(better, np.where(at_start | at_end, VERTEX, EDGE), kind)
        index = np.where(better, np.where(at_start, k, np.where(at_end, (k + 1) % 3, k)), index)
    return best, best_d2, kind, index


def barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (..., 3) of points p in the planes of triangles (a, b, c)."""
    v, s, _ = _plane_coordinates(p, a, b - a, c - a)
    return np.stack([1.0 - v - s, v, s], axis=-1)


def _plane_coordinates(p, a, e0, e1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(v, s, den): p's projection on the plane of a + v e0 + s e1, and the Gram determinant
    den (0 for a degenerate triangle, where v and s are not finite)."""
    w = p - a
    d00 = np.einsum("...i,...i", e0, e0)
    d01 = np.einsum("...i,...i", e0, e1)
    d11 = np.einsum("...i,...i", e1, e1)
    d20 = np.einsum("...i,...i", w, e0)
    d21 = np.einsum("...i,...i", w, e1)
    den = d00 * d11 - d01 * d01
    with np.errstate(divide="ignore", invalid="ignore"):
        return (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den, den


PERCENTILE = 25
"""Triangles larger than this percentile of them are cut for the search (search_points)."""


def search_points(corners: np.ndarray, limit: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(points (s, 3), the triangle each belongs to (s,), reach) of triangles ``corners``
    (f, 3, 3), for a nearest-point search: each triangle larger than the smallest quarter of them
    (:data:`PERCENTILE`) is cut by longest-edge bisection (Rivara 1984) into pieces no larger
    (centroid to corner) than those, and the points are the pieces' centroids (at most about
    ``limit`` points, or one a triangle: the size grows until they fit). Every point of a
    triangle then lies within ``reach`` of one of its own search points, so a triangle whose
    points are all farther than d + reach from x holds no point within d of x, however long it
    is (a CAD file's flat faces are a few long slivers beside fillets of many small triangles)."""
    spread = _spread(corners)
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    size = max(float(np.percentile(spread, PERCENTILE)), float(np.sqrt(area.sum() / limit)), 1e-300)
    points, owner, reach = [], [], 0.0
    tri, own, count = corners, np.arange(len(corners)), 0
    while len(tri):
        s = _spread(tri)
        done = s <= size
        points.append(tri[done].mean(axis=1))
        owner.append(own[done])
        reach, count = max(reach, float(s[done].max(initial=0.0))), count + int(done.sum())
        tri, own = tri[~done], own[~done]
        if count + 2 * len(tri) > max(limit, len(corners)):
            size *= 1.5
            continue
        k = np.argmax(np.linalg.norm(np.roll(tri, -1, axis=1) - tri, axis=2), axis=1)
        rows = np.arange(len(tri))[:, None]
        a, b, c = (tri[rows[:, 0], (k + j) % 3] for j in range(3))
        m = 0.5 * (a + b)
        tri = np.concatenate([np.stack([a, m, c], axis=1), np.stack([m, b, c], axis=1)])
        own = np.concatenate([own, own])
    return np.vstack(points), np.concatenate(owner), reach


def _spread(corners: np.ndarray) -> np.ndarray:
    """The largest centroid-to-corner distance of each triangle (f, 3, 3)."""
    return np.linalg.norm(corners - corners.mean(axis=1)[:, None], axis=2).max(axis=1)
