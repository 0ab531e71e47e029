"""Forming a box (docs/tool_surfaces.md, "The die's opening"): a punch that is no hemisphere in
a die whose opening is no circle, at a user's size, and its cost against the cells.

The punch: a box 120 × 80 mm with fillet radius 25 mm on every edge (``--fillet``;
analytic.RoundedBox, given to the plug-in as a surface and so tabulated:
forming/tabulated_tools.py), its top at z = 0.
The die and the holder: an opening 130 × 90 mm with corner radius 15 mm (a clearance of 5 mm all
round) and a lip of 5 mm. A 240 mm square blank at ±45° (solved on the quarter), the fitted
woven fabric with the forming demo's assumed bending and its holder (10 kPa, μ = 0.3), formed
to 30 mm in 12 steps on meshes h = 5, 3.54 and 2.5 mm (``--h0``, ``--levels``); ``--locking``
gives the fabric the forming demo's shear locking at that angle, ``--softening`` and
``--stabilisation`` the punch's softened contact and the viscous drag; ``--width`` makes the
blank a rectangle 240 mm × width and ``--domain`` chooses the solved domain (a rectangle at ±45°
is solved on its quarter when its sides fit the fibre lattice). A punch whose top
is flat over a large part of it is the hard case: the sheet lies on the flat with next to no
pressure, and Newton's contact set flickers there (docs/tool_surfaces.md, "A box").

Printed per mesh: the domain solved, its cells, unknowns, Newton iterations and cut steps of the
converged steps, wall time, the last stroke reached, its punch force, the largest shear angle
and where it is (the reference position of its cell's midpoint), the largest penetration into
any tool, the share of the punch's work the drag dissipated and the wrinkle indicator's area
(a run that stops says where and why); then, over
the runs that finished, the exponent of the time's growth with the cells and the differences
of force and shear between meshes.

Run: ``mpirun -n 2 python benchmarks/forming_box.py [--h0 5] [--levels 3] [--fillet 25]
[--softening 0] [--stabilisation 0] [--locking 0] [--width 240] [--domain auto]``.
"""

import argparse
import logging
import math
import time
from itertools import pairwise

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming.stroke_log import StrokeLog
from fabricsurf.experiments.forming.surfaces import analytic
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.log import configure, rank0
from fabricsurf.studies import hemisphere_forming as parts

logger = logging.getLogger(__name__)
comm = MPI.COMM_WORLD
BLANK, STROKE, STEPS, BENDING = 240.0, 30.0, 12, 1.0


def punch(fillet: float) -> analytic.RoundedBox:
    """The box punch, its top at z = 0, its edges and corners rounded to ``fillet`` (mm)."""
    return analytic.RoundedBox((60.0, 40.0, 50.0), fillet, centre=(0.0, 0.0, -50.0))


TOOLING = {
    "punch_radius": 40.0,  # the default mesh and the indicator's curvature only
    "die_opening_length": 130.0,
    "die_opening_width": 90.0,
    "die_corner_radius": 15.0,
    "die_lip": 5.0,
    "holder_gap": 1.0,
    **parts.HOLDER,
}


