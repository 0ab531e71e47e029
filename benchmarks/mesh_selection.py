"""Verdicts with and without the diagnosis's mesh selection (docs/diagnosis.md, "Mesh
selection") on held-aside synthetic cases, none of them the test's (tests/test_mesh_choice.py).

Each case: continuum bias-extension data of the complete model (fibre_stretch + shear + the
hidden effect) made on a mesh finer than any the diagnosis builds, with Gaussian noise; the
diagnosis of fibre_stretch + shear at the test's default h (W/10), once on that mesh alone (the
diagnosis before mesh selection: its outcome ends "refine h" when the h/2 check is too coarse)
and once with :func:`~fabricsurf.inverse.diagnosis.mesh_choice.diagnose_on_mesh` (default
budget unless ``--max-dofs`` / ``--time-budget``). Prints per case and mode: wall time,
unknowns of the last fit mesh, verdict, adequate, the h/2 check against the noise band, and
the outcome; writes OUT/mesh_selection.json.

* ``position_40x20``: 40 × 20 mm, position clamps, 3 steps to 9 %, 10 × 5 points, geodesic
  bending hidden (A_g = 15 N·mm), noise 0.004 mm / 0.008 N;
* ``gradient_60x30``: 60 × 30 mm, gradient clamps, 3 steps to 9 %, shear_gradient hidden
  (A_Γ = 20 N·mm), noise 0.002 mm / 0.004 N;
* ``gradient_40x20_geodesic``: as ``position_40x20`` with gradient clamps (their force
  converges slowly in h) and noise 0.001 mm / 0.002 N.

    .venv/bin/python benchmarks/mesh_selection.py --out out/mesh_selection --cases position_40x20
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mpi4py import MPI

from fabricsurf.discretise.output import write_json
from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.diagnosis.mesh_choice import Budget, diagnose_on_mesh, level_record
from fabricsurf.inverse.synthetic import generate as sy

COMM = MPI.COMM_WORLD
BASE = {"fibre_stretch": {"k_l": 30.0, "k_m": 30.0}, "shear": {"k_s": 0.5}}
CASES = {
    "position_40x20": dict(
        L=40.0, W=20.0, clamp="position", noise=0.004, hidden={"geodesic_bending": {"A_g": 15.0}}
    ),
    "gradient_60x30": dict(
        L=60.0, W=30.0, clamp="gradient", noise=0.002, hidden={"shear_gradient": {"A_Gamma": 20.0}}
    ),
    "gradient_40x20_geodesic": dict(
        L=40.0, W=20.0, clamp="gradient", noise=0.001, hidden={"geodesic_bending": {"A_g": 15.0}}
    ),
}


def data(c: dict):
    L, W = c["L"], c["W"]
    exp = sy.template(
        L,
        W,
        [0.03 * L, 0.06 * L, 0.09 * L],
        sy.grid_points(L, W, 10, 5),
        clamp=c["clamp"],
        name="held_aside",
    )
    true = BASE | c["hidden"]
    sy.continuum_data(exp, full_model(list(true), true), h=W / 10 / 2.9)
    return sy.add_noise(exp, c["noise"], 2 * c["noise"], 23)


def summary(d, seconds: float) -> dict:
    q = level_record(d, seconds)
    return {
        k: q[k]
        for k in (
            "h",
            "dofs",
            "seconds",
            "chi2_h",
            "noise_band",
            "too_coarse",
            "verdict",
            "adequate",
            "misfit",
            "moduli",
        )
    } | {"outcome": d.outcome(), "mesh_selection": d.mesh_selection}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--max-dofs", type=int, default=Budget().max_dofs)
    ap.add_argument("--time-budget", type=float, default=Budget().seconds)
    args = ap.parse_args()
    budget = Budget(max_dofs=args.max_dofs, seconds=args.time_budget)
    results = {}
    for name in args.cases.split(","):
        exp = data(CASES[name])
        kw = dict(confirm=1, max_effects=1, comm=COMM)
        t = time.perf_counter()
        before = diagnose(exp, list(BASE), **kw)
        t_before = time.perf_counter() - t
        t = time.perf_counter()
        after = diagnose_on_mesh(exp, list(BASE), budget=budget, **kw)
        t_after = time.perf_counter() - t
        results[name] = {"without": summary(before, t_before), "with": summary(after, t_after)}
        for mode, r in results[name].items():
            if COMM.rank == 0:
                print(
                    f"{name} {mode:7s} mesh selection: {r['seconds']:7.1f} s, h {r['h']}, "
                    f"{r['dofs']:,} unknowns, verdict {r['verdict']}, adequate "
                    f"{r['adequate']}, chi2_h {r['chi2_h']:.4g} vs band {r['noise_band']:.4g}"
                    f": {r['outcome']}",
                    flush=True,
                )
        write_json(COMM, args.out / "mesh_selection.json", results)


if __name__ == "__main__":
    main()
