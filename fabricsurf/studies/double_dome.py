"""What demos/demo_double_dome.py needs: a double-dome tool set of our own dimensions (the punch
from geometry/double_dome.py, given to the forming plug-in as a surface; the die and holder
plates about a slot with round ends), one forming run per blank, the shear along measurement
lines on the part, the check against the kinematic drape over the punch, and the figures.

The dimensions scale with the domes' radius R (:data:`TOOL`, :data:`BLANK`). They are not
those of the woven-composites double-dome benchmark (docs/tool_surfaces.md, "A double
dome").
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from dolfinx import fem

from fabricsurf.discretise.evaluation import eval_points
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming.stroke_log import StrokeLog
from fabricsurf.experiments.forming.surfaces import meshes
from fabricsurf.experiments.forming.surfaces.triangulated import TriangulatedSurface
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.geometry.double_dome import double_dome_punch
from fabricsurf.studies import hemisphere_forming as parts
from fabricsurf.verification.drapes import tool_drape

TOOL = {"spacing": 1.75, "fillet": 0.3, "clearance": 0.125, "lip": 0.125, "tool_h": 0.075}
"""The tool set in multiples of the domes' radius R: the domes' centres 1.75 R apart (where
the two spheres meet, 0.52 R below their tops, before the fillet of 0.3 R), clearance to the die
and the die's lip R/8, the punch meshed with triangles of side 0.075 R at most."""
BLANK = (7.0, 5.0)
"""The blank in multiples of R (length along the domes' axis × width): 280 × 200 mm at R = 40
mm. Its sides fit the ±45° fibre lattice, so that it is solved on its quarter."""
TOUCH = 0.01
"""The sheet lies on the punch where its distance from it is below this times R."""
PUNCH_FRICTION = 0.3
"""Coulomb's coefficient between the fabric and the punch, as under the holder
(hemisphere_forming.HOLDER)."""


def punch(R: float, comm) -> TriangulatedSurface:
    """The double-dome punch (geometry/double_dome.py), its tops at z = 0."""
    points, faces = double_dome_punch(
        radius=R,
        spacing=TOOL["spacing"] * R,
        fillet=TOOL["fillet"] * R,
        h=TOOL["tool_h"] * R,
        comm=comm,
    )
    return meshes.welded(points, faces, "double-dome punch")


def tooling(R: float) -> dict:
    """The ``[tooling]`` table: the slot about the punch's outline plus the clearance, the lip,
    the forming demo's holder (hemisphere_forming.HOLDER) and :data:`PUNCH_FRICTION`."""
    c = TOOL["clearance"] * R
    return {
        "punch_radius": R,
        "clearance": c,
        "die_lip": TOOL["lip"] * R,
        "die_opening_length": (2.0 + TOOL["spacing"]) * R + 2.0 * c,
        "die_opening_width": 2.0 * (R + c),
        "holder_gap": 1.0,
        "blank": "rectangle",
        "punch_friction": PUNCH_FRICTION,
        **parts.HOLDER,
    }


def experiment(
    R: float, surface, angles: tuple[float, float], h: float, model: list, comm
) -> HemispherePlugin:
    """The forming plug-in over the double-dome tools with a blank at ``angles``."""
    opts = HemispherePlugin.parse_options({"tooling": tooling(R)}, 1.0, "double dome")
    setup = PluginSetup(
        "hemisphere", BLANK[0] * R, BLANK[1] * R, angles, {**opts, "punch_surface": surface}
    )
    return HemispherePlugin(setup, model, h, comm)


def form(e: HemispherePlugin, values: dict, stroke: float, steps: int, label: str) -> dict:
    """Form to ``stroke`` with moduli ``values``; the reduced results."""
    parts.set_moduli(e, values)
    t0 = time.perf_counter()
    e.run(stroke, steps, label=label)
    return {
        "stroke_mm": list(e.stroke),
        "punch_force_N": list(e.force),
        "step_log": StrokeLog.totals(e.steps),
        "seconds": time.perf_counter() - t0,
        "max_shear_deg": e.max_shear_deg(),
        "most_sheared_mm": list(e.most_sheared()),
        "largest_penetration_mm": max(e.max_penetration(t) for t in ("punch", "die", "holder")),
        **e.area_fractions(),
    }


def lines(sheet: tool_drape.Continuum, surface, seed: np.ndarray, R: float, n: int = 81) -> dict:
    """The shear along three measurement lines of the reference blank, each from the axis to
    the blank's edge: the domes' axis (Y = 0), the transverse line through the material point
    ``seed`` on the dome's top, and the transverse mid-line over the saddle (X = 0); with the
    formed position (the punch's frame), the distance from the punch and whether the sheet lies
    on it (:data:`TOUCH`). The same on every rank."""
    half = 0.5 * np.array([sheet.e.setup.length, sheet.e.setup.width])
    t = np.linspace(0.0, 1.0, n)
    paths = {
        "axis": np.column_stack([t * half[0], 0.0 * t]),
        "across_dome": np.column_stack([np.full(n, seed[0]), t * half[1]]),
        "across_saddle": np.column_stack([0.0 * t, t * half[1]]),
    }
    out = {}
    for name, P in paths.items():
        r, shear = sheet.at(P)
        gap = np.full(n, np.inf)
        inside = np.isfinite(r).all(axis=1)
        gap[inside] = np.abs(surface.signed_distance(r[inside]))
        out[name] = {"X": P, "r": r, "shear_deg": shear, "gap": gap, "on": gap < TOUCH * R}
    return out


