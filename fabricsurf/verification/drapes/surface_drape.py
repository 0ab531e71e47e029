"""The fishnet drape (Mack & Taylor 1956) over any surface given by its signed distance and
normal: a triangulated surface (an STL or OBJ file, a gmsh mesh) or an analytic one
(experiments/forming/surfaces).

The net of square (or rhombic) cells of side ``a`` is laid from a seed point on the surface
with fibre directions at two angles in the tangent plane there (from a reference direction
projected onto it). Its two generators, the fibres through the seed, are discrete geodesics
with chords a: node k + 1 is the point of the surface at distance a from node k in the plane
through node k spanned by the previous chord and the surface normal there (the discrete
geodesic condition, x_{k+1} − 2 x_k + x_{k−1} along the normal up to O(a³); on a sphere the
plane holds the centre and the generator is a great circle, as in fishnet.generator). Every
other node closes a cell: it is the point of the surface at distance a from its two known
neighbours p and q, other than the cell's known corner o. Those points lie on the circle of
the two spheres of radius a about p and q, centre m = (p + q)/2, radius √(a² − |q − p|²/4),
in the plane normal to q − p; the node is the root of the signed distance along that circle
near the far side from o (o lies on it too, half a turn away), found by Newton's method on the
circle's angle safeguarded by bisection (the distance of a triangle mesh is only piecewise
smooth). On a sphere this is fishnet.close_cell's mirror image of o, to round-off.

On a triangle mesh the surface is the triangles themselves (nodes O(h²) from the smooth
surface they approximate, h the triangle size) and the geodesic planes take the interpolated
vertex normals (TriangulatedSurface.smooth_normal, O(h²)); the face normals, O(h), would bend
the generators by O(h) per step. The shear angle of a cell is fishnet.cell_shear's, γ = θ0 − θ
between the cell's mean fibre vectors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fabricsurf.errors import InputError
from fabricsurf.verification.drapes.fishnet import cell_shear, unit

if TYPE_CHECKING:  # the protocol only: the drape itself needs numpy alone
    from fabricsurf.experiments.forming.surfaces import ToolSurface

ROOT_TOL = 1e-12
"""Tolerance of the node's signed distance, relative to the size of the coordinates."""
MAX_ITERATIONS = 100
SIGNS = ((1, 1), (1, -1), (-1, 1), (-1, -1))
"""The net's quadrants: the senses of the L and M generator halves that bound each."""
SEED_TOLERANCE = 1e-2
"""A seed farther from the surface than this times the cell side is refused; a nearer one is
moved onto the surface along its normal."""


@dataclass
class SurfaceNet:
    """The draped net: node (i, j) (|i|, |j| ≤ n) at ``x[i + n, j + n]``, reference position
    ``ref[i + n, j + n]`` = a (i L + j M) in the seed's tangent frame (rows of ``frame``: e1, e2,
    normal), cell (i, j) with shear angle ``shear[i + n, j + n]`` (rad), as fishnet.Net."""

    a: float
    n: int
    angles_deg: tuple[float, float]
    seed: np.ndarray
    frame: np.ndarray
    x: np.ndarray
    ref: np.ndarray
    shear: np.ndarray


def _normal(surface, x: np.ndarray) -> np.ndarray:
    smooth = getattr(surface, "smooth_normal", None)
    return (smooth or surface.normal)(x)


def on_circle(
    surface: ToolSurface,
    centre: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    radius,
    theta0: np.ndarray,
) -> np.ndarray:
    """Points c(θ) = centre + radius (cos θ u + sin θ v) (rows) where the signed distance
    vanishes, the root nearest θ0 found by safeguarded Newton (module docstring)."""
    radius = np.broadcast_to(np.asarray(radius, float), theta0.shape)
    tol = ROOT_TOL * max(1.0, float(np.abs(centre).max()))
    th = np.array(theta0, float)
    neg, pos = np.full_like(th, np.nan), np.full_like(th, np.nan)
    for _ in range(MAX_ITERATIONS):
        cs, sn = np.cos(th)[:, None], np.sin(th)[:, None]
        y = centre + radius[:, None] * (cs * u + sn * v)
        g = surface.signed_distance(y)
        if np.all(np.abs(g) <= tol):
            return y
        dg = radius * np.einsum("ij,ij->i", surface.normal(y), -sn * u + cs * v)
        neg, pos = np.where(g < 0, th, neg), np.where(g > 0, th, pos)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = th - np.clip(g / dg, -0.5, 0.5)
        lo, hi = np.minimum(neg, pos), np.maximum(neg, pos)
        out = np.isfinite(neg) & np.isfinite(pos) & ~((new > lo) & (new < hi))
        new = np.where(out | ~np.isfinite(new), 0.5 * (lo + hi), new)
        new = np.where(np.isfinite(new), new, th + 0.1)
        th = np.where(np.abs(g) <= tol, th, new)
    bad = int(np.argmax(np.abs(g)))
    raise ArithmeticError(
        f"surface drape: a node could not be placed on {getattr(surface, 'name', 'the surface')} "
        f"near {np.round(y[bad], 3).tolist()} (the net runs off the surface's edge, or its "
        "cells are too large for the surface's curvature: fewer nodes or a smaller side)"
    )


