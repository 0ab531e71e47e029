"""The kinematic drape with the continuum's own generators over any tool surface: the check of
a forming run over a punch that is no sphere (demos/demo_double_dome.py).

A net of inextensible fibres lying on a surface is a Chebyshev net, fixed by its two
generators (Hazzidakis 1879). As generator_drape.py does on the sphere, the generators are read
off the continuum result: the material fibre lines through a seed point X_s, deformed,
projected onto the punch along its normal (x − d n), and cut into chords a. The cells are then
closed on the surface (surface_drape.close_net). Node (i, j) of the net is the material point
X_s + a (i L + j M) if the fibres neither stretch nor leave the tool, and what is compared is
the shear angle there: the continuum's recovered γ against the net's central-difference γ.

A node's position depends on every node between it and the generators (the rectangle from the
seed to it in its quadrant), so a node is compared only where the continuum's sheet lies on
the punch (|d| < ``touch``) at all of them: where the sheet spans a concave part of the tool (a
saddle between two domes) or leaves it over the die's lip, no drape applies. A solution on the
quarter is unfolded by the mid-lines' mirrors (HemispherePlugin.shear_points).
"""

from __future__ import annotations

import math

import numpy as np

from fabricsurf.discretise.evaluation import PointLocator, nodal_average
from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE
from fabricsurf.verification.drapes.drape_map import differences
from fabricsurf.verification.drapes.fishnet import cell_shear, unit
from fabricsurf.verification.drapes.surface_drape import (
    SIGNS,
    SurfaceNet,
    close_net,
    node_shear,
    tangent_frame,
)

SAMPLES_PER_CHORD = 8
"""Points at which a fibre line is evaluated per chord of the net."""