def grid(sheet: tool_drape.Continuum, n: int = 61) -> dict:
    """The shear (deg) and the wrinkling indicator's marks on an n × n grid of the reference
    quarter (X, Y ≥ 0), for the maps. The same on every rank."""
    e = sheet.e
    half = 0.5 * np.array([e.setup.length, e.setup.width])
    X, Y = np.meshgrid(*(np.linspace(0.0, h, n) for h in half), indexing="xy")
    P = np.column_stack([X.ravel(), Y.ravel()])
    _, shear = sheet.at(P)
    V = fem.FunctionSpace(e.specimen.mesh, ("DG", 0))
    mark = fem.Function(V)
    mark.interpolate(fem.Expression(e.wrinkling.mark, V.element.interpolation_points()))
    Q, _ = e.shear_points(P + half)
    marked = eval_points(mark, Q)[:, 0] > 0.5
    return {"half": half, "shear_deg": shear.reshape(n, n), "wrinkle": marked.reshape(n, n)}


def drape_check(sheet: tool_drape.Continuum, surface, R: float, a: float) -> dict:
    """The sheet over the right-hand dome against the kinematic drape from its own generators
    (tool_drape.compare), seeded at the material point that lies on that dome's top."""
    setup = sheet.e.setup
    top = 0.5 * TOOL["spacing"] * R
    seed = tool_drape.seed_on_axis(sheet, top, 0.5 * setup.length)
    reach = 0.5 * math.pi * R
    out = tool_drape.compare(sheet, surface, seed, setup.fibre_angles_deg, a, reach, TOUCH * R)
    return {**out, "seed": seed}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw_force(path: Path, runs: dict[str, dict]) -> None:
    """Punch force against stroke, one curve per blank (rank 0)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5, 3.6))
    for name, run in runs.items():
        ax.plot(run["stroke_mm"], run["punch_force_N"], "o-", ms=3, label=name)
    ax.set(xlabel="stroke (mm)", ylabel="punch force (N)", title="double dome: punch force")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def draw_maps(path: Path, grids: dict[str, dict], R: float) -> None:
    """Per blank, the shear map of the reference quarter with the wrinkling indicator's points
    (black) and the outline of a dome's base at the blank's place before forming (dashed)
    (rank 0)."""
    plt = _plt()
    fig, axes = plt.subplots(1, len(grids), figsize=(5.2 * len(grids), 3.8), squeeze=False)
    top = 0.5 * TOOL["spacing"] * R
    for ax, (name, g) in zip(axes[0], grids.items(), strict=True):
        hx, hy = g["half"]
        im = ax.imshow(
            g["shear_deg"], origin="lower", extent=(0, hx, 0, hy), cmap="RdBu_r", aspect="equal"
        )
        ny, nx = g["wrinkle"].shape
        Y, X = np.mgrid[0 : hy : ny * 1j, 0 : hx : nx * 1j]
        ax.plot(X[g["wrinkle"]], Y[g["wrinkle"]], "k.", ms=2, label="wrinkling indicator")
        s = np.linspace(0.0, math.pi, 90)
        x, y = top + R * np.cos(s), R * np.sin(s)
        ax.plot(x[x >= 0], y[x >= 0], "k--", lw=0.8, label="a dome's outline (flat)")
        ax.set(title=name, xlabel="X (mm, reference)", ylabel="Y (mm, reference)")
        ax.set(xlim=(0, hx), ylim=(0, hy))
        fig.colorbar(im, ax=ax, label="shear angle (deg)")
    axes[0][0].legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def draw_lines(path: Path, profiles: dict[str, dict]) -> None:
    """The shear along the measurement lines against the reference distance from the axis,
    one panel per line, one curve per blank, the points on the punch filled (rank 0)."""
    plt = _plt()
    names = list(next(iter(profiles.values())))
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.4), squeeze=False)
    for ax, line in zip(axes[0], names, strict=True):
        for blank, prof in profiles.items():
            p = prof[line]
            s = np.abs(p["X"][:, 0] if line == "axis" else p["X"][:, 1])
            (h,) = ax.plot(s, p["shear_deg"], "-", label=blank)
            ax.plot(s[p["on"]], p["shear_deg"][p["on"]], "o", ms=3, color=h.get_color())
        ax.set(title=line.replace("_", " "), xlabel="reference distance (mm)", ylabel="shear (deg)")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
