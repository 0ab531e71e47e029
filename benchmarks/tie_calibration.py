"""Calibration of the tie rule of the diagnosis (docs/diagnosis.md, "Ties").

Continuum bias tests of our own generator (70 × 35 mm, ±45°, fibre_stretch k_l = 30 N/mm,
shear k_s = 0.5 N/mm, data on a 2.2 mm mesh, diagnosed at h = 3.5 mm; 10 × 5 field points and
the force at 3 steps): null data (nothing hidden) and one hidden effect, geodesic_bending
(A_g = 15 N·mm) or shear_gradient (A_Γ = 20 N·mm), at a small and a large displacement, two
noise levels and several noise seeds, diagnosed from fibre_stretch + shear with every refit
confirmed (confirm 3, one effect). Each outcome is one of: the right single effect, a tie that
holds the truth, a wrong single effect, a tie without the truth, nothing. Printed: one line per
data set and the table of rates; "wrong top refit" counts the outcomes the former rule (the
best refit named alone) would have got wrong, and how many of those the tie rule turns into a
tie holding the truth.

    .venv/bin/python benchmarks/tie_calibration.py [--seeds 2] [--first-seed 0] [--json OUT]
    .venv/bin/python benchmarks/tie_calibration.py --table OUT1.json OUT2.json  # merge
"""

from __future__ import annotations

import argparse
import itertools
import logging
import time

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0
from research.rows import read_rows, save_rows

logger = logging.getLogger(__name__)

BASE = {"fibre_stretch": {"k_l": 30.0, "k_m": 30.0}, "shear": {"k_s": 0.5}}
HIDDEN = {
    "none": {},
    "geodesic_bending": {"geodesic_bending": {"A_g": 15.0}},
    "shear_gradient": {"shear_gradient": {"A_Gamma": 20.0}},
}
DISPLACEMENTS = {"small": 1.2, "large": 3.6}
NOISES = (0.01, 0.02)


def data(hidden: str, d_max: float, noise: float, seed: int):
    exp = sy.template(
        70.0, 35.0, list(np.linspace(d_max / 3, d_max, 3)), sy.grid_points(70.0, 35.0, 10, 5)
    )
    params = {**BASE, **HIDDEN[hidden]}
    sy.continuum_data(exp, full_model(list(params), params), h=2.2)
    return sy.add_noise(exp, noise, 0.02, seed)


def outcome(d, hidden: str) -> str:
    tie = d.tied()
    if d.verdict is None:
        return "nothing"
    if hidden == "none":
        return "false tie" if tie else "false single"
    if tie:
        return "tie with truth" if hidden in tie else "tie without truth"
    return "right single" if d.verdict == hidden else "wrong single"


def run(seeds: int, first: int = 0) -> list[dict]:
    rows = []
    for hidden, (regime, d_max), noise, seed in itertools.product(
        HIDDEN, DISPLACEMENTS.items(), NOISES, range(first, first + seeds)
    ):
        t0 = time.perf_counter()
        exp = data(hidden, d_max, noise, 100 + seed)
        with detail():
            d = diagnose(
                exp,
                ["fibre_stretch", "shear"],
                h=3.5,
                confirm=3,
                max_effects=1,
                check_discretisation=False,
            )
        comps = d.tie.comparisons if d.tie else []
        row = {
            "hidden": hidden,
            "regime": regime,
            "noise": noise,
            "seed": seed,
            "verdict": d.verdict,
            "tie": d.tied(),
            "outcome": outcome(d, hidden),
            "comparisons": [
                {k: c[k] for k in ("effects", "delta_chi2", "resolution", "z", "p", "cosine")}
                for c in comps
            ],
            "seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        rank0(
            logger,
            MPI.COMM_WORLD,
            f"{hidden:17s} {regime:5s} noise {noise:<5g} seed {seed}: "
            f"{row['outcome']:17s} verdict {d.verdict} tie {d.tied()} "
            + "; ".join(
                f"{'/'.join(c['effects'])} z {c['z']:.2f} cos {c['cosine']:.3f}"
                for c in row["comparisons"]
            )
            + f" ({row['seconds']:.0f} s)",
        )
    return rows


def table(rows: list[dict]) -> None:
    say = lambda m: rank0(logger, MPI.COMM_WORLD, m)  # noqa: E731
    kinds = [
        "right single",
        "tie with truth",
        "wrong single",
        "tie without truth",
        "nothing",
        "false single",
        "false tie",
    ]
    say(
        "\nhidden            regime  n  "
        + "  ".join(f"{k:>6.6s}" for k in kinds)
        + "  wrong-top  tie-rescued"
    )
    for hidden, regime in itertools.product(HIDDEN, DISPLACEMENTS):
        sel = [r for r in rows if r["hidden"] == hidden and r["regime"] == regime]
        wrong_top = [r for r in sel if hidden != "none" and r["verdict"] not in (None, hidden)]
        rescued = [r for r in wrong_top if r["tie"] and hidden in r["tie"]]
        say(
            f"{hidden:17s} {regime:6s} {len(sel):2d}  "
            + "  ".join(f"{sum(r['outcome'] == k for r in sel):6d}" for k in kinds)
            + f"  {len(wrong_top):9d}  {len(rescued):11d}"
        )
    eff = [r for r in rows if r["hidden"] != "none" and r["verdict"] is not None]
    single_true = [
        r for r in eff if r["verdict"] == r["hidden"] or (r["tie"] and r["hidden"] in r["tie"])
    ]
    say(
        f"\nhidden effect found (alone or in a tie): {len(single_true)}/{len(eff)} with a "
        f"verdict; reported as a tie: {sum(bool(r['tie']) for r in single_true)}; wrong single "
        f"answers: {sum(r['outcome'] == 'wrong single' for r in eff)} (the best refit alone: "
        f"{sum(r['verdict'] != r['hidden'] for r in eff)})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--json", default=None, help="write the rows to this file")
    ap.add_argument(
        "--table",
        nargs="*",
        default=None,
        help="only print the table of these --json files (no runs)",
    )
    args = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    if args.table:
        table(read_rows(args.table))
        return
    rows = run(args.seeds, args.first_seed)
    table(rows)
    save_rows(args.json, rows)


if __name__ == "__main__":
    main()
