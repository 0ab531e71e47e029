"""Wrinkling benchmark (docs/forming.md, "Wrinkling"): what the wrinkling indicator marks
against the flange's out-of-plane amplitude and a buckling estimate of its unpressed strip
(fabricsurf/verification/wrinkling.py), on meshes h = 4, 4/√2, 2 mm.

The set-up is that of tests/test_hemisphere.py's mesh convergence (R = 20 mm, a 72 mm blank at
±45°, die clearance and lip 2 mm, holder gap 0.4 mm, the holder with 10 kPa and μ = 0.3; the
test's model K = 10³ N/mm, k_s = 1 N/mm), formed to 12 mm = 0.6 R in 12 steps, in variants of
one experiment per mesh (no recompilation): the bending k_b = k_t = 0.1 N·mm (the tests')
and 1 N·mm (ten times stiffer), and the holder pressure lowered to 1 kPa. Printed per variant
and mesh: the indicator's area (fraction of the blank), the amplitude (largest residual beyond
the four-fold field), the fraction of the sample grid whose residual exceeds ``--bound``, the
overlap of the two, the hoop compression in the strip against the plate buckling load, and per
step the amplitude and the buckling ratio (when wrinkles start).

Run: ``python benchmarks/wrinkling.py [--h 4 2.83 2] [--variants ...] [--bound 0.05] [--blank 72]``
(serial or under ``mpirun -n 2``).
"""

import argparse
import logging
import math
import time

from mpi4py import MPI

from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.log import configure, rank0
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist
from fabricsurf.verification import wrinkling

logger = logging.getLogger(__name__)

comm = MPI.COMM_WORLD
R, BLANK, STROKE, STEPS = 20.0, 72.0, 12.0, 12
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
    "wrinkle_curvature": 1.0 / R,
}
CURVATURES = (1.0, 0.5, 0.25, 0.1)
"""Wrinkling curvatures κ_w of the indicator compared, in units of 1/R (the default: 1)."""
VARIANTS = {"k_b 0.1": (0.1, 1e-2), "k_b 1": (1.0, 1e-2), "k_b 0.1, 1 kPa": (0.1, 1e-3)}
"""name: (k_b = k_t in N·mm, holder pressure in N/mm²)."""


def model() -> list:
    return [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]


def run(e: HemispherePlugin, k_b: float, p_h: float, bound: float) -> dict:
    e.model[2].set(k_b=k_b)
    e.model[3].set(k_t=k_b)
    e.tools.p_h.value = p_h
    history = []

    def step(k: int, s: float) -> None:
        history.append(
            (
                s,
                wrinkling.amplitude(e)["amplitude"],
                wrinkling.buckling(e)["ratio"],
                e.area_fractions()["wrinkle"],
            )
        )

    t0 = time.perf_counter()
    try:
        e.run(STROKE, STEPS, on_step=step)
        stopped = ""
    except Exception as err:  # a step that cannot be followed: report where, go on
        stopped = f"stopped: {err}"
    c = wrinkling.compare(e, bound, tuple(f / R for f in CURVATURES))
    return {
        **c,
        "buckling": wrinkling.buckling(e),
        "history": history,
        "stopped": stopped,
        "seconds": comm.allreduce(time.perf_counter() - t0, op=MPI.MAX),
    }


def main(hs: list[float], names: list[str], bound: float, blank: float = BLANK) -> None:
    rows = []
    for h in hs:
        setup = PluginSetup("hemisphere", blank, blank, (45.0, -45.0), dict(TOOLING))
        with HemispherePlugin(setup, model(), h, comm) as e:
            dofs = 3 * e.problem.V.dofmap.index_map.size_global
            for name in names:
                k_b, p_h = VARIANTS[name]
                r = run(e, k_b, p_h, bound)
                rows.append((name, h, dofs, r))
                b = r["buckling"]
                rank0(
                    logger,
                    comm,
                    f"{name}, h = {h:.3g} mm ({dofs} DOFs, {r['seconds']:.0f} s) {r['stopped']}",
                )
                for s, a, q, w in r["history"]:
                    rank0(
                        logger,
                        comm,
                        f"  stroke {s:5.2f}: amplitude {a:.4f} mm, buckling "
                        f"ratio {q:6.2f}, indicator {w:.4f}",
                    )
                rank0(
                    logger,
                    comm,
                    "  bands (inner rho, points, largest residual): "
                    + ", ".join(f"{a:.0f}:{m:.3f}" for a, _, m in r["bands"][:8]),
                )
                rank0(
                    logger,
                    comm,
                    f"  strip: N = {b['hoop']:.3f} N/mm on {b['points']} points,"
                    f" D = {b['D']:.3f} N·mm, b = {b['b']:g} mm, N_cr "
                    f"{b['N_cr']['simply supported']:.3f} (s.s.) – "
                    f"{b['N_cr']['clamped']:.3f} (clamped) N/mm",
                )
                rank0(logger, comm, "  " + line(name, h, r))
    rank0(
        logger,
        comm,
        f"\nreference: |residual| > {bound} mm; indicator: the least principal "
        "value of the smoothed membrane force in the unheld strip below -N_cr; "
        "curvature flag: T < "
        f"-{TOOLING['wrinkle_tension']:g} N/mm and |K| > κ_w; points of the "
        f"81 × 81 sample grid of the quarter",
    )
    rank0(logger, comm, HEADER)
    for name, h, _, r in rows:
        rank0(logger, comm, line(name, h, r))


HEADER = (
    "variant           h (mm)  amplitude (mm)  ref. area  ref. points  N_hoop  N_cr(ss)  "
    "ratio | indicator: area, points, overlap, in the envelope | curvature flag, κ_w·R: "
    "area, points, overlap"
)


def line(name: str, h: float, r: dict) -> str:
    """One row of the comparison table (:data:`HEADER`)."""
    b = r["buckling"]
    m, *flags = r["indicator"]
    marks = f"{m['area']:.4f}, {m['points']}, {m['overlap']}, {m['in_region']} | " + "; ".join(
        f"{i['curvature'] * R:g}: {i['area']:.4f}, {i['points']}, {i['overlap']}" for i in flags
    )
    return (
        f"{name:16s} {h:7.3g} {r['amplitude']:15.4f} {r['reference_area']:10.4f}"
        f" {r['reference_points']:12d} {b['hoop']:7.3f} "
        f"{b['N_cr']['simply supported']:8.3f} {b['ratio']:6.2f} | {marks}"
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h", type=float, nargs="+", default=[4.0, 4.0 / math.sqrt(2.0), 2.0])
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--bound", type=float, default=0.05)
    ap.add_argument(
        "--blank",
        type=float,
        default=BLANK,
        help="side of the blank (mm; tests/test_wrinkling.py: 60)",
    )
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    main(a.h, a.variants, a.bound, a.blank)
