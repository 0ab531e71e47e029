"""What demos/demo_forming.py and benchmarks/forming.py share: the forming model built from
fitted in-plane moduli the caller passes in (a params file of demo_woven_fabric.py, or the
documented fit a demo or benchmark holds with its source), one experiment reformed with other
moduli (no recompilation), profiles against the fishnet drape, and the figures."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from fabricsurf.datasets import woven_fit
from fabricsurf.discretise.evaluation import eval_points, interpolate_expression
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming.flat_pattern import flat_pattern, reach
from fabricsurf.experiments.forming.stroke_log import StrokeLog
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.model.terms import (
    CrossoverFriction,
    FibreStretch,
    NormalBending,
    Shear,
    ShearLocking,
    Twist,
)
from fabricsurf.verification.drapes.fishnet import bisector_shear

KINEMATIC = {
    "shear": {"k_s": 1e-2},
    "crossover_friction": {"tau_f": 0.0},
    "shear_locking": {"k4": 0.0, "k6": 0.0},
    "normal_bending": {"k_b": 0.05},
    "twist": {"k_t": 0.05},
}
"""The inextensible, shear-free limit (stiff fibres kept): shear and bending a hundredth and
less of the fibres' moduli times the punch radius."""
TOUCH_FRACTION = 0.01
"""Points within this fraction of R of the punch's cap count as on it, as over the contact area
(verification/drapes/forming_map.py). Defined here, not imported: importing forming_map from here
changes the order the demo loads its modules in, and with it the demo's results by round-off."""


def documented_fit() -> dict:
    """The documented fit of the woven fabric (:func:`fabricsurf.datasets.woven_fit`)."""
    return json.loads(woven_fit().read_text(encoding="utf-8"))


def add_params_option(ap) -> None:
    """The forming demos' ``--params``: the params file of demo_woven_fabric.py (read by
    :func:`read_params`)."""
    ap.add_argument(
        "--params",
        type=Path,
        default=Path("out/woven/woven_params.json"),
        help="params file of demo_woven_fabric.py",
    )


def read_params(path: Path | None, out: Path) -> tuple[dict, str]:
    """The params file of demo_woven_fabric.py, or else the documented fit shipped with the
    package (:func:`fabricsurf.datasets.woven_fit`), copied to
    ``out/woven_params_documented.json``; returns (params, where they came from)."""
    if path is not None and Path(path).is_file():
        return json.loads(Path(path).read_text())["params"], str(path)
    documented = documented_fit()
    target = Path(out) / "woven_params_documented.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(documented, indent=1))
    return documented["params"], f"{target} (the values of {documented['source']})"


def forming_model(params: dict, k_b: float, k_t: float) -> list:
    """The fitted in-plane model, shear locking at zero (switched on by :func:`reform`) and the
    out-of-plane rigidities, which the in-plane fit cannot give."""
    fs, sh = params["fibre_stretch"], params["shear"]
    fr = params.get("crossover_friction", {"tau_f": 0.0})
    return [
        FibreStretch(k_l=fs["k_l"], k_m=fs["k_m"]),
        Shear(k_s=sh["k_s"]),
        CrossoverFriction(tau_f=fr["tau_f"]),
        ShearLocking(k4=0.0, k6=0.0),
        NormalBending(k_b=k_b),
        Twist(k_t=k_t),
    ]


def fitted_values(params: dict, k_bend: float) -> dict:
    """The fitted model's moduli for :func:`reform` (shear and crossover friction of the fit,
    the assumed bending and twist ``k_bend``)."""
    return {
        "shear": params["shear"],
        "crossover_friction": params.get("crossover_friction", {"tau_f": 0.0}),
        "normal_bending": {"k_b": k_bend},
        "twist": {"k_t": k_bend},
    }


def effect_variants(params: dict, k_bend: float) -> dict[str, dict]:
    """The variants of the fitted model whose effect demos/demo_forming.py shows: the bending
    weakened tenfold, and shear locking with k₄ chosen so that the model locks at 40°."""
    k4 = params["shear"]["k_s"] / math.radians(40.0) ** 2
    return {
        "bending / 10": {
            **fitted_values(params, k_bend),
            "normal_bending": {"k_b": 0.1 * k_bend},
            "twist": {"k_t": 0.1 * k_bend},
        },
        "locking at 40 deg": {**fitted_values(params, k_bend), "shear_locking": {"k4": k4}},
    }


