"""Forming beyond the symmetric square (docs/forming.md, "Blanks"): blanks × fibre pairs in the
kinematic limit (stiff fibres, soft shear and bending, the holder with friction), formed to
0.6 R, against both kinematic drapes over the contact area, and the punch force; run with
--h 2.83 or --k 1e5 for what the clipped lattice's boundary cells cost (the force against a
finer mesh and against stiffer fibres), with --lattice for a square on the clipped lattice.

    mpirun -n 2 python benchmarks/forming_blanks.py [--cases circle:30,120 rectangle:40,-50 ...]
        [--h 4] [--k 1e3] [--stroke 12] [--steps 12] [--domain auto|full] [--lattice] [--log]
        [--figures DIR]

Prints one row per case: blank, fibre pair, domain, cells, punch force (N), drape max / RMS over
the contact (deg), within 0.75 R max (deg), the same against the drape closed from the
continuum's own fibres through the pole (verification/drapes/generator_drape.py), seconds,
the mesh's note; or where a run stopped
(the last stroke followed and the force there). Against the quarter at the same K: run the
square with --domain auto (the quarter, h used 4.24 at --h 4), --domain full (its mesh unfolded)
and --domain full --lattice (the clipped lattice; at --h 4.2426 it is the unfolded quarter's
mesh, the outline then passing through lattice vertices).
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming import blank as forming_blank
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.geometry.fibre_blank import fibre_blank
from fabricsurf.log import PROGRESS, configure
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist
from fabricsurf.verification.drapes.forming_map import (
    compare_with_drapes,
    compare_with_generator_drape,
)
from fabricsurf.verification.drapes.generator_drape import draw_map

R = 20.0
TOOLING = {
    "punch_radius": R,
    "clearance": 2.0,
    "die_lip": 2.0,
    "holder_gap": 0.4,
    "holder_pressure": 1e-2,
    "friction": 0.3,
    "contact_stiffness": 100.0,
    "locking_angle_deg": 50.0,
    "wrinkle_tension": 1e-3,
    "wrinkle_curvature": 0.1 / R,
}
SIZES = {"square": (60.0, 60.0), "circle": (72.0, 72.0), "rectangle": (72.0, 60.0)}


def soft(k: float = 1e3) -> list:
    return [FibreStretch(k_l=k, k_m=k), Shear(k_s=1e-2), NormalBending(k_b=0.05), Twist(k_t=0.05)]


def case(
    blank: str,
    angles: tuple[float, float],
    h: float,
    k: float,
    stroke: float,
    steps: int,
    domain: str = "auto",
    tools: float = 2.0,
    size=None,
    figures: Path | None = None,
) -> dict:
    L, W = size or SIZES[blank]
    setup = PluginSetup(
        "hemisphere",
        L,
        W,
        angles,
        dict(TOOLING, blank=blank, blank_domain=domain, clearance=tools, die_lip=tools),
    )
    t = time.perf_counter()
    with HemispherePlugin(setup, soft(k), h) as e:
        try:
            e.run(stroke, steps, label="    ")
        except LoadStepError as err:
            return {
                "blank": blank,
                "fibres": angles,
                "domain": e.domain,
                "cells": e.discretisation["cells"],
                "stopped": err.last_load,
                "force": e.force[-1],
                "note": e.discretisation["mesh_note"],
                "s": time.perf_counter() - t,
            }
        m = compare_with_drapes(e, a=R / 40.0)
        inner = np.hypot(*m["points"].T) < 0.75 * R
        d = np.abs(m["continuum_deg"] - m["fishnet_deg"])
        if e.domain == "full":
            g = compare_with_generator_drape(e)
            own = g["continuum_vs_generator_drape"]
            if figures is not None and MPI.COMM_WORLD.rank == 0:
                name = f"{blank}_{L:g}x{W:g}_{angles[0]:g}_{angles[1]:g}_h{h:g}_K{k:g}.png"
                figures.mkdir(parents=True, exist_ok=True)
                draw_map(
                    figures / name,
                    g,
                    R,
                    f"{blank} {L:g} × {W:g} mm, fibres "
                    f"{angles[0]:g}/{angles[1]:g}°, h = {h:g} mm, K = {k:g} N/mm",
                )
            g_d = np.abs(g["continuum_deg"] - g["drape_deg"])
            g_d = g_d[np.hypot(*g["points"].T) < 0.75 * R]
        else:  # the quarter's generators are mirror lines: the geodesic drape is theirs
            g = {"points": m["points"], "left_out": 0}
            own, g_d = m["continuum_vs_fishnet"], d[inner]
        return {
            "blank": blank,
            "fibres": angles,
            "domain": e.domain,
            "cells": e.discretisation["cells"],
            "force": e.force[-1],
            "max": m["continuum_vs_fishnet"]["max_deg"],
            "rms": m["continuum_vs_fishnet"]["rms_deg"],
            "goursat_rms": m["continuum_vs_goursat"]["rms_deg"],
            "inner_max": float(d[inner].max()),
            "points": len(m["points"]),
            "gen_max": own["max_deg"],
            "gen_rms": own["rms_deg"],
            "gen_inner_max": float(g_d.max()),
            "gen_points": len(g["points"]),
            "gen_left_out": g["left_out"],
            "largest": float(np.abs(m["fishnet_deg"]).max()),
            "pins": e.pin_reactions(),
            "note": e.discretisation["mesh_note"],
            "s": time.perf_counter() - t,
        }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument(
        "--cases",
        nargs="+",
        default=[
            "square:45,-45",
            "circle:30,120",
            "circle:40,-50",
            "circle:20,-50",
            "rectangle:30,120",
            "rectangle:40,-50",
        ],
    )
    ap.add_argument("--h", type=float, default=4.0)
    ap.add_argument("--k", type=float, default=1e3)
    ap.add_argument("--stroke", type=float, default=12.0)
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--domain", default="auto")
    ap.add_argument(
        "--tools",
        type=float,
        default=2.0,
        help="die clearance and lip (mm; 2 = R/10, the tests'; 4 = R/5, where the "
        "force converges with h ≤ 4)",
    )
    ap.add_argument("--size", type=float, nargs=2, help="blank length, width (mm)")
    ap.add_argument("--log", action="store_true", help="print each load step as it converges")
    ap.add_argument(
        "--figures",
        type=Path,
        help="write each full blank's map against its own generators' drape here",
    )
    ap.add_argument(
        "--lattice",
        action="store_true",
        help="the full blank of a symmetric square on the clipped fibre lattice "
        "(geometry/fibre_blank.py) instead of the quarter's mesh unfolded",
    )
    a = ap.parse_args()
    configure(PROGRESS if a.log else logging.WARNING)  # the load steps with --log only
    if a.lattice:
        forming_blank.blank_mesh = lambda s, dom, theta, h, comm: fibre_blank(
            "rectangle", 0.5 * s.length, 0.5 * s.width, tuple(s.fibre_angles_deg), h, comm
        )
    for c in a.cases:
        blank, pair = c.split(":")
        angles = tuple(float(v) for v in pair.split(","))
        r = case(blank, angles, a.h, a.k, a.stroke, a.steps, a.domain, a.tools, a.size, a.figures)
        if MPI.COMM_WORLD.rank == 0 and "stopped" in r:
            print(
                f"{r['blank']:9s} {a.size or SIZES[blank]} tools {a.tools:g} "
                f"{r['fibres']!s:14s} {r['domain']:7s} h={a.h:g} K={a.k:g} "
                f"cells={r['cells']:5d} STOPPED at {r['stopped']:.3f} mm of {a.stroke:g} "
                f"(F={r['force']:.4f} N there)  {r['s']:.0f} s  [{r['note']}]",
                flush=True,
            )
        elif MPI.COMM_WORLD.rank == 0:
            print(
                f"{r['blank']:9s} {a.size or SIZES[blank]} tools {a.tools:g} "
                f"{r['fibres']!s:14s} {r['domain']:7s} h={a.h:g} "
                f"K={a.k:g} cells={r['cells']:5d} F={r['force']:.4f} N  points={r['points']} "
                f"largest={r['largest']:.1f}  max={r['max']:.2f} rms={r['rms']:.3f} "
                f"(goursat rms {r['goursat_rms']:.3f}) inner max={r['inner_max']:.2f} deg; "
                f"own generators: points={r['gen_points']} (left out {r['gen_left_out']}) "
                f"max={r['gen_max']:.2f} rms={r['gen_rms']:.3f} "
                f"inner max={r['gen_inner_max']:.2f} deg  "
                f"{r['s']:.0f} s  [{r['note']}]",
                flush=True,
            )


if __name__ == "__main__":
    main()