def geodesic(surface: ToolSurface, x0: np.ndarray, t0: np.ndarray, a: float, n: int) -> np.ndarray:
    """Nodes 0..n (axis 1) of the discrete geodesics from x0 along the unit tangents t0 (rows),
    chords a (module docstring)."""
    x = np.empty((len(t0), n + 1, 3))
    x[:, 0] = x0
    prev_t = t0
    for k in range(n):
        nk = _normal(surface, x[:, k])
        tn = np.einsum("ij,ij->i", prev_t, nk)
        d = prev_t - tn[:, None] * nk
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        phi0 = -np.arcsin(np.clip(tn, -1.0, 1.0)) if k else np.zeros(len(t0))
        x[:, k + 1] = on_circle(surface, x[:, k], d, nk, a, phi0)
        prev_t = (x[:, k + 1] - x[:, k]) / a
    return x


def close_cells(
    surface: ToolSurface, o: np.ndarray, p: np.ndarray, q: np.ndarray, a: float
) -> np.ndarray:
    """The fourth corners (rows) of cells with corner o and its neighbours p, q: on the
    surface, at distance a from p and q, across from o (module docstring)."""
    w = q - p
    half = 0.5 * np.linalg.norm(w, axis=1)
    if (half >= a).any():
        raise ArithmeticError("surface drape: a cell has locked (its diagonal reached 2a)")
    w /= (2.0 * half)[:, None]
    m = 0.5 * (p + q)
    u = (m - o) - np.einsum("ij,ij->i", m - o, w)[:, None] * w
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return on_circle(surface, m, u, np.cross(w, u), np.sqrt(a * a - half**2), np.zeros(len(o)))


def tangent_frame(surface: ToolSurface, seed: np.ndarray, e1) -> np.ndarray:
    """Rows e1 (the reference direction projected onto the tangent plane), e2 = n × e1, n."""
    nrm = _normal(surface, seed[None])[0]
    t1 = np.asarray(e1, float) - np.dot(e1, nrm) * nrm
    if np.linalg.norm(t1) < 1e-8:
        raise InputError("surface drape: the reference direction is normal to the surface")
    t1 /= np.linalg.norm(t1)
    return np.array([t1, np.cross(nrm, t1), nrm])


def close_net(surface: ToolSurface, gen: np.ndarray, a: float) -> np.ndarray:
    """Node (i, j), |i|, |j| ≤ n, of the net at ``x[i + n, j + n]``, closed cell by cell from its
    four generator halves ``gen`` (4 × (n + 1) × 3: L forwards, L backwards, M forwards, M
    backwards, each from the seed), every anti-diagonal of the four quadrants at once."""
    n = gen.shape[1] - 1
    q = np.empty((4, n + 1, n + 1, 3))
    for c, (si, sj) in enumerate(SIGNS):
        q[c, :, 0] = gen[0 if si > 0 else 1]
        q[c, 0, :] = gen[2 if sj > 0 else 3]
    for k in range(2, 2 * n + 1):
        i = np.arange(max(1, k - n), min(n, k - 1) + 1)
        j = k - i
        shape = q[:, i, j].shape
        o, p, r = (q[:, i - 1, j - 1], q[:, i, j - 1], q[:, i - 1, j])
        x = close_cells(surface, o.reshape(-1, 3), p.reshape(-1, 3), r.reshape(-1, 3), a)
        q[:, i, j] = x.reshape(shape)
    x = np.empty((2 * n + 1, 2 * n + 1, 3))
    k = np.arange(n + 1)
    for c, (si, sj) in enumerate(SIGNS):
        x[np.ix_(n + si * k, n + sj * k)] = q[c]
    return x


def drape(
    surface: ToolSurface,
    seed,
    a: float,
    n: int,
    angles_deg: tuple[float, float] = (0.0, 90.0),
    direction=(1.0, 0.0, 0.0),
) -> SurfaceNet:
    """The fishnet drape of nodes |i|, |j| ≤ n from ``seed`` over ``surface`` (anything with
    ``signed_distance`` and ``normal``, and optionally ``smooth_normal``), fibres at
    ``angles_deg`` from ``direction`` in the tangent plane (module docstring)."""
    if not a > 0 or n < 1:
        raise InputError(f"surface drape: need a > 0 and n ≥ 1 (a = {a}, n = {n})")
    seed = np.asarray(seed, float)
    name = getattr(surface, "name", "the surface")
    for _ in range(3):
        d = float(surface.signed_distance(seed[None])[0])
        if abs(d) > SEED_TOLERANCE * a:
            raise InputError(
                f"surface drape: the seed point {seed.round(6).tolist()} is {d:.6g} mm off "
                f"{name}; give a point on the surface"
            )
        seed = seed - d * surface.normal(seed[None])[0]
    frame = tangent_frame(surface, seed, direction)
    L, M = unit(angles_deg[0]), unit(angles_deg[1])
    t3 = np.array([s * (d @ frame[:2]) for d in (L, M) for s in (1.0, -1.0)])
    x = close_net(surface, geodesic(surface, seed, t3, a, n), a)
    kk = np.arange(-n, n + 1)
    ref = a * (kk[:, None, None] * L + kk[None, :, None] * M)
    return SurfaceNet(a, n, tuple(angles_deg), seed, frame, x, ref, cell_shear(x, L, M))


def node_shear(net: SurfaceNet) -> np.ndarray:
    """γ at the interior nodes from central differences along each family (fishnet.node_shear)."""
    x = net.x
    L, M = unit(net.angles_deg[0]), unit(net.angles_deg[1])
    lv, mv = x[2:, 1:-1] - x[:-2, 1:-1], x[1:-1, 2:] - x[1:-1, :-2]
    cos_t = np.sum(lv * mv, axis=-1) / (np.linalg.norm(lv, axis=-1) * np.linalg.norm(mv, axis=-1))
    return math.acos(float(np.dot(L, M))) - np.arccos(np.clip(cos_t, -1.0, 1.0))
