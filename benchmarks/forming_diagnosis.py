"""Forming data with a hidden effect, diagnosed (docs/forming.md "In the loop").

Synthetic hemisphere data (fabricsurf/inverse/synthetic/formed_part.py): the punch force at every
stroke step and the shear angles at points of the formed part (an optical system's grid over
the die opening, all four quarters of the blank, at mid-stroke and at the end), made with a
model holding a hidden effect, plus Gaussian noise of known size; then ``diagnose`` from a
baseline without it. Cases (``--case``):

* ``locking``: a deep stroke with friction under the holder (the sheet wraps the punch and
  shears), a soft shear modulus, and shear locking (¼k₄γ⁴) hidden; the baseline holds
  fibre_stretch (fixed: known from a tensile test), shear, normal_bending and twist;
* ``bending``: a shallow frictionless stroke (the sheet spans the punch, held by its shear and
  bending stiffness), normal bending hidden; the baseline holds fibre_stretch, shear, twist.
* ``none``: the locking set-up with nothing hidden (the diagnosis must add nothing).
* ``dd_locking``, ``dd_none``: the same over the double dome of demos/demo_double_dome.py
  (fabricsurf/studies/double_dome.py) at the scale of the 60 mm blank, domes of radius 10 mm in
  a slot with round ends, given to the plug-in as a triangle mesh, with Coulomb friction 0.3
  on the punch as well; the shear points on a grid over the slot.

The data are made on a mesh ``--data-h`` (default: the fit's h, so that the discretisation
error stays out of the verdict; a finer one shows what it adds). Prints the data's sizes, the
baseline and final misfits, the ranking with every refit, the verdict and the time.

    .venv/bin/python benchmarks/forming_diagnosis.py --case locking [--k4 0.1] [--candidates a,b]
        [--quiet]
"""

from __future__ import annotations

import argparse
import logging

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import formed_part as sf
from fabricsurf.log import configure, detail, rank0
from fabricsurf.model.terms import make_term
from fabricsurf.studies import double_dome as dd

logger = logging.getLogger(__name__)

R, BLANK = 20.0, 60.0
TOOLS = {
    "punch_radius": R,
    "clearance": 2.0,
    "die_lip": 2.0,
    "holder_gap": 0.4,
    "contact_stiffness": 100.0,
}
CASES = {
    "locking": {
        "tools": {"holder_pressure": 1e-2, "friction": 0.3},
        "stroke": 12.0,
        "steps": 6,
        "truth": {
            "fibre_stretch": {"k_l": 1e3, "k_m": 1e3},
            "shear": {"k_s": 0.01},
            "shear_locking": {"k4": 1.0, "k6": 0.0},
            "normal_bending": {"k_b": 1e-3},
            "twist": {"k_t": 1e-3},
        },
        "baseline": ["fibre_stretch", "shear", "normal_bending", "twist"],
        "fixed": ["fibre_stretch"],
    },
    "bending": {
        "tools": {"holder_pressure": 1e-3},
        "stroke": 4.0,
        "steps": 4,
        "truth": {
            "fibre_stretch": {"k_l": 1e3, "k_m": 1e3},
            "shear": {"k_s": 1.0},
            "normal_bending": {"k_b": 0.1},
            "twist": {"k_t": 0.1},
        },
        "baseline": ["fibre_stretch", "shear", "twist"],
        "fixed": [],
    },
}
CASES["none"] = dict(
    CASES["locking"],
    truth={k: v for k, v in CASES["locking"]["truth"].items() if k != "shear_locking"},
)
DD_R, DD_C = 10.0, 2.0
"""The double dome's radius and its clearance to the die (mm)."""
DD_TOOLS = {
    "punch_radius": DD_R,
    "die_opening_length": (2.0 + dd.TOOL["spacing"]) * DD_R + 2.0 * DD_C,
    "die_opening_width": 2.0 * (DD_R + DD_C),
    "punch_friction": dd.PUNCH_FRICTION,
}
for name in ("locking", "none"):
    CASES[f"dd_{name}"] = dict(
        CASES[name],
        tools=CASES[name]["tools"] | DD_TOOLS,
        stroke=0.75 * DD_R,
        h=2.0,
        double_dome=True,
    )


