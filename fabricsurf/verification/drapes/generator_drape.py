"""The kinematic drape with the continuum's own generators: a reference for forming set-ups
whose fibres through the pole are not geodesics (docs/forming.md, "Blanks").

A net of inextensible fibres lying on the punch is a Chebyshev net, and a Chebyshev net is
fixed by its two generators, the fibres through the pole (Hazzidakis 1879). The fishnet drape
lays them along great circles, which is the kinematic limit only where they are mirror lines of
the set-up. Elsewhere (a rectangle, a square at 30/120, an unbalanced pair) the draw-in of the
flange bends them, and the drape differs from the continuum by the generators' choice, not by
the continuum's kinematics. Here the generators are read off the continuum result itself: the
material fibre lines X = t L and X = t M through the pole, deformed, projected radially onto the
punch's cap and divided into chords a; the cells are closed from them as in the fishnet
(fishnet.close_net). What is left to compare is what inextensibility on the punch dictates
given the generators: the shear everywhere else on the contact area.

A generator node is only on the punch up to where its fibre leaves the cap; a net cell (i, j)
depends on the generator nodes up to i and up to j, so the comparison keeps the reference
points whose fibre coordinates lie within each generator's part on the punch.
"""

from __future__ import annotations

import math

import numpy as np

from fabricsurf.discretise.evaluation import eval_points
from fabricsurf.verification.drapes import fishnet
from fabricsurf.verification.drapes.drape_map import differences, draw_panels, fishnet_shear_at

SAMPLES_PER_CHORD = 8
"""Points at which the continuum's fibre line is evaluated per chord of the net."""


def fibre_line(
    u, stroke: float, R: float, direction: np.ndarray, reach: float, a: float
) -> tuple[np.ndarray, np.ndarray]:
    """The deformed material line X = t · direction, 0 ≤ t ≤ reach, relative to the centre of
    the punch's cap (c = (0, 0, s − R)): (t, positions); the part inside the mesh (collective:
    the same on every rank)."""
    t = np.linspace(0.0, reach, math.ceil(reach / a * SAMPLES_PER_CHORD) + 1)
    X = np.outer(t, direction)
    r = np.column_stack([X, np.zeros(len(t))]) + eval_points(u, X)
    r[:, 2] -= stroke - R
    inside = np.isfinite(r).all(axis=1)
    stop = len(t) if inside.all() else int(np.argmin(inside))
    return t[:stop], r[:stop]


def chord_nodes(r: np.ndarray, R: float, a: float, n: int | None = None) -> np.ndarray:
    """Nodes on the sphere of radius R along the sampled curve r (rows) projected radially onto
    it, the first at r[0], consecutive chords a (each node interpolated between the two samples
    that straddle the chord, then projected; a sample at a chord of a to rounding is the node):
    n + 1 of them, or as many as the curve holds (n None). Raises if it holds fewer than n + 1."""
    p = R * r / np.linalg.norm(r, axis=1)[:, None]
    nodes, j = [p[0]], 1
    while n is None or len(nodes) <= n:
        last = nodes[-1]
        while j < len(p) and np.linalg.norm(p[j] - last) < a * (1 - 1e-12):
            j += 1
        if j == len(p):
            if n is None:
                break
            raise ValueError(
                f"generator drape: the fibre line ends after {len(nodes) - 1} of {n} chords"
            )
        d0, d1 = np.linalg.norm(p[j - 1] - last), np.linalg.norm(p[j] - last)
        w = (a - d0) / (d1 - d0)
        x = (1 - w) * p[j - 1] + w * p[j]
        nodes.append(R * x / np.linalg.norm(x))
    return np.array(nodes)


