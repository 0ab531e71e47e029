"""A second kinematic drape, independent of the fishnet: the Chebyshev net integrated as the
Goursat problem of its embedding, on any smooth implicit surface.

A net of inextensible fibres draped on a surface is a Chebyshev net: r(u, v) with u, v the arc
lengths along the two families, |r_u| = |r_v| = 1. Differentiating r_u·r_u = 1 along v and
r_v·r_v = 1 along u gives r_uv·r_u = r_uv·r_v = 0: the mixed derivative is normal to the surface,

    r_uv = λ n,    r on the surface,

a hyperbolic system whose characteristics are the fibres (Pipkin's ideal fibre-reinforced
sheets). Given the two fibres through the start point (the generators; here geodesics, as in the
fishnet and as symmetry forces on the hemisphere benchmark, whose fibres through the pole lie on
mirror planes), it fixes the net (a Goursat problem). It is integrated here on a grid of step h
in (u, v) by the centred box scheme

    x_{i+1,j+1} − x_{i+1,j} − x_{i,j+1} + x_{i,j} = λ n_c,

n_c the unit normal at the mean of the cell's four corners (two fixed-point passes), λ chosen
so that x_{i+1,j+1} lies on the surface (Newton along n_c). The generators are integrated the
same way as geodesics, r_ss = κ n, by the central scheme x_{k+1} − 2 x_k + x_{k−1} = κ n(x_k)
(the first node is the start point moved by h along the fibre and back onto the surface along
its normal). Both are second-order accurate; nothing constrains the edge lengths, which are h
only to O(h²) (the fishnet keeps them exact and closes each cell by a mirror image in the
sphere), and the surface enters only through its implicit function and gradient. The shear
angle is γ = θ0 − ∠(r_u, r_v) at the nodes from second-order differences, and at any reference
point by bilinear interpolation in (u, v).

Checked on its own (tests/test_drape.py): on a cylinder and a cone, developable, the net is the
flat net rolled onto them, zero shear, positions known in closed form; on the sphere the shear
near the start point is K sin θ0 u v (Hazzidakis' equation linearised) and converges to the
Chebyshev net's at rate 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

NEWTON_TOL = 1e-13
"""Tolerance of the projection onto the surface, relative to the size of the coordinates."""


@dataclass(frozen=True)
class Sphere:
    """|x − c|² − R² = 0."""

    R: float
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def value(self, x: np.ndarray) -> np.ndarray:
        d = x - np.asarray(self.centre)
        return np.sum(d * d, axis=-1) - self.R**2

    def gradient(self, x: np.ndarray) -> np.ndarray:
        return 2.0 * (x - np.asarray(self.centre))


@dataclass(frozen=True)
class Cylinder:
    """x² + (z − z_axis)² − ρ² = 0: radius ρ, axis along y at height z_axis."""

    rho: float
    z_axis: float = 0.0

    def value(self, x: np.ndarray) -> np.ndarray:
        return x[..., 0] ** 2 + (x[..., 2] - self.z_axis) ** 2 - self.rho**2

    def gradient(self, x: np.ndarray) -> np.ndarray:
        g = 2.0 * x
        g[..., 1] = 0.0
        g[..., 2] = 2.0 * (x[..., 2] - self.z_axis)
        return g


@dataclass(frozen=True)
class Cone:
    """x² + y² − tan²α z² = 0 (z > 0): apex at the origin, axis z, half-angle α."""

    alpha: float

    def value(self, x: np.ndarray) -> np.ndarray:
        return x[..., 0] ** 2 + x[..., 1] ** 2 - (math.tan(self.alpha) * x[..., 2]) ** 2

    def gradient(self, x: np.ndarray) -> np.ndarray:
        g = 2.0 * x
        g[..., 2] *= -(math.tan(self.alpha) ** 2)
        return g


def normal(surface, x: np.ndarray) -> np.ndarray:
    """Unit normal ∇f/|∇f| at x (rows)."""
    g = surface.gradient(x)
    return g / np.linalg.norm(g, axis=-1, keepdims=True)


def onto(surface, c: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    """c + λ n on the surface (f = 0), λ by Newton from 0, row by row."""
    scale = max(1.0, float(np.abs(c).max()))
    lam = np.zeros(c.shape[:-1])
    for _ in range(30):
        y = c + lam[..., None] * nrm
        step = surface.value(y) / np.sum(surface.gradient(y) * nrm, axis=-1)
        lam -= step
        if np.abs(step).max() < NEWTON_TOL * scale:
            return c + lam[..., None] * nrm
    raise ArithmeticError(
        "goursat drape: the projection onto the surface did not converge "
        "(a step too large for the surface's curvature?)"
    )


def geodesics(surface, x0: np.ndarray, tangents: np.ndarray, h: float, n: int) -> np.ndarray:
    """Nodes 0..n (axis 1) of the geodesics from x0 along each unit tangent (rows), step h:
    x_{k+1} = 2 x_k − x_{k−1} + κ n(x_k) on the surface (module docstring)."""
    x = np.empty((len(tangents), n + 1, 3))
    x[:, 0] = x0
    x[:, 1] = onto(surface, x0 + h * tangents, np.broadcast_to(normal(surface, x0), tangents.shape))
    for k in range(1, n):
        x[:, k + 1] = onto(surface, 2.0 * x[:, k] - x[:, k - 1], normal(surface, x[:, k]))
    return x


def sweep(surface, q: np.ndarray) -> None:
    """Fill the quadrants q[:, i, j] (i, j ≥ 1) from their generators q[:, :, 0], q[:, 0, :]
    by the box scheme, one anti-diagonal i + j = k at a time (all its cells are independent)."""
    n = q.shape[1] - 1
    for k in range(2, 2 * n + 1):
        i = np.arange(max(1, k - n), min(n, k - 1) + 1)
        j = k - i
        o, p, r = q[:, i - 1, j - 1], q[:, i, j - 1], q[:, i - 1, j]
        pred = p + r - o
        x = pred
        for _ in range(2):
            x = onto(surface, pred, normal(surface, 0.25 * (o + p + r + x)))
        q[:, i, j] = x


@dataclass
class GoursatNet:
    """The net: node (i, j) (|i|, |j| ≤ n) at u = i h, v = j h is ``x[i + n, j + n]``, reference
    position i h L + j h M in the blank plane, shear angle ``shear[i + n, j + n]`` (rad)."""

    h: float
    n: int
    L: np.ndarray
    M: np.ndarray
    x: np.ndarray
    shear: np.ndarray

    def fibre_coordinates(self, points: np.ndarray) -> np.ndarray:
        """(u, v) of reference points (rows of the blank plane): X = u L + v M."""
        return np.linalg.solve(np.column_stack([self.L, self.M]), np.asarray(points, float).T).T

    def _interpolate(self, values: np.ndarray, points: np.ndarray) -> np.ndarray:
        uv = self.fibre_coordinates(points)
        reach = self.n * self.h
        if np.abs(uv).max() > reach * (1 + 1e-12):
            raise ValueError(f"goursat drape: a point lies beyond the net (|u|, |v| ≤ {reach:g})")
        k = np.arange(-self.n, self.n + 1) * self.h
        return RegularGridInterpolator((k, k), values)(uv)

    def shear_at(self, points: np.ndarray) -> np.ndarray:
        """γ (rad) at reference points, bilinear in (u, v)."""
        return self._interpolate(self.shear, points)

    def position_at(self, points: np.ndarray) -> np.ndarray:
        """Draped positions of reference points (bilinear in (u, v), O(h²) off the surface)."""
        return self._interpolate(self.x, points)


def net_shear(x: np.ndarray, h: float, L: np.ndarray, M: np.ndarray) -> np.ndarray:
    """γ = θ0 − ∠(r_u, r_v) at every node, second-order differences (one-sided at the edges)."""
    ru = np.gradient(x, h, axis=0, edge_order=2)
    rv = np.gradient(x, h, axis=1, edge_order=2)
    cos_t = np.sum(ru * rv, axis=-1) / (np.linalg.norm(ru, axis=-1) * np.linalg.norm(rv, axis=-1))
    return math.acos(float(L @ M)) - np.arccos(np.clip(cos_t, -1.0, 1.0))


def drape(
    surface, start: np.ndarray, frame: np.ndarray, angles_deg: tuple[float, float], h: float, n: int
) -> GoursatNet:
    """The Chebyshev net from ``start`` on ``surface`` with geodesic generators along the fibre
    angles (deg, in the tangent plane's orthonormal ``frame``, rows e1, e2), nodes |i|, |j| ≤ n
    at step h."""
    if not h > 0 or n < 1:
        raise ValueError(f"goursat drape: need h > 0 and n ≥ 1 (h = {h}, n = {n})")
    L, M = (np.array([math.cos(math.radians(t)), math.sin(math.radians(t))]) for t in angles_deg)
    frame = np.asarray(frame, float)
    start = np.asarray(start, float)
    t3 = np.array([s * d @ frame for d in (L, M) for s in (1.0, -1.0)])
    gen = geodesics(surface, start, t3, h, n)
    signs = [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    q = np.empty((4, n + 1, n + 1, 3))
    for c, (si, sj) in enumerate(signs):
        q[c, :, 0] = gen[0 if si > 0 else 1]
        q[c, 0, :] = gen[2 if sj > 0 else 3]
    sweep(surface, q)
    x = np.empty((2 * n + 1, 2 * n + 1, 3))
    k = np.arange(n + 1)
    for c, (si, sj) in enumerate(signs):
        x[np.ix_(n + si * k, n + sj * k)] = q[c]
    return GoursatNet(h, n, L, M, x, net_shear(x, h, L, M))


def hemisphere(R: float, angles_deg: tuple[float, float], h: float, reach: float) -> GoursatNet:
    """The net from the pole (0, 0, R) of the sphere of radius R about the origin, the blank
    plane z = R's axes as the frame, covering |u|, |v| ≤ reach."""
    n = math.ceil(reach / h)
    return drape(Sphere(R), np.array([0.0, 0.0, R]), np.eye(3)[:2], angles_deg, h, n)
