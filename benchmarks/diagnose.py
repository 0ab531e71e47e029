"""Diagnosis cost benchmark: a diagnosis counted in forward solves (docs/verification.md).

Makes bias-extension data with a hidden effect (continuum, fibre_stretch + shear +
geodesic_bending on a finer mesh, noise), diagnoses it with the baseline fibre_stretch + shear
and prints, from one run:
  * the time of one forward solve along the load path (the unit),
  * ranking all candidates (one forward run + tangent solves with the converged factorisation)
    over one forward solve — required ≤ 3,
  * forward runs of the baseline fit and of each confirmed refit (LM trials included),
  * the whole diagnosis over one forward solve.

    mpirun -n 2 .venv/bin/python benchmarks/diagnose.py [--h 3] [--confirm 2]
"""

from __future__ import annotations

import argparse
import logging

from mpi4py import MPI

from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0

logger = logging.getLogger(__name__)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h", type=float, default=3.0, help="element size of the fitted model (mm)")
    ap.add_argument("--confirm", type=int, default=2)
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    say = lambda s: rank0(logger, comm, s)  # noqa: E731
    truth = {
        "fibre_stretch": {"k_l": 30.0, "k_m": 30.0},
        "shear": {"k_s": 0.5},
        "geodesic_bending": {"A_g": 20.0},
    }
    exp = sy.template(90.0, 45.0, [1.5, 3.0, 4.5, 6.0], sy.grid_points(90.0, 45.0, 14, 7))
    sy.continuum_data(exp, full_model(list(truth), truth), h=0.7 * a.h, comm=comm)
    sy.add_noise(exp, 0.01, 0.02, 7)
    t0 = MPI.Wtime()
    with detail():  # the cost is the point here, not the diagnosis' own progress
        d = diagnose(exp, ["fibre_stretch", "shear"], h=a.h, confirm=a.confirm, comm=comm)
    total = MPI.Wtime() - t0
    c = d.as_dict()["cost"]
    say(
        f"ranks {comm.size}, mesh h = {a.h} mm, {len(exp.steps)} load steps, "
        f"{len(exp.X)} field rows"
    )
    say(f"one forward solve:                     {c['forward_seconds']:.3f} s")
    say(f"ranking all {len(d.ranking)} candidates / forward solve: {c['rank_over_forward']:.2f}")
    say(
        f"baseline fit: {d.base_fit.forward_runs} forward runs (with tangents), "
        f"{d.base_fit.iterations} LM iterations"
    )
    for name, r in d.refits.items():
        say(f"refit {name:17s}: {r.forward_runs} forward runs, misfit {r.misfit['combined']:.3f}")
    say(
        f"whole diagnosis / forward solve:       {total / c['forward_seconds']:.1f} ({total:.1f} s)"
    )
    say(f"verdict {d.verdict}; baseline misfit {d.base_fit.misfit['combined']:.3f}")


if __name__ == "__main__":
    main()