HOLDER = {"holder_pressure": 1e-2, "friction": 0.3}
"""The holder of the demo and the benchmark: 10 kPa on the flange and a Coulomb coefficient of
0.3 between fabric and steel tools. The friction tensions the fibres, so that the sheet wraps
the punch (docs/forming.md). Their die has clearance and lip R/5 (:func:`experiment`): the
meshes must resolve them (h ≤ R/5) for the punch force to converge."""


def experiment(
    R: float, blank: float, h: float, angle: float, model: list, comm, **tooling
) -> HemispherePlugin:
    """The plug-in with its default tools (mm) and :data:`HOLDER`, ``tooling`` over them."""
    opts = HemispherePlugin.parse_options(
        {"tooling": {"punch_radius": R, **HOLDER, **tooling}}, 1.0, "forming"
    )
    return HemispherePlugin(
        PluginSetup("hemisphere", blank, blank, (angle, -angle), opts), model, h, comm
    )


def set_moduli(e: HemispherePlugin, values: dict) -> None:
    """Set moduli of the experiment's terms ({term: {modulus: value}}; no recompilation)."""
    terms = {t.name: t for t in e.model}
    for name, v in values.items():
        terms[name].set(**v)


def reform(e: HemispherePlugin, values: dict, stroke: float, steps: int, label: str = "") -> dict:
    """Set moduli ({term: {modulus: value}}), form to ``stroke`` (each step's line logged,
    prefixed with ``label``); the reduced results."""
    set_moduli(e, values)
    t0 = time.perf_counter()
    its = e.run(stroke, steps, label=label)
    prof = e.profile(e.diagonal_deg, n=81)
    on = (prof["gap"] < TOUCH_FRACTION * e.R) & (prof["X"] > 0)
    kin = np.degrees(bisector_shear(e.R, prof["X"][on]))
    cen = e.profile(e.diagonal_deg, e.element_centres())
    c_on = cen["gap"] < TOUCH_FRACTION * e.R
    c_diff = np.abs(cen["shear_deg"][c_on] - np.degrees(bisector_shear(e.R, cen["X"][c_on])))

    fib = e.profile(e.theta, n=81)

    def largest(values) -> float:
        return float(np.abs(values[on] - kin).max()) if on.any() else float("nan")

    return {
        "stroke_mm": list(e.stroke),
        "punch_force_N": list(e.force),
        "newton_iterations": list(its),
        "attempts": list(e.stepper.attempts),
        "step_log": StrokeLog.totals(e.steps),
        "seconds": time.perf_counter() - t0,
        "max_shear_deg": e.max_shear_deg(),
        **e.area_fractions(),
        "diagonal_shear_deg": prof["shear_recovered_deg"].tolist(),
        "profile": {
            "X_mm": prof["X"][on].tolist(),
            "arc_length_mm": prof["arc"][on].tolist(),
            "shear_deg": prof["shear_recovered_deg"][on].tolist(),
            "shear_per_element_deg": prof["shear_deg"][on].tolist(),
            "kinematic_shear_deg": kin.tolist(),
        },
        "fibre_profile": {
            "X_mm": fib["X"].tolist(),
            "arc_length_mm": fib["arc"].tolist(),
            "shear_deg": fib["shear_recovered_deg"].tolist(),
            "on_punch": (fib["gap"] < TOUCH_FRACTION * e.R).tolist(),
        },
        "diagonal_shear_max_diff_deg": largest(prof["shear_recovered_deg"]),
        "points_on_punch": int(on.sum()),
        "centres_max_diff_deg": float(c_diff.max()) if c_on.any() else float("nan"),
        "centres_on_punch": int(c_on.sum()),
        "per_element_max_diff_deg": largest(prof["shear_deg"]),
    }


