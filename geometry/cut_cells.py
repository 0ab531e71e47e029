"""The cut cells of a fibre blank (geometry/fibre_blank.py): a lattice triangle that the
blank's outline crosses keeps its part inside the blank, triangulated without slivers.

The part is the convex polygon of the triangle's corners inside the outline, the points where
its sides cross the outline and the outline's corners inside it (:func:`piece_inside`); it is
triangulated by the fan that maximises the smallest angle (:func:`fan`). No vertex leaves the
lattice triangle, so every triangle of the blank's mesh lies in one lattice parallelogram and
stiff fibres lock nowhere, the boundary row included (the module docstring of
geometry/fibre_blank.py says why). Numbers only (numpy): no mesh is built here.
"""

from __future__ import annotations

import math

import numpy as np


def _segment_inside(
    shape: str, a: float, b: float, p: np.ndarray, q: np.ndarray
) -> tuple[float, float] | None:
    """The parameter interval [t0, t1] ⊂ [0, 1] of p + t (q − p) inside the outline, or None
    (a box: Liang–Barsky clipping; a circle: the roots of |p + t v|² = a²)."""
    v = q - p
    if shape == "circle":
        A, B, C = v @ v, 2.0 * (p @ v), p @ p - a * a
        disc = B * B - 4.0 * A * C
        if disc <= 0.0:
            return None
        s = math.sqrt(disc)
        t0, t1 = max(0.0, (-B - s) / (2 * A)), min(1.0, (-B + s) / (2 * A))
    else:
        t0, t1 = 0.0, 1.0
        for k, half in ((0, a), (1, b)):
            if abs(v[k]) < 1e-300:
                if abs(p[k]) > half:
                    return None
                continue
            lo, hi = sorted(((-half - p[k]) / v[k], (half - p[k]) / v[k]))
            t0, t1 = max(t0, lo), min(t1, hi)
    return (t0, t1) if t1 - t0 > 1e-12 else None


def piece_inside(
    shape: str,
    a: float,
    b: float,
    P: np.ndarray,
    corners: np.ndarray,
    inside: np.ndarray,
    merge: float,
) -> np.ndarray:
    """The points of the lattice triangle P (3 × 2) ∩ the blank: its corners inside,
    where its sides cross the outline, and the outline's corners inside P; all lie on the
    piece's boundary, which is convex. No sliver is made: a crossing within ``merge`` (mm) of
    the side's end is moved onto that end (along the side; an end outside the outline becomes
    a vertex, at most ``merge`` outside), and an outline corner within ``merge`` of a crossing
    is left out (the corner is cut off)."""
    pts = [P[k] for k in range(3) if inside[k]]
    cross = []
    for k in range(3):
        p, q = P[k], P[(k + 1) % 3]
        if tuple(q) < tuple(p):  # each edge the same way round from both its triangles
            p, q = q, p
        span = _segment_inside(shape, a, b, p, q)
        if span is None:
            continue
        for t in span:
            if 0.0 < t < 1.0:
                m = merge / np.linalg.norm(q - p)
                cross.append(p if t < m else q if t > 1.0 - m else p + t * (q - p))
    pts += cross
    T = np.linalg.inv(np.column_stack([P[1] - P[0], P[2] - P[0]]))
    side = min(np.linalg.norm(P[k] - P[k - 1]) for k in range(3))
    for c in corners:
        st = T @ (c - P[0])
        near = any(np.linalg.norm(c - x) < merge for x in cross)
        if (st > 1e-12).all() and st.sum() < 1.0 - 1e-12 and not near:
            pts.append(c)
    pts = np.array(pts).reshape(-1, 2)
    key = np.round(pts / (1e-9 * side))
    return pts[np.sort(np.unique(key, axis=0, return_index=True)[1])]


def fan(pts: np.ndarray) -> list[tuple[int, int, int]]:
    """Triangles of the convex polygon ``pts`` (unordered, all on its boundary): a fan from
    the vertex that maximises the smallest angle, ties broken by a rule symmetric under
    X → −X; [] if the polygon has no area."""
    c = pts.mean(axis=0)
    order = np.argsort(np.arctan2(*(pts - c).T[::-1]))
    pts = pts[order]
    n, best = len(pts), None
    for k in range(n):
        tris = [(k, (k + i) % n, (k + i + 1) % n) for i in range(1, n - 1)]
        score = min(min_angle(pts[list(t)]) for t in tris)
        key = (round(score, 9), round(math.atan2(*(pts[k] - c)[::-1]) % math.pi, 9))
        if score > 1e-9 and (best is None or key > best[0]):
            best = (key, tris)
    return [] if best is None else [tuple(order[list(t)]) for t in best[1]]


def min_angle(T: np.ndarray) -> float:
    e = [T[(k + 1) % 3] - T[k] for k in range(3)]
    ang = [abs(math.atan2(np.cross(-e[k - 1], e[k]), -e[k - 1] @ e[k])) for k in range(3)]
    return min(ang)
