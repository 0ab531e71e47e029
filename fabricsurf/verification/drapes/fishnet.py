"""Kinematic drape of a woven sheet over a sphere: the fishnet algorithm (Mack & Taylor 1956).

The sheet is an inextensible pin-jointed net of square (or rhombic) cells of side ``a``: its
nodes are the crossings X_ij = a (i L + j M) of two fibre families with reference directions
L and M in the blank plane. Draped from the pole of a sphere of radius R (centre at the
origin, pole at (0, 0, R), blank plane tangent there), the net is fixed by two generators,
the fibres through the pole, laid along great circles (geodesics) in the directions L and M:
node i of a generator is at the polar angle i · 2 asin(a / 2R), so each chord is a. Every other
node closes a cell: it lies on the sphere at distance a from its two known neighbours
p = x_{i-1,j} and q = x_{i,j-1}. Of the two such points one is the cell's known corner
o = x_{i-1,j-1}; the other is its mirror image in the plane through the centre, p and q,

    x_ij = o − 2 (o·n) n,   n = p × q / |p × q|,

which is on the sphere and at distance a from p and q because the reflection keeps |x| and
the distances to points of the plane. The cells are swept outwards from the generators in
each quadrant (Mack & Taylor's construction; KinDrape does the same on a general mould).

The shear angle of a cell is γ = θ0 − θ, θ0 the reference angle between L and M and θ the angle
between the cell's mean fibre vectors (the sums of its two opposite edges along each family).
As a → 0 the net tends to the Chebyshev net with geodesic generators, whose fibre angle
ω = θ0 − γ obeys Hazzidakis' equation ω_uv = −K sin ω (K = 1/R², u, v arc lengths along the
fibres) with ω = θ0 on the generators (their geodesic curvature is ±ω_u, ±ω_v).
:func:`chebyshev_shear` solves that Goursat problem on its own grid: an intrinsic check of the
geometric construction, which knows nothing of the sphere's embedding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Net:
    """A draped net: ``x[i + n, j + n]`` is node (i, j) (|i|, |j| ≤ n) on the sphere, ``ref`` its
    reference position in the blank plane; cell (i, j) spans nodes i..i+1, j..j+1, with
    shear angle ``shear[i + n, j + n]`` (rad) and centre ``cell_ref`` in the blank plane."""

    R: float
    a: float
    n: int
    angles_deg: tuple[float, float]
    x: np.ndarray
    ref: np.ndarray
    shear: np.ndarray
    cell_ref: np.ndarray
    cell_x: np.ndarray

    def on_punch(self, z_min: float = 0.0) -> np.ndarray:
        """Cells whose four corners lie at z ≥ z_min (on the hemisphere for z_min = 0)."""
        z = self.x[..., 2] >= z_min
        return z[:-1, :-1] & z[1:, :-1] & z[:-1, 1:] & z[1:, 1:]

    def polar_arc(self) -> np.ndarray:
        """Arc length from the pole along the sphere to each cell's centre, R · polar angle."""
        c = self.cell_x
        return self.R * np.arccos(np.clip(c[..., 2] / np.linalg.norm(c, axis=-1), -1.0, 1.0))


def unit(deg: float) -> np.ndarray:
    t = math.radians(deg)
    return np.array([math.cos(t), math.sin(t)])


def fibre_coordinates(points: np.ndarray, angles_deg: tuple[float, float]) -> np.ndarray:
    """(u, v) of reference points (rows of the blank plane): X = u L + v M, the fibres at
    ``angles_deg``."""
    L, M = unit(angles_deg[0]), unit(angles_deg[1])
    return np.linalg.solve(np.column_stack([L, M]), np.asarray(points, float).T).T


def generator(R: float, a: float, direction: np.ndarray, n: int) -> np.ndarray:
    """Nodes 0..n of the great circle from the pole along the blank-plane unit ``direction``,
    consecutive chords a."""
    phi = np.arange(n + 1) * 2.0 * math.asin(a / (2.0 * R))
    e = np.array([direction[0], direction[1], 0.0])
    return R * (np.outer(np.sin(phi), e) + np.outer(np.cos(phi), [0.0, 0.0, 1.0]))


