"""Coverage of the prediction band from one specimen size to another (docs/uncertainty.md).

For each hidden size effect × fabric × size ratio of :mod:`fabricsurf.inverse.synthetic.sizes`
(lattice force curves, force only): fit the shear modulus on a 40 × 20 mm specimen, estimate
the size part there (:mod:`fabricsurf.inverse.fitting.size_form`), predict the specimen
``ratio`` times its size (larger, or smaller for a ratio below 1), and print the share of its
points inside the 95 % band (noisy, and of its noise-free curve) and the band's mean half-width
(% of its largest force), with the size part and without it (the band before), and the largest
error:

    mpirun -n 2 .venv/bin/python benchmarks/size_coverage.py [--quick] [--out OUT]

``--quick``: one fabric, one ratio, both effects. Rows are appended to OUT/size_coverage.json.
"""

from __future__ import annotations

import argparse
import itertools
import json
import logging
import time
from pathlib import Path

from mpi4py import MPI

from fabricsurf.inverse.synthetic import sizes
from fabricsurf.log import configure, rank0

logger = logging.getLogger(__name__)

FITTED = (40.0, 20.0)
RATIOS = (1.5, 2.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--h", type=float, default=2.5, help="mesh of the fitted specimen (mm)")
    ap.add_argument("--steps", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="out/size_coverage")
    ap.add_argument("--fabrics", nargs="*", default=list(sizes.FABRICS))
    ap.add_argument("--effects", nargs="*", default=list(sizes.HIDDEN))
    ap.add_argument("--ratios", nargs="*", type=float, default=list(RATIOS))
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    say = lambda s: rank0(logger, comm, s)  # noqa: E731
    fabrics, ratios = (a.fabrics[:1], a.ratios[:1]) if a.quick else (a.fabrics, a.ratios)
    out = Path(a.out)
    if comm.rank == 0:
        out.mkdir(parents=True, exist_ok=True)
    rows = []
    say(
        f"{'effect':13s} {'fabric':6s} {'ratio':>5s} {'cover':>6s} {'clean':>6s} "
        f"{'width %':>8s} {'before':>6s} {'width %':>8s} {'max err %':>9s} {'s':>5s}"
    )
    for effect, fabric, ratio in itertools.product(a.effects, fabrics, ratios):
        t0 = time.perf_counter()
        seed = a.seed + 17 * len(rows)
        calib, _ = sizes.curve(*FITTED, fabric, effect, a.steps, seed)
        other, clean = sizes.curve(
            ratio * FITTED[0], ratio * FITTED[1], fabric, effect, a.steps, seed + 1
        )
        row = sizes.pair_coverage(calib, other, fabric, a.h, comm, other_clean=clean.force)
        row |= {
            "effect": effect,
            "fabric": fabric,
            "ratio": ratio,
            "seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        say(
            f"{effect:13s} {fabric:6s} {ratio:5.1f} {row['coverage']:6.2f} "
            f"{row['coverage_clean']:6.2f} "
            f"{row['mean_half_width_pct']:8.2f} {row['coverage_without_size']:6.2f} "
            f"{row['mean_half_width_without_pct']:8.2f} {row['max_error_pct']:9.2f} "
            f"{row['seconds']:5.0f}"
        )
    n = sum(r["points"] for r in rows)
    inside, clean, before = (
        sum(r[k] * r["points"] for r in rows) / n
        for k in ("coverage", "coverage_clean", "coverage_without_size")
    )
    say(
        f"all: {inside:.3f} of {n} points inside, {clean:.3f} of the noise-free curve's "
        f"(without the size part {before:.3f})"
    )
    if comm.rank == 0:
        f = out / "size_coverage.json"
        old = json.loads(f.read_text()) if f.exists() else []
        f.write_text(json.dumps(old + rows, indent=1))


if __name__ == "__main__":
    main()