def run(h: float, args: argparse.Namespace) -> dict:
    """One mesh's run with the command line's options; a run that stops (a step Newton cannot
    follow) reports where. ``args.locking``: the angle (deg) at which the fabric's shear locks
    (k₄ = k_s/γ_lock², the forming demo's variant), 0: the fitted fabric without locking."""
    tooling = {
        **TOOLING,
        "contact_softening": args.softening,
        "stabilisation": args.stabilisation,
        "blank": "square" if args.width == BLANK else "rectangle",
        "blank_domain": args.domain,
    }
    opts = HemispherePlugin.parse_options({"tooling": tooling}, 1.0, "box")
    params = parts.documented_fit()["params"]
    model = parts.forming_model(params, BENDING, BENDING)
    opts = {**opts, "punch_surface": punch(args.fillet)}
    setup = PluginSetup("hemisphere", BLANK, args.width, (45.0, -45.0), opts)
    locking = args.locking
    t0 = time.perf_counter()
    with HemispherePlugin(setup, model, h, comm) as e:
        values = parts.fitted_values(params, BENDING)
        if locking:
            values["shear_locking"] = {"k4": params["shear"]["k_s"] / math.radians(locking) ** 2}
        parts.set_moduli(e, values)
        stopped = None
        try:
            e.run(STROKE, STEPS, label=f"h = {h:.3g}: ")
        except LoadStepError as err:
            stopped = str(err)
        totals = StrokeLog.totals(e.steps)
        return {
            "h": h,
            "domain": e.domain,
            "cells": comm.allreduce(e.specimen.mesh.topology.index_map(2).size_local),
            "dofs": e.problem.V.dofmap.index_map.size_global * 3,
            "newton": totals["newton_iterations"],
            "cuts": totals["cuts"],
            "seconds": time.perf_counter() - t0,
            "stroke": e.stroke[-1],
            "force": e.force[-1],
            "max_shear": e.max_shear_deg(),
            "where": e.most_sheared(),
            "penetration": max(e.max_penetration(t) for t in ("punch", "die", "holder")),
            "damped": e.damped() / float(np.trapz(e.force, e.stroke)),
            "wrinkle": e.area_fractions()["wrinkle"],
            "stopped": stopped,
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--h0", type=float, default=5.0, help="the coarsest mesh (mm)")
    parser.add_argument("--levels", type=int, default=3, help="meshes h = h0/√2^k, k < levels")
    parser.add_argument("--fillet", type=float, default=25.0, help="the punch's fillet (mm)")
    parser.add_argument(
        "--softening", type=float, default=0.0, help="the punch's contact softening (mm)"
    )
    parser.add_argument(
        "--stabilisation", type=float, default=0.0, help="the viscous drag η (N/mm²)"
    )
    parser.add_argument(
        "--locking", type=float, default=0.0, help="the fabric's locking angle (deg; 0: none)"
    )
    parser.add_argument(
        "--width", type=float, default=BLANK, help="the blank's width along y (mm; a rectangle)"
    )
    parser.add_argument("--domain", default="auto", help="blank_domain: auto, quarter or full")
    args = parser.parse_args()
    configure()
    rows = [run(h, args) for h in (args.h0 / math.sqrt(2.0) ** k for k in range(args.levels))]

    def say(msg: str) -> None:
        rank0(logger, comm, msg)

    say(
        "    h  domain  cells   dofs  Newton cuts  wall (s)  stroke (mm)  force (N)  "
        "max shear (deg)  at (X, Y) mm  penetration (mm)  drag's share of the work  wrinkle area"
    )
    for r in rows:
        say(
            f"{r['h']:5.2f} {r['domain']:>7} {r['cells']:6d} {r['dofs']:6d} {r['newton']:7d} "
            f"{r['cuts']:4d} "
            f"{r['seconds']:9.1f} {r['stroke']:12.2f} {r['force']:10.4f} {r['max_shear']:16.2f} "
            f" ({r['where'][0]:5.1f}, {r['where'][1]:5.1f}) {r['penetration']:17.2e} "
            f"{r['damped']:25.2%} {r['wrinkle']:13.2%}"
        )
        if r["stopped"]:
            say(f"  h = {r['h']:.3g} stopped: {r['stopped']}")
    done = [r for r in rows if not r["stopped"]]
    for a, b in pairwise(done):
        growth = math.log(b["seconds"] / a["seconds"]) / math.log(b["cells"] / a["cells"])
        say(
            f"h {a['h']:.3g} -> {b['h']:.3g}: time ~ cells^{growth:.2f}, force "
            f"{b['force'] - a['force']:+.4f} N, max shear "
            f"{b['max_shear'] - a['max_shear']:+.2f} deg"
        )


if __name__ == "__main__":
    main()
