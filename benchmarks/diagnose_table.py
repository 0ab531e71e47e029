"""The stiff-fibre diagnosis table on the full bias specimen: four cases (docs/diagnosis.md).

Hencky-lattice bias-extension data of a nearly inextensible fabric: 187 × 119 mm, lattice
spacing 2.5 mm (the generator takes the nearest spacing whose held layers sit on both specimen
ends), k_l = 1000 N/mm, k_s = 0.4 N/mm
(k_l/k_s = 2500), geodesic bending A_g = 40 N·mm (l_b = √(A_g/k_s) = 10 mm), grips holding
two node columns, 12 steps to 15 % of the length, noise 0.05 mm and 0.05 N. The cases
(hidden effect → baseline given):

* ``hidden_shear``: fibre_stretch + geodesic_bending (shear hidden);
* ``complete``: fibre_stretch + shear + geodesic_bending (nothing hidden: any verdict is a
  false alarm);
* ``weak_geodesic``: fibre_stretch + shear (geodesic bending, l_b = 10 mm, hidden);
* ``angles40_m_kn``: as ``weak_geodesic`` with fibres at ±40°, the data written in m and kN and
  read back by the loader.

Every ``--every``-th lattice node (grip and clamp layers excluded) is a measurement point.
Prints progress on rank 0 and, per case, the outcome,
``adequate``, the misfit path, the ranking (score, refit misfit, significant), the
discretisation check (h against h/2) and the wall time; writes OUT/diagnose_table.json after
every case. ``--truth`` also runs the complete model at the true moduli (the lattice–continuum
form error) and, for ``hidden_shear``, a fit of the complete model started there (is the
nested refit stuck, or is the rest form error?).

    .venv/bin/python benchmarks/diagnose_table.py --out out/diagnose_table --h 6
    mpirun -n 2 .venv/bin/python benchmarks/diagnose_table.py --out out/diagnose_table --quick
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import write_json
from fabricsurf.geometry.specimen import BIAS_LENGTH as LENGTH
from fabricsurf.geometry.specimen import BIAS_WIDTH as WIDTH
from fabricsurf.inverse.contract.data import load_experiment, write_experiment
from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardSet
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0
from fabricsurf.network import spanning_spacing

logger = logging.getLogger(__name__)

SPACING, STEPS, STRAIN = 2.5, 12, 0.15
K_L, K_S, A_G = 1000.0, 0.4, 40.0
NOISE_MM, NOISE_N = 0.05, 0.05
COMPLETE = ["fibre_stretch", "shear", "geodesic_bending"]
TRUTH = {
    "fibre_stretch": {"k_l": K_L, "k_m": K_L},
    "shear": {"k_s": K_S},
    "geodesic_bending": {"A_g": A_G},
}
CASES = {  # name: (fibre angle, baseline, written in m and kN)
    "hidden_shear": (45.0, ["fibre_stretch", "geodesic_bending"], False),
    "complete": (45.0, COMPLETE, False),
    "weak_geodesic": (45.0, ["fibre_stretch", "shear"], False),
    "angles40_m_kn": (40.0, ["fibre_stretch", "shear"], True),
}


def lattice(angle: float, every: int, length: float, width: float) -> sy.Experiment:
    """Noise-free lattice data of the module docstring at fibre angles ±``angle``."""
    path = list(np.linspace(STRAIN * length / STEPS, STRAIN * length, STEPS))
    exp = sy.template(
        length, width, path, np.zeros((0, 2)), angles=(angle, -angle), name=f"lattice_{angle:g}"
    )
    return sy.lattice_data(exp, SPACING, k_l=K_L, k_s=K_S, A_g=A_G, every=every)


def noisy(clean, seed: int):
    return sy.noisy_copy(clean, NOISE_MM, NOISE_N, seed)


def in_m_kn(exp, out: Path, comm):
    """``exp`` written in mm/N, rewritten in m/kN, read back by the loader."""
    d = out / "angles40_m_kn_data"
    if comm.rank == 0:
        write_experiment(d, exp)
        sy.rewrite_in_m_kn(d)
    comm.barrier()
    return load_experiment(d)


def truth_check(exp, case: str, h: float, comm) -> dict:
    """Misfit of the complete model at the true moduli and, for hidden shear, its fit from
    there (module docstring)."""
    fs = ForwardSet([exp], full_model(COMPLETE, TRUTH), h=h, comm=comm)
    at_truth = fs.misfit(fs.run())
    out = {"misfit_at_truth": at_truth["combined"], "chi2_at_truth": at_truth["chi2"]}
    if case == "hidden_shear":
        free = [i for i, (t, _) in enumerate(fs.params) if t.name in COMPLETE]
        t0 = time.perf_counter()
        with detail():
            r = fit(fs, free, scale_start=False, space="linear")
        out |= {
            "complete_fit_from_truth": {
                "misfit": r.misfit["combined"],
                "chi2": r.chi2,
                "params": r.params(),
                "iterations": r.iterations,
                "seconds": time.perf_counter() - t0,
            }
        }
    return out


def summary(d, seconds: float) -> dict:
    j = d.as_dict()
    return {
        "outcome": j["outcome"],
        "verdict": j["verdict"],
        "adequate": j["adequate"],
        "baseline": j["baseline"],
        "path": j["path"],
        "ranking": [
            {
                k: r.get(k)
                for k in (
                    "effect",
                    "score",
                    "refit_misfit",
                    "refit_chi2",
                    "refit_params",
                    "significant",
                )
            }
            for r in j["ranking"]
        ],
        "rounds": len(j["rounds"]),
        "final": {"terms": j["final"]["terms"], "params": j["final"]["params"]},
        "discretisation": j["discretisation"],
        "unexplained": j["unexplained"],
        "n": j["final"]["misfit"]["n"],
        "baseline_fit_seconds": j["seconds"]["baseline_fit"],
        "seconds": seconds,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/diagnose_table", help="output directory")
    ap.add_argument(
        "--h",
        type=float,
        default=None,
        help="element size of the fitted model (mm; default: the plug-in's, W/10)",
    )
    ap.add_argument("--every", type=int, default=4, help="every n-th lattice node is a point")
    ap.add_argument("--cases", default=",".join(CASES), help="comma list of " + ", ".join(CASES))
    ap.add_argument("--confirm", type=int, default=2, help="candidates confirmed per round")
    ap.add_argument("--max-effects", type=int, default=2)
    ap.add_argument("--seed", type=int, default=11, help="noise seed")
    ap.add_argument("--truth", action="store_true", help="also the checks at the true moduli")
    ap.add_argument(
        "--no-discretisation",
        action="store_true",
        help="skip the h against h/2 check (one run at h/2 per case)",
    )
    ap.add_argument(
        "--quick",
        action="store_true",
        help="a cheap run: half-size specimen, h = 8, one case per regime",
    )
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    say = lambda s: rank0(logger, comm, s)  # noqa: E731
    cases = a.cases.split(",")
    unknown = sorted(set(cases) - set(CASES))
    if unknown:
        raise SystemExit(f"diagnose_table: unknown cases {unknown}; known: {', '.join(CASES)}")
    length, width, h = LENGTH, WIDTH, a.h
    if a.quick:
        length, width, h, cases = LENGTH / 2, WIDTH / 2, 8.0, ["complete", "weak_geodesic"]
    out = Path(a.out)
    clean: dict[float, object] = {}
    results: dict = {
        "setup": {
            "length_mm": length,
            "width_mm": width,
            "spacing_mm": SPACING,
            "lattice_spacing_mm": {
                f"±{CASES[c][0]:g}": spanning_spacing(length, SPACING, (CASES[c][0], -CASES[c][0]))
                for c in cases
            },
            "k_l": K_L,
            "k_s": K_S,
            "A_g": A_G,
            "steps": STEPS,
            "strain": STRAIN,
            "noise_mm": NOISE_MM,
            "noise_N": NOISE_N,
            "every": a.every,
            "h_mm": h,
            "confirm": a.confirm,
            "max_effects": a.max_effects,
            "ranks": comm.size,
        },
        "cases": {},
    }
    for case in cases:
        angle, baseline, m_kn = CASES[case]
        t0 = time.perf_counter()
        if angle not in clean:
            clean[angle] = lattice(angle, a.every, length, width)
            say(
                f"[{case}] lattice data at ±{angle:g}°: {len(clean[angle].X)} field rows, "
                f"{time.perf_counter() - t0:.0f} s"
            )
        exp = noisy(clean[angle], a.seed)
        if m_kn:
            exp = in_m_kn(exp, out, comm)
        t1 = time.perf_counter()
        d = diagnose(
            exp,
            baseline,
            h=h,
            confirm=a.confirm,
            max_effects=a.max_effects,
            check_discretisation=not a.no_discretisation,
            comm=comm,
        )
        row = summary(d, time.perf_counter() - t1)
        if a.truth:
            row["truth"] = truth_check(exp, case, h, comm)
        results["cases"][case] = row
        say(
            f"[{case}] {row['outcome']}; adequate {row['adequate']}; path "
            + " -> ".join(f"{p['misfit']:.3f}" for p in row["path"])
            + f"; discretisation misfit {row['discretisation']['misfit']}; "
            f"{row['seconds']:.0f} s"
        )
        say(f"    final moduli {row['final']['params']}")
        for r in row["ranking"]:
            say(
                f"    {r['effect']:18s} score {r['score']:10.4g}  refit misfit "
                f"{r['refit_misfit'] if r['refit_misfit'] is None else round(r['refit_misfit'], 4)}"
                f"  significant {r['significant']}"
            )
        write_json(comm, out / "diagnose_table.json", results)


if __name__ == "__main__":
    main()
