"""``fabricsurf bias``: the continuum bias-extension test (XDMF, force curve, step log).

    mpirun -n 2 python -m fabricsurf bias --out out/bias [--ubar 46.75] [--steps 10] [--h 6]
        [--terms fibre_stretch,shear,geodesic_bending] [--params params.json]

``--params`` is a JSON file {"term": {"parameter": value}} (units: N/mm, N·mm). Writes
OUT/bias.xdmf (u, λ, μ, γ, J per step), OUT/bias_steps.csv|json, OUT/bias_curve.json,
OUT/force.png and OUT/summary.json.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from mpi4py import MPI

from fabricsurf.discretise.output import rank0_print, write_json
from fabricsurf.experiments.bias_extension import BiasExtension, default_model, plot_curves
from fabricsurf.model.terms import parse_terms


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=Path("out/bias"), help="output directory")
    p.add_argument("--length", type=float, default=187.0, help="specimen length along x (mm)")
    p.add_argument("--width", type=float, default=119.0, help="specimen width (mm)")
    p.add_argument("--h", type=float, default=6.0, help="mesh size (mm)")
    p.add_argument("--ubar", type=float, default=None,
                   help="final grip displacement (mm); default 25%% of the length")
    p.add_argument("--steps", type=int, default=10, help="number of requested load steps")
    p.add_argument("--terms", default=None,
                   help="comma-separated effects (default fibre_stretch,shear,geodesic_bending)")
    p.add_argument("--params", type=Path, default=None,
                   help='JSON file {"term": {"parameter": value}}')
    p.add_argument("--clamp", choices=("gradient", "position"), default="gradient")


def load_params(path: Path | None) -> dict:
    if path is None:
        return {}
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise SystemExit(f"--params {path}: cannot read JSON ({e})")
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        raise SystemExit(f'--params {path}: expected {{"term": {{"parameter": value}}}}')
    return data


def run(args: argparse.Namespace) -> dict:
    comm = MPI.COMM_WORLD
    params = load_params(args.params)
    try:
        model = parse_terms(args.terms, params) if args.terms else default_model()
    except ValueError as e:
        raise SystemExit(f"--terms/--params: {e}")
    if args.steps < 1:
        raise SystemExit(f"--steps {args.steps}: must be at least 1")
    ubar = 0.25 * args.length if args.ubar is None else args.ubar
    rank0_print(comm, f"bias extension {args.length} x {args.width} mm, h = {args.h} mm, "
                      f"terms {[t.name for t in model]}, ubar up to {ubar} mm "
                      f"on {comm.size} rank(s)")
    test = BiasExtension(model, args.length, args.width, args.h, args.clamp)
    res = test.run(ubar, args.steps, out=args.out)
    summary = {"terms": {t.name: t.values() for t in model}, "ubar": res.ubar,
               "force": res.force, "angle_A_deg": res.angle_A_deg,
               "angle_B_deg": res.angle_B_deg, "newton_iterations": res.newton,
               "seconds": res.seconds, "ranks": comm.size}
    write_json(comm, args.out / "summary.json", summary)
    if comm.rank == 0:
        plot_curves(res, args.out / "force.png")
    rank0_print(comm, f"done in {res.seconds:.1f} s; XDMF, force curve and summary in {args.out}")
    return summary


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="fabricsurf bias", description=__doc__.splitlines()[0])
    add_arguments(parser)
    run(parser.parse_args(argv))


if __name__ == "__main__":
    main()