def on_cap(r: np.ndarray, R: float, touch: float) -> int:
    """How many leading samples of r reach to the last sample on the punch's cap (above its
    centre, less than ``touch`` outside the sphere, as the contact map counts them), where the
    fibre leaves the punch for the free span; 0 if none is on it. A coarse sheet touches the
    cap at its quadrature points and lifts off it between them by more than ``touch``, the
    pole among such points (measured in docs/forming.md, "Blanks"): samples before
    the last are kept whatever their gap, and their projection onto the cap errs by it, which
    :func:`compare` reports."""
    on = (r[:, 2] > 0) & (np.linalg.norm(r, axis=1) - R < touch)
    return int(np.flatnonzero(on)[-1]) + 1 if on.any() else 0


def continuum_net(
    u,
    stroke: float,
    R: float,
    angles_deg: tuple[float, float],
    a: float,
    reach: float,
    touch: float,
) -> tuple[fishnet.Net, dict[tuple[int, int], float], float]:
    """The net closed from the continuum's four generator halves (module docstring), as many
    chords each as the shortest holds; the reference length of each half that reaches the cap
    (keys (family, sense) as in fishnet.close_net, :func:`on_cap`); and the largest distance
    from the sphere of the generators' samples over those lengths (mm)."""
    lines, on, gap = {}, {}, 0.0
    for f, deg in enumerate(angles_deg):
        for s in (1, -1):
            t, r = fibre_line(u, stroke, R, s * fishnet.unit(deg), reach, a)
            lines[(f, s)] = r
            k = on_cap(r, R, touch)
            on[(f, s)] = float(t[k - 1]) if k else -np.inf  # -inf: nothing on the cap
            if k:
                gap = max(gap, float(np.abs(np.linalg.norm(r[:k], axis=1) - R).max()))
    gens = {k: chord_nodes(r, R, a) for k, r in lines.items()}
    n = min(len(g) for g in gens.values()) - 1
    if n < 2:
        raise ValueError(
            f"generator drape: a fibre line through the pole holds {n} chords of {a:g} mm"
        )
    gens = {k: g[: n + 1] for k, g in gens.items()}
    return fishnet.close_net(R, a, tuple(angles_deg), gens), on, gap


def compare(
    points: np.ndarray,
    shear_deg: np.ndarray,
    on_punch: np.ndarray,
    u,
    stroke: float,
    R: float,
    angles_deg: tuple[float, float],
    a: float,
    touch: float,
) -> dict:
    """The continuum's shear (deg) at reference ``points`` against the drape with its own
    generators, over the points on the punch whose fibre coordinates lie within the generators'
    parts on the cap: the compared points, both shears, max and RMS of the difference (deg),
    how many points on the punch were left out (beyond the generators' contact), and the
    generators' largest distance from the sphere where they are used."""
    uv = fishnet.fibre_coordinates(points, angles_deg)
    reach = float(np.abs(uv[on_punch]).max()) + 4 * a
    net, on, gap = continuum_net(u, stroke, R, angles_deg, a, reach, touch)
    covered = (
        (uv[:, 0] <= on[(0, 1)])
        & (uv[:, 0] >= -on[(0, -1)])
        & (uv[:, 1] <= on[(1, 1)])
        & (uv[:, 1] >= -on[(1, -1)])
        & (np.abs(uv).max(axis=1) < (net.n - 1) * a)
    )
    keep = on_punch & covered
    if not keep.any():
        raise ValueError("generator drape: no point on the punch within the generators' contact")
    drape = np.degrees(fishnet_shear_at(net, points[keep]))
    return {
        "points": points[keep],
        "continuum_deg": shear_deg[keep],
        "drape_deg": drape,
        "continuum_vs_generator_drape": differences(shear_deg[keep], drape),
        "left_out": int((on_punch & ~covered).sum()),
        "generators_on_cap_mm": on,
        "generators_largest_gap_mm": gap,
    }


def draw_map(path, result: dict, R: float, title: str = "") -> None:
    """Two panels over the compared points (reference blank): the continuum's shear and its
    difference from the drape with its own generators (deg). Call on one rank."""
    fe = result["continuum_deg"]
    draw_panels(
        path,
        result["points"],
        R,
        fe,
        "continuum shear (deg)",
        [(fe - result["drape_deg"], "continuum − drape, own generators (deg)")],
        title,
    )
