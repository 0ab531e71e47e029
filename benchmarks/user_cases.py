"""A new user's slow cases, again: the default diagnosis on the stiff-fibre lattice data.

The speed work of docs/speed.md started from a table of cases a new user had run with
``fabricsurf diagnose DATA --terms fibre_stretch,shear`` and the defaults (the mesh selection of
docs/diagnosis.md) that took up to twenty minutes. Their data are remade here with the
package's generator, the stiff-fibre lattice of benchmarks/diagnose_table.py (187 × 119 mm,
k_l = 1000 N/mm, k_s = 0.4 N/mm, geodesic bending A_g = 40 N·mm hidden, spacing 2.5 mm, 12
steps), and the command is run as the user ran it:

* ``angles40_m_kn``: fibres at ±40°, 15 % stretch, noise 0.05 mm and 0.05 N, the data written
  in m and kN and read back by the loader;
* ``small_displacements``: ±45°, 2 % stretch, noise 0.005 mm and 0.005 N (low noise, so the
  h/2 check asks for a fine mesh);
* ``two_sizes_force_only``: two force-only curves of different sizes together, with
  ``--max-effects 2``: the shipped Cao et al. 2008 curve (115 × 230 mm) and a second size made
  here, 100 × 200 mm, ±45°, 20 steps to the Cao curve's last displacement scaled by the length,
  the continuum response of the fabric as the woven-fabric demo fits it
  (``fabricsurf.datasets.woven_fit()``) on a mesh of h = 5 mm, force noise 0.05 N.

Per case it prints the wall time, the mesh levels (h, unknowns, seconds, verdict), the
outcome and whether the mesh was fine enough; OUT/user_cases.json keeps them.

    mpirun -n 2 .venv/bin/python benchmarks/user_cases.py --out out/user_cases
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf import datasets
from fabricsurf.cli import main as cli
from fabricsurf.discretise.output import write_json
from fabricsurf.geometry.specimen import BIAS_LENGTH as LENGTH
from fabricsurf.geometry.specimen import BIAS_WIDTH as WIDTH
from fabricsurf.inverse.contract.data import load_experiment, write_experiment
from fabricsurf.inverse.contract.experiment import template
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.terms import parse_terms

SPACING, STEPS = 2.5, 12
K_L, K_S, A_G = 1000.0, 0.4, 40.0
CASES = {  # name: (fibre angle, stretch, noise mm, noise N, written in m and kN)
    "angles40_m_kn": (40.0, 0.15, 0.05, 0.05, True),
    "small_displacements": (45.0, 0.02, 0.005, 0.005, False),
}
TWO_SIZES = "two_sizes_force_only"
SECOND = (200.0, 100.0, 20, 5.0, 0.05)
"""The second size's length, width (mm), steps, mesh h (mm) and force noise (N)."""


def make_data(name: str, every: int, out: Path, comm: MPI.Comm) -> Path:
    """The case's measurement directory (made once, on rank 0)."""
    angle, strain, mm, n, m_kn = CASES[name]
    d = out / f"{name}_data"
    if comm.rank == 0 and not (d / "experiment.toml").exists():
        path = list(np.linspace(strain * LENGTH / STEPS, strain * LENGTH, STEPS))
        exp = sy.template(LENGTH, WIDTH, path, np.zeros((0, 2)), angles=(angle, -angle), name=name)
        sy.lattice_data(exp, SPACING, k_l=K_L, k_s=K_S, A_g=A_G, every=every)
        sy.add_noise(exp, mm, n, seed=11)
        write_experiment(d, exp, overwrite=True)
        if m_kn:
            sy.rewrite_in_m_kn(d)
    comm.barrier()
    return d


def two_sizes_data(out: Path, comm: MPI.Comm) -> list[Path]:
    """The shipped Cao curve and the second size (module docstring; made once, on rank 0)."""
    d = out / "second_size_data"
    if comm.rank == 0 and not (d / "experiment.toml").exists():
        length, width, steps, h, noise = SECOND
        fit = json.loads(datasets.woven_fit().read_text())
        cao = load_experiment(datasets.cao2008_plain_weave())
        top = float(np.max(cao.path)) * length / cao.setup.length
        path = np.linspace(top / steps, top, steps)
        exp = template(length, width, path, np.zeros((0, 2)), name="second_size")
        model = parse_terms(",".join(fit["terms"]), fit["params"])
        sy.continuum_data(exp, model, h, MPI.COMM_SELF)
        sy.add_noise(exp, 0.0, noise, seed=12)
        write_experiment(d, exp, overwrite=True)
    comm.barrier()
    return [datasets.cao2008_plain_weave(), d]


def run(name: str, every: int, out: Path, comm: MPI.Comm) -> dict:
    """The default command on the case's data: its record."""
    if name == TWO_SIZES:
        data, extra = [str(p) for p in two_sizes_data(out, comm)], ["--max-effects", "2"]
    else:
        data, extra = [str(make_data(name, every, out, comm))], []
    t0 = time.perf_counter()
    argv = ["diagnose", *data, "--terms", "fibre_stretch,shear", *extra]
    rc = cli([*argv, "--out", str(out / name)])
    seconds = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    d = json.loads((out / name / "diagnosis.json").read_text()) if comm.rank == 0 else None
    d = comm.bcast(d)
    levels = d["discretisation"]["mesh_selection"]["levels"]
    return {
        "exit_code": rc,
        "seconds": seconds,
        "verdict": d["verdict"],
        "outcome": d["outcome"],
        "too_coarse": d["discretisation"]["too_coarse"],
        "levels": [
            {k: q.get(k) for k in ("h", "dofs", "seconds", "verdict", "too_coarse")} for q in levels
        ],
        "rows": d["final"]["misfit"]["n"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/user_cases", help="output directory")
    names = [*CASES, TWO_SIZES]
    ap.add_argument("--cases", default=",".join(names), help="comma list of " + ", ".join(names))
    ap.add_argument("--every", type=int, default=2, help="every n-th lattice node is a point")
    args = ap.parse_args()
    comm, out = MPI.COMM_WORLD, Path(args.out)
    records = {}
    for name in args.cases.split(","):
        records[name] = run(name, args.every, out, comm)
        write_json(comm, out / "user_cases.json", records)
        if comm.rank == 0:
            r = records[name]
            print(f"{name}: {r['seconds']:.0f} s, {r['rows']} residuals; {r['outcome']}")
            for q in r["levels"]:
                print(f"  level h = {q['h']}: {q['dofs']} unknowns, {q['seconds']:.0f} s, {q}")
            print(f"  too coarse at the end: {r['too_coarse']}", flush=True)


if __name__ == "__main__":
    main()