def shear_grid(e: HemispherePlugin, n: int = 41) -> np.ndarray:
    """γ (deg) on an n × n grid of the quarter's reference points (the same on every rank)."""
    half = 0.5 * e.setup.length
    x = np.linspace(0.0, half, n)
    X, Y = np.meshgrid(x, x, indexing="xy")
    kin = e.problem.energy.kin
    gam = interpolate_expression(np.degrees(1.0) * kin.gamma, e._S)
    return eval_points(gam, np.column_stack([X.ravel(), Y.ravel()]))[:, 0].reshape(n, n)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figures(out: Path, grid: np.ndarray, blank: float, cases: dict[str, dict], R: float) -> None:
    """Shear map (the quarter mirrored to the blank), diagonal profiles against the fishnet
    drape, punch force against stroke (rank 0)."""
    plt = _plt()
    full = np.block([[grid[::-1, ::-1], grid[::-1, 1:]], [grid[:, ::-1], grid[:, 1:]]])
    fig, ax = plt.subplots(figsize=(5, 4.2))
    h = 0.5 * blank
    im = ax.imshow(full, origin="lower", extent=(-h, h, -h, h), cmap="viridis")
    ax.add_patch(plt.Circle((0, 0), R, fill=False, color="w", ls="--"))
    fig.colorbar(im, label="shear angle (deg)")
    ax.set(xlabel="x (mm, reference)", ylabel="y (mm, reference)", title="shear angle map")
    fig.savefig(out / "shear_map.png", dpi=120, bbox_inches="tight")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 4))
    for name, c in cases.items():
        p = c["profile"]
        ax.plot(p["arc_length_mm"], p["shear_deg"], "o-", ms=3, label=name)
    first = next(iter(cases.values()))["profile"]
    ax.plot(first["arc_length_mm"], first["kinematic_shear_deg"], "k--", label="fishnet drape")
    ax.set(
        xlabel="arc length from the pole (mm)",
        ylabel="shear angle (deg)",
        title="diagonal (fibre bisector), on the punch",
    )
    ax.legend(fontsize=8)
    fig.savefig(out / "diagonal_shear.png", dpi=120, bbox_inches="tight")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5, 4))
    for name, c in cases.items():
        ax.plot(c["stroke_mm"], c["punch_force_N"], "o-", ms=3, label=name)
    ax.set(xlabel="stroke (mm)", ylabel="punch force (N)", title="punch force")
    ax.legend(fontsize=8)
    fig.savefig(out / "punch_force.png", dpi=120, bbox_inches="tight")
    plt.close(fig)


def pattern_check(e, R: float, h: float, depth: float) -> dict:
    """The flat pattern of the part trimmed ``depth`` below the punch's top, against the
    inextensible drape: along the fibre through the pole (a meridian) it reaches the arc length
    R φ_t, φ_t = acos(1 − depth/R), within the contour's bound: the P1 error of r_z,
    h_max² κ/8 with h_max = √2 h and κ = 1/(R cos³ φ_t), over the meridian's slope sin φ_t
    (forming.flat_pattern). The reach along the fibres' bisector is reported beside it."""
    phi = math.acos(1.0 - depth / R)
    seg = flat_pattern(e, "height", float(e.tools.stroke.value) - depth)
    L = np.asarray(e.problem.L.value)
    fibre = math.degrees(math.atan2(L[1], L[0]))
    along = reach(seg, fibre, 8.0)
    bound = 2.0 * h**2 / (8.0 * R * math.cos(phi) ** 3) / math.sin(phi)
    return {
        "trim_depth_mm": depth,
        "fibre_reach_mm": along,
        "arc_mm": R * phi,
        "bisector_reach_mm": reach(seg, fibre + 45.0, 8.0),
        "bound_mm": bound,
        "fibre_reach_error_per_bound": abs(along - R * phi) / bound,
    }


def draw_pattern(path: Path, seg: np.ndarray, blank: float, R: float) -> None:
    """The flat pattern's outline (segments, reference mm) over the blank (rank 0)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(4.6, 4.4))
    h = 0.5 * blank
    ax.plot([-h, h, h, -h, -h], [-h, -h, h, h, -h], "k-", lw=1, label="blank")
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection(seg, colors="C3", linewidths=1.5, label="flat pattern"))
    ax.add_patch(plt.Circle((0, 0), R, fill=False, color="0.5", ls="--"))
    ax.set_aspect("equal")
    ax.set(xlabel="X (mm, flat blank)", ylabel="Y (mm, flat blank)", title="flat pattern")
    ax.legend(fontsize=8, loc="upper right")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
