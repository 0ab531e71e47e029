"""Memory over many diagnoses in one process (benchmarks/README.md, "Resources").

Makes two small synthetic data sets once, then diagnoses each ``--count`` times in the same
process through the public API and prints, after every diagnosis, the resident memory (VmRSS,
the largest over the ranks). The growth per diagnosis after the first, (last − first)/(count − 1),
is compared with the target: a study of many diagnoses must not run out of memory, so each
diagnosis may leave less than :data:`TARGET_MB` behind.

* bias: continuum bias-extension data with geodesic bending hidden from fibre_stretch + shear,
  diagnosed with the discretisation check at h/2;
* stiff: Hencky-lattice data in the regime of real fabrics (nearly inextensible fibres), the
  complete model diagnosed.

    mpirun -n 2 .venv/bin/python benchmarks/memory.py [--count 50] [--cases bias,stiff]
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.diagnosis.diagnose import diagnose, full_model
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.log import configure, detail, rank0

logger = logging.getLogger(__name__)

TARGET_MB = 5.0
BASE = {"fibre_stretch": {"k_l": 30.0, "k_m": 30.0}, "shear": {"k_s": 0.5}}
STIFF_K_L, STIFF_K_S, STIFF_L_B = 1000.0, 0.4, 5.0


def resident_mb() -> float:
    """This process's resident memory (MB), from /proc/self/status."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS in /proc/self/status")


def bias_case(comm: MPI.Comm):
    """(data, diagnose keywords) of the small bias test."""
    exp = sy.template(60.0, 30.0, [1.0, 2.0], sy.grid_points(60.0, 30.0, 6, 3))
    truth = {**BASE, "geodesic_bending": {"A_g": 15.0}}
    sy.continuum_data(exp, full_model(list(truth), truth), h=3.0, comm=comm)
    sy.add_noise(exp, 0.01, 0.02, 3)
    return exp, {"baseline": ["fibre_stretch", "shear"], "h": 6.0}


def stiff_case(comm: MPI.Comm):
    """(data, diagnose keywords) of the stiff-fibre regime on lattice data."""
    length, width = 48.0, 24.0
    path = list(np.linspace(0.04 * length, 0.12 * length, 3))
    exp = sy.template(length, width, path, np.zeros((0, 2)), name="stiff")
    sy.lattice_data(exp, 1.6, k_l=STIFF_K_L, k_s=STIFF_K_S, A_g=STIFF_K_S * STIFF_L_B**2, every=2)
    sy.add_noise(exp, 0.02, 0.02, 5)
    return exp, {
        "baseline": ["fibre_stretch", "shear", "geodesic_bending"],
        "h": 4.0,
        "check_discretisation": False,
    }


CASES = {"bias": bias_case, "stiff": stiff_case}


def run_case(name: str, count: int, comm: MPI.Comm) -> float:
    """Diagnose ``count`` times; returns the growth per diagnosis after the first (MB)."""
    say = lambda s: rank0(logger, comm, s)  # noqa: E731
    exp, kw = CASES[name](comm)
    say(f"{name}: {count} diagnoses on {comm.size} rank(s); resident memory, max over ranks")
    rss = []
    for k in range(count):
        t0 = MPI.Wtime()
        with detail():
            d = diagnose(exp, confirm=1, max_effects=1, comm=comm, **kw)
        outcome = d.outcome()
        del d
        rss.append(comm.allreduce(resident_mb(), op=MPI.MAX))
        say(f"  {name} {k + 1:3d}: {rss[-1]:8.1f} MB  ({MPI.Wtime() - t0:5.1f} s, {outcome})")
    growth = (rss[-1] - rss[0]) / (count - 1) if count > 1 else float("nan")
    say(
        f"{name}: growth per diagnosis after the first {growth:.3f} MB "
        f"(target < {TARGET_MB:g} MB: {growth / TARGET_MB:.3f} of it, "
        f"{'met' if growth < TARGET_MB else 'NOT met'})"
    )
    return growth


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=50, help="diagnoses per case")
    ap.add_argument("--cases", default="bias,stiff", help=f"comma list of {list(CASES)}")
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    names = [c for c in a.cases.split(",") if c]
    unknown = [c for c in names if c not in CASES]
    if unknown or a.count < 2:
        raise SystemExit(f"--cases {unknown} unknown (use {list(CASES)}) or --count < 2")
    t0 = time.perf_counter()
    growth = {c: run_case(c, a.count, comm) for c in names}
    rank0(
        logger,
        comm,
        "summary: "
        + ", ".join(f"{c} {g:.3f} MB/diagnosis" for c, g in growth.items())
        + f"; target < {TARGET_MB:g} MB "
        + ("met" if all(g < TARGET_MB for g in growth.values()) else "NOT met")
        + f" ({time.perf_counter() - t0:.0f} s)",
    )


if __name__ == "__main__":
    main()
