"""The kinematic drapes over the whole punch: the fishnet (fishnet.py) and the Goursat net
(goursat_drape.py), two constructions that share no code, evaluated at any reference points of
the blank, compared with each other and with a continuum result's shear angles, and drawn as a
map of the differences.

Both drapes start at the pole of the sphere of radius R with their fibres through it along great
circles (mirror planes of the benchmark) and tend to the same Chebyshev net as their cell size
a → 0, each at O(a²): their difference is a measure of the discretisation error of either, and a
continuum result in its kinematic limit (stiff fibres, soft shear and bending) should approach
them wherever the sheet lies on the punch. Shear angles are compared at the same reference
(blank-plane) points: with inextensible fibres the reference coordinates along the fibres are
the arc lengths u, v of the net.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from fabricsurf.verification.drapes import fishnet, goursat_drape

REACH = 0.5 * math.pi
"""Fibre arc length the nets cover from the pole, in punch radii (a quarter great circle: every
point of the hemisphere has |u|, |v| below it, the generators being the longest way there)."""


def fishnet_shear_at(net: fishnet.Net, points: np.ndarray) -> np.ndarray:
    """γ (rad) of the fishnet's interior nodes (central differences, fishnet.node_shear) at
    reference points, bilinear in the fibre coordinates (u, v) = a (i, j)."""
    uv = fishnet.fibre_coordinates(points, net.angles_deg)
    k = np.arange(-(net.n - 1), net.n) * net.a
    if np.abs(uv).max() > k[-1] * (1 + 1e-12):
        raise ValueError(f"drape map: a point lies beyond the fishnet (|u|, |v| ≤ {k[-1]:g})")
    return RegularGridInterpolator((k, k), fishnet.node_shear(net))(uv)


def drapes_at(
    R: float, points: np.ndarray, angles_deg: tuple[float, float], a: float | None = None
) -> dict[str, np.ndarray]:
    """Both drapes' γ (deg) at reference points (rows, mm), cell size ``a`` (default R/100), and
    the polar angle (deg) of each point draped by the Goursat net (a point is on the cap of the
    punch below 90°). The nets reach as far along the fibres as the farthest point."""
    a = R / 100.0 if a is None else a
    points = np.asarray(points, float)
    reach = np.abs(fishnet.fibre_coordinates(points, angles_deg)).max()
    fish = fishnet.drape(R, a, math.ceil(reach / a) + 2, tuple(angles_deg))
    net = goursat_drape.hemisphere(R, tuple(angles_deg), a, reach + a)
    x = net.position_at(points)
    polar = np.degrees(np.arccos(np.clip(x[:, 2] / np.linalg.norm(x, axis=1), -1.0, 1.0)))
    return {
        "fishnet_deg": np.degrees(fishnet_shear_at(fish, points)),
        "goursat_deg": np.degrees(net.shear_at(points)),
        "polar_deg": polar,
    }


def differences(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    """Largest and root-mean-square |a − b| (deg)."""
    d = np.asarray(a) - np.asarray(b)
    return {"max_deg": float(np.abs(d).max()), "rms_deg": float(np.sqrt(np.mean(d * d)))}


def cap_grid(
    R: float, angles_deg: tuple[float, float], spacing: float, polar_max_deg: float
) -> np.ndarray:
    """Reference points of a square grid (``spacing``) over the quarter x, y ≥ 0 whose draped
    position lies at a polar angle below ``polar_max_deg`` (the Goursat net's, cell R/20: the
    region only, not the compared values)."""
    k = np.arange(0.0, REACH * R, spacing)
    pts = np.column_stack([g.ravel() for g in np.meshgrid(k, k, indexing="ij")])
    net = goursat_drape.hemisphere(R, tuple(angles_deg), R / 20.0, REACH * R)
    uv = net.fibre_coordinates(pts)
    pts = pts[np.abs(uv).max(axis=1) <= REACH * R]
    x = net.position_at(pts)
    polar = np.degrees(np.arccos(np.clip(x[:, 2] / np.linalg.norm(x, axis=1), -1.0, 1.0)))
    return pts[polar < polar_max_deg]


def drape_agreement(
    R: float, a: float, angles_deg: tuple[float, float], points: np.ndarray
) -> dict[str, float]:
    """The two drapes at cell size ``a`` against each other at reference points: max and RMS
    of the difference (deg), and the largest shear (deg) for scale."""
    d = drapes_at(R, points, angles_deg, a)
    return {
        **differences(d["fishnet_deg"], d["goursat_deg"]),
        "points": len(points),
        "largest_shear_deg": float(np.abs(d["fishnet_deg"]).max()),
    }


def shear_difference_map(
    R: float,
    points: np.ndarray,
    shear_deg: np.ndarray,
    angles_deg: tuple[float, float] = (45.0, -45.0),
    on: np.ndarray | None = None,
    a: float | None = None,
) -> dict:
    """A continuum result's shear angles (deg) at reference points (rows, mm) against both
    drapes, over the points marked ``on`` (on the punch; default all): the drapes' values there
    and the max and RMS differences continuum − fishnet, continuum − Goursat and fishnet −
    Goursat (deg)."""
    points = np.asarray(points, float)
    shear_deg = np.asarray(shear_deg, float)
    on = np.ones(len(points), bool) if on is None else np.asarray(on, bool)
    if len(shear_deg) != len(points) or len(on) != len(points):
        raise ValueError(
            f"drape map: {len(points)} points, {len(shear_deg)} shear angles, {len(on)} flags"
        )
    if not on.any():
        raise ValueError("drape map: no point on the punch to compare")
    pts, fe = points[on], shear_deg[on]
    d = drapes_at(R, pts, angles_deg, a)
    return {
        "points": pts,
        "continuum_deg": fe,
        **d,
        "continuum_vs_fishnet": differences(fe, d["fishnet_deg"]),
        "continuum_vs_goursat": differences(fe, d["goursat_deg"]),
        "fishnet_vs_goursat": differences(d["fishnet_deg"], d["goursat_deg"]),
    }


def summary(result: dict) -> dict:
    """The scalars of :func:`shear_difference_map` (for a summary.json)."""
    keys = ("continuum_vs_fishnet", "continuum_vs_goursat", "fishnet_vs_goursat", "excluded")
    return {k: result[k] for k in keys if k in result} | {"points": len(result["points"])}


def draw_difference_map(path: Path, result: dict, R: float) -> None:
    """Three panels over the compared points (reference blank): the continuum's shear, its
    difference from the fishnet and from the Goursat net (deg). Call on one rank."""
    fe = result["continuum_deg"]
    draw_panels(
        path,
        result["points"],
        R,
        fe,
        "continuum shear (deg)",
        [
            (fe - result["fishnet_deg"], "continuum − fishnet (deg)"),
            (fe - result["goursat_deg"], "continuum − Goursat net (deg)"),
        ],
    )


def draw_panels(
    path: Path,
    points: np.ndarray,
    R: float,
    shear: np.ndarray,
    label: str,
    diffs: list[tuple[np.ndarray, str]],
    title: str = "",
) -> None:
    """A shear map and difference maps side by side over reference ``points``, the punch's
    outline dashed; the differences on one symmetric colour scale. Call on one rank."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = points
    lim = max(float(np.abs(v).max()) for v, _ in diffs)
    panels = [(shear, label, {"cmap": "viridis"})] + [
        (v, t, {"cmap": "coolwarm", "vmin": -lim, "vmax": lim}) for v, t in diffs
    ]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.4 * len(panels), 4))
    for ax, (v, text, kw) in zip(axes, panels):
        im = ax.tricontourf(p[:, 0], p[:, 1], v, levels=21, **kw)
        ax.add_patch(plt.Circle((0, 0), R, fill=False, color="k", ls="--", lw=0.8))
        ax.set(aspect="equal", xlabel="x (mm, reference)", title=text)
        fig.colorbar(im, ax=ax, shrink=0.8)
    axes[0].set_ylabel("y (mm, reference)")
    if title:
        fig.suptitle(title)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