def close_cell(o: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The fourth corner: o mirrored in the plane through the centre, p and q."""
    nrm = np.cross(p, q)
    nrm /= np.linalg.norm(nrm)
    return o - 2.0 * np.dot(o, nrm) * nrm


def drape(R: float, a: float, n: int, angles_deg: tuple[float, float] = (0.0, 90.0)) -> Net:
    """Fishnet drape from the pole of nodes |i|, |j| ≤ n (module docstring)."""
    if not 0 < a < 2 * R or n < 1:
        raise ValueError(f"fishnet: need 0 < a < 2R and n ≥ 1 (a = {a}, R = {R}, n = {n})")
    L, M = unit(angles_deg[0]), unit(angles_deg[1])
    return close_net(
        R,
        a,
        angles_deg,
        {(0, s): generator(R, a, s * L, n) for s in (1, -1)}
        | {(1, s): generator(R, a, s * M, n) for s in (1, -1)},
    )


def close_net(
    R: float,
    a: float,
    angles_deg: tuple[float, float],
    generators: dict[tuple[int, int], np.ndarray],
) -> Net:
    """The net of nodes |i|, |j| ≤ n closed cell by cell from its four generator halves,
    ``generators[(f, s)]`` the n + 1 nodes from the pole along family f (0: L, 1: M) in the
    sense s = ±1, on the sphere of radius R centred at the origin, consecutive chords a (the
    great circles of :func:`drape`, or any other curves: a Chebyshev net is fixed by its two
    generators, Hazzidakis 1879)."""
    n = len(generators[(0, 1)]) - 1
    L, M = unit(angles_deg[0]), unit(angles_deg[1])
    x = np.full((2 * n + 1, 2 * n + 1, 3), np.nan)
    for s in (1, -1):
        x[n + s * np.arange(n + 1), n] = generators[(0, s)]
        x[n, n + s * np.arange(n + 1)] = generators[(1, s)]
    for si in (1, -1):
        for sj in (1, -1):
            for i in range(1, n + 1):
                for j in range(1, n + 1):
                    r, c = n + si * i, n + sj * j
                    x[r, c] = close_cell(x[r - si, c - sj], x[r - si, c], x[r, c - sj])
    k = np.arange(-n, n + 1)
    ref = a * (k[:, None, None] * L + k[None, :, None] * M)
    return Net(
        R,
        a,
        n,
        tuple(angles_deg),
        x,
        ref,
        cell_shear(x, L, M),
        0.25 * (ref[:-1, :-1] + ref[1:, :-1] + ref[:-1, 1:] + ref[1:, 1:]),
        0.25 * (x[:-1, :-1] + x[1:, :-1] + x[:-1, 1:] + x[1:, 1:]),
    )


def cell_shear(x: np.ndarray, L: np.ndarray, M: np.ndarray) -> np.ndarray:
    """γ = θ0 − θ of each cell (module docstring)."""
    lv = (x[1:, :-1] - x[:-1, :-1]) + (x[1:, 1:] - x[:-1, 1:])
    mv = (x[:-1, 1:] - x[:-1, :-1]) + (x[1:, 1:] - x[1:, :-1])
    cos_t = np.sum(lv * mv, axis=-1) / (np.linalg.norm(lv, axis=-1) * np.linalg.norm(mv, axis=-1))
    return math.acos(float(np.dot(L, M))) - np.arccos(np.clip(cos_t, -1.0, 1.0))


def node_shear(net: Net) -> np.ndarray:
    """γ at the interior nodes (shape (2n−1, 2n−1), node (i, j) at [i + n − 1, j + n − 1]) from
    the central differences along each family: exactly zero on the generators of a net that is
    mirror-symmetric about them (orthogonal fibres)."""
    x = net.x
    L, M = unit(net.angles_deg[0]), unit(net.angles_deg[1])
    lv, mv = x[2:, 1:-1] - x[:-2, 1:-1], x[1:-1, 2:] - x[1:-1, :-2]
    cos_t = np.sum(lv * mv, axis=-1) / (np.linalg.norm(lv, axis=-1) * np.linalg.norm(mv, axis=-1))
    return math.acos(float(np.dot(L, M))) - np.arccos(np.clip(cos_t, -1.0, 1.0))


def line_profile(
    net: Net, direction_deg: float, z_min: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """(arc length from the pole, shear angle in rad) of the cells whose reference centre lies
    on the ray from the pole at ``direction_deg`` in the blank plane, on the punch (z ≥ z_min),
    sorted by arc length."""
    e = unit(direction_deg)
    c = net.cell_ref
    along = c @ e
    off = np.abs(c[..., 0] * e[1] - c[..., 1] * e[0])
    sel = (off < 1e-9 * net.a) & (along > 0) & net.on_punch(z_min)
    s, g = net.polar_arc()[sel], net.shear[sel]
    order = np.argsort(s)
    return s[order], g[order]


def edge_lengths(net: Net) -> np.ndarray:
    """Lengths of all net edges (both families)."""
    x = net.x
    return np.concatenate(
        [
            np.linalg.norm(x[1:] - x[:-1], axis=-1).ravel(),
            np.linalg.norm(x[:, 1:] - x[:, :-1], axis=-1).ravel(),
        ]
    )


def chebyshev_shear(R: float, u: float, v: float, steps: int, theta0: float = math.pi / 2) -> float:
    """γ(u, v) of the Chebyshev net with geodesic generators on a sphere of radius R: Hazzidakis'
    equation γ_uv = K sin(θ0 − γ), γ = 0 on u = 0 and v = 0 (module docstring), marched on a
    ``steps`` × ``steps`` grid by the second-order box scheme (the source at the cell centre,
    from the mean of its four corners, by fixed-point iteration)."""
    K, hu, hv = 1.0 / R**2, u / steps, v / steps
    g = np.zeros((steps + 1, steps + 1))
    for i in range(steps):
        for j in range(steps):
            known = g[i + 1, j] + g[i, j + 1] - g[i, j]
            new = known
            for _ in range(6):
                mid = 0.25 * (g[i, j] + g[i + 1, j] + g[i, j + 1] + new)
                new = known + hu * hv * K * math.sin(theta0 - mid)
            g[i + 1, j + 1] = new
    return float(g[-1, -1])


def bisector_shear(
    R: float, X: np.ndarray, theta_deg: float = 45.0, a: float | None = None
) -> np.ndarray:
    """γ (rad) of the fishnet drape of fibres at ±θ at reference distances ``X`` from the pole
    along their bisector (the blank's x axis, the forming benchmarks' diagonal): the nodal
    shear of the nodes (i, i), at X = 2 a i cos θ, interpolated linearly. The net's side ``a``
    defaults to R/100 (the shear differs from the Chebyshev net's by O(a²))."""
    a = R / 100.0 if a is None else a
    X = np.asarray(X, dtype=float)
    step = 2.0 * a * math.cos(math.radians(theta_deg))
    n = math.ceil(X.max() / step) + 2
    if n * a >= 0.5 * math.pi * R * 0.999:
        raise ValueError(
            f"fishnet: the bisector to X = {X.max():g} leaves the hemisphere (R = {R:g})"
        )
    net = drape(R, a, n, (theta_deg, -theta_deg))
    g = node_shear(net)
    i = np.arange(n)
    return np.interp(X, i * step, g[n - 1 + i, n - 1 + i])