def slot_points(n: int) -> np.ndarray:
    """An n × n grid over the double dome's slot, kept inside it, in the data's frame."""
    a, b = 0.5 * DD_TOOLS["die_opening_length"], 0.5 * DD_TOOLS["die_opening_width"]
    x, y = np.meshgrid(np.linspace(-a, a, n), np.linspace(-b, b, n))
    beyond = np.maximum(np.abs(x) - (a - b), 0.0)
    inside = np.hypot(beyond, y) < b
    return np.column_stack([x[inside], y[inside]]) + 0.5 * BLANK


def data(case: dict, h: float, force_noise: float, shear_noise: float, comm):
    """The synthetic experiment of ``case`` (noise: a fraction of the largest force, deg)."""
    n, double_dome = case["steps"], case.get("double_dome", False)
    exp = sf.hemisphere_template(
        BLANK,
        TOOLS | case["tools"],
        np.linspace(case["stroke"] / n, case["stroke"], n),
        slot_points(8) if double_dome else sf.part_points(BLANK, R, 8),
        shear_steps=[n // 2, n],
    )
    if double_dome:
        exp.setup.options["punch_surface"] = dd.punch(DD_R, comm)
    truth = [make_term(k, **v) for k, v in case["truth"].items()]
    sf.forming_data(exp, truth, h, comm)
    return sf.add_forming_noise(
        exp, force_noise * float(np.abs(exp.force).max()), shear_noise, seed=11
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=sorted(CASES), default="locking")
    ap.add_argument("--h", type=float, default=None, help="element size of the fit (mm)")
    ap.add_argument("--data-h", type=float, default=None, help="element size of the data")
    ap.add_argument(
        "--force-noise",
        type=float,
        default=0.01,
        help="force noise as a fraction of the largest force",
    )
    ap.add_argument("--shear-noise", type=float, default=0.5, help="shear noise (deg)")
    ap.add_argument("--candidates", default=None, help="comma-separated (default: all seen)")
    ap.add_argument(
        "--k4",
        type=float,
        default=None,
        help="shear locking's k4 of the locking case (N/mm, default 1)",
    )
    ap.add_argument(
        "--quiet", action="store_true", help="no progress of the diagnosis, only its result"
    )
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    say = lambda s: rank0(logger, comm, s)  # noqa: E731
    case = CASES[a.case]
    a.h = a.h or case.get("h", 4.0)
    if a.k4 is not None and "shear_locking" in case["truth"]:
        case["truth"] = case["truth"] | {"shear_locking": {"k4": a.k4, "k6": 0.0}}
    t0 = MPI.Wtime()
    exp = data(case, a.data_h or a.h, a.force_noise, a.shear_noise, comm)
    say(
        f"case {a.case}: {len(exp.steps)} strokes to {exp.path[-1]:g} mm, punch force up to "
        f"{np.abs(exp.force).max():.3g} N (noise {exp.force_noise_std:.3g} N), "
        f"{len(exp.shear)} shear angles up to {np.abs(exp.shear).max():.3g}° (noise "
        f"{exp.shear_noise_deg:g}°); data in {MPI.Wtime() - t0:.1f} s"
    )
    t1 = MPI.Wtime()
    cands = a.candidates.split(",") if a.candidates else None
    with detail(a.quiet):  # its progress: the double dome's takes the better part of an hour
        d = diagnose(
            [exp],
            case["baseline"],
            h=a.h,
            params=case["truth"],
            comm=comm,
            fixed=case["fixed"] or None,
            candidates=cands,
            check_discretisation=False,
        ).as_dict()
    say(f"baseline {'+'.join(case['baseline'])}: misfit {d['baseline']['misfit']:.3f}")
    for q in d["ranking"]:
        say(
            f"  {q['effect']:18s} score {q['score']:10.4g}  refit misfit "
            f"{q.get('refit_misfit') or float('nan'):.3f}  significant "
            f"{q.get('significant')}"
        )
    say(
        f"verdict {d['verdict']}; adequate {d['adequate']}; path "
        + " -> ".join(
            f"{p.get('added', '+'.join(p.get('terms', [])))} ({p['misfit']:.3f})" for p in d["path"]
        )
    )
    say(f"diagnosis {MPI.Wtime() - t1:.0f} s on {comm.size} rank(s)")


if __name__ == "__main__":
    main()