class Continuum:
    """The formed sheet of a forming plug-in ``e`` at whole-blank reference points (the frame
    centred on the punch axis): positions in the punch's frame (its top at z = 0 before the
    stroke) and the recovered shear angle, the quarter unfolded by its mirrors."""

    def __init__(self, e) -> None:
        self.e = e
        kin = e.problem.energy.kin
        self.shear = nodal_average(
            kin.gamma * (180.0 / math.pi), e.specimen.mesh, CELL_QUADRATURE_DEGREE
        )
        self.stroke = float(e.tools.stroke.value)
        self.centre = 0.5 * np.array([e.setup.length, e.setup.width])

    def at(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(positions n × 3, shear n (deg)); NaN outside the blank. Collective."""
        P = np.asarray(P, float).reshape(-1, 2)
        Q, sign = self.e.shear_points(P + self.centre)
        at = PointLocator(self.e.specimen.mesh, Q)
        u = at(self.e.problem.u)
        if self.e.domain == "quarter":
            u[:, :2] *= np.where(P < 0.0, -1.0, 1.0)
        r = np.column_stack([P, np.zeros(len(P))]) + u
        r[:, 2] -= self.stroke
        return r, sign * at(self.shear)[:, 0]


def _project(surface, x: np.ndarray) -> np.ndarray:
    for _ in range(2):
        x = x - surface.signed_distance(x)[:, None] * surface.normal(x)
    return x


def chords(surface, p: np.ndarray, a: float) -> np.ndarray:
    """Nodes along the sampled curve p (rows, on the surface) at consecutive chords a, each
    interpolated between the two samples that straddle its chord and projected onto the
    surface; as many as the curve holds (it ends where a projected node falls back within a/2
    of the last: the curve has left the part of the surface it was following)."""
    nodes, j = [p[0]], 1
    while True:
        last = nodes[-1]
        while j < len(p) and np.linalg.norm(p[j] - last) < a * (1 - 1e-12):
            j += 1
        if j == len(p):
            return np.array(nodes)
        d0, d1 = np.linalg.norm(p[j - 1] - last), np.linalg.norm(p[j] - last)
        w = (a - d0) / (d1 - d0)
        x = _project(surface, ((1 - w) * p[j - 1] + w * p[j])[None])[0]
        if not np.linalg.norm(x - last) > 0.5 * a:
            return np.array(nodes)
        nodes.append(x)


def net_from_continuum(
    sheet: Continuum, surface, seed: np.ndarray, angles_deg, a: float, reach: float, touch: float
) -> tuple[np.ndarray, int]:
    """The net's nodes (2n + 1) × (2n + 1) × 3 closed on ``surface`` from the continuum's four
    generator halves through the material point ``seed``, each taken up to where the sheet
    leaves the surface (farther than ``touch``); n the chords of the largest quadrant."""
    t = np.linspace(0.0, reach, math.ceil(reach / a * SAMPLES_PER_CHORD) + 1)
    gens = []
    for deg in angles_deg:
        for s in (1.0, -1.0):
            r, _ = sheet.at(seed + np.outer(t, s * unit(deg)))
            on = np.isfinite(r).all(axis=1)
            on[on] = np.abs(surface.signed_distance(r[on])) < touch
            stop = len(t) if on.all() else int(np.argmin(on))
            gens.append(chords(surface, _project(surface, r[:stop]), a) if stop else r[:0])
    return _quadrants(surface, gens, a)


def _quadrants(surface, gens: list[np.ndarray], a: float) -> tuple[np.ndarray, int]:
    """Each quadrant closed from its own two generator halves, as far as the shorter holds (a
    fibre that leaves the tool on one side of the seed does not shorten the net on the other);
    NaN where a quadrant does not reach."""
    size = [
        min(len(gens[0 if si > 0 else 1]), len(gens[2 if sj > 0 else 3])) - 1 for si, sj in SIGNS
    ]
    if max(size) < 2:
        raise ValueError(
            f"tool drape: the fibre lines through the seed hold fewer than 2 chords of {a:g} mm "
            "on the tool in every quadrant"
        )
    n = max(size)
    x = np.full((2 * n + 1, 2 * n + 1, 3), np.nan)
    for (si, sj), m in zip(SIGNS, size, strict=True):
        if m < 1:
            continue
        L, M = gens[0 if si > 0 else 1][: m + 1], gens[2 if sj > 0 else 3][: m + 1]
        k = np.arange(m + 1)
        x[np.ix_(n + si * k, n + sj * k)] = close_net(surface, np.stack([L, L, M, M]), a)[
            np.ix_(m + k, m + k)
        ]
    return x, n


def _reachable(on: np.ndarray, n: int) -> np.ndarray:
    """Nodes whose whole rectangle back to the seed, in their quadrant, is on the tool."""
    ok = np.zeros_like(on)
    k = np.arange(n + 1)
    for si in (1, -1):
        for sj in (1, -1):
            idx = np.ix_(n + si * k, n + sj * k)
            ok[idx] = np.logical_and.accumulate(np.logical_and.accumulate(on[idx], 0), 1)
    return ok


def seed_on_axis(sheet: Continuum, x: float, reach: float, samples: int = 400) -> np.ndarray:
    """The material point of the mid-line Y = 0 (0 ≤ X ≤ ``reach``) whose deformed position
    lies at abscissa ``x``: on a punch symmetric about y = 0 it stays on that plane."""
    X = np.linspace(0.0, reach, samples)
    r, _ = sheet.at(np.column_stack([X, np.zeros(samples)]))
    keep = np.isfinite(r[:, 0])
    if not (r[keep, 0].min() <= x <= r[keep, 0].max()):
        raise ValueError(f"tool drape: no material point of the mid-line reaches x = {x:g} mm")
    return np.array([float(np.interp(x, r[keep, 0], X[keep])), 0.0])


def compare(
    sheet: Continuum, surface, seed: np.ndarray, angles_deg, a: float, reach: float, touch: float
) -> dict:
    """The continuum's shear against the net from its own generators through the material
    point ``seed`` (module docstring), at the net's interior nodes whose rectangle back to the
    seed lies on ``surface`` (the punch in its own frame) within ``touch``: the compared
    reference points, both shears (deg), max and RMS of the difference, the nodes left out."""
    x, n = net_from_continuum(sheet, surface, seed, angles_deg, a, reach, touch)
    L, M = unit(angles_deg[0]), unit(angles_deg[1])
    k = np.arange(-n, n + 1)
    ref = seed + a * (k[:, None, None] * L + k[None, :, None] * M)
    r, shear = sheet.at(ref.reshape(-1, 2))
    d = np.full(len(r), np.inf)
    inside = np.isfinite(r).all(axis=1)
    d[inside] = surface.signed_distance(r[inside])
    valid = _reachable((np.abs(d) < touch).reshape(2 * n + 1, 2 * n + 1), n)[1:-1, 1:-1]
    frame = tangent_frame(surface, x[n, n], (1.0, 0.0, 0.0))
    net = SurfaceNet(a, n, tuple(angles_deg), x[n, n], frame, x, ref, cell_shear(x, L, M))
    drape = np.degrees(node_shear(net))
    valid &= np.isfinite(drape)
    drape = drape[valid]
    continuum = shear.reshape(2 * n + 1, 2 * n + 1)[1:-1, 1:-1][valid]
    if not valid.any():
        raise ValueError("tool drape: no node of the net lies on the tool with its generators")
    return {
        "points": ref[1:-1, 1:-1][valid],
        "continuum_deg": continuum,
        "drape_deg": drape,
        "continuum_vs_drape": differences(continuum, drape),
        "nodes": int(valid.sum()),
        "chords": n,
    }
