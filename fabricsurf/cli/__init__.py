"""Command line: ``fabricsurf compare|fit|diagnose DATA --terms T1,T2 --out OUT`` and
``fabricsurf bias --out OUT`` (the continuum bias-extension test, :mod:`fabricsurf.cli.bias`).

Each subcommand is a small function ``cmd_<name>(args)``; :func:`build_parser` holds the
parsers (add further subcommands with ``sub.add_parser``). Bad input ends with one message and
exit status 2. Everything runs under ``mpirun -n P``; files are written on rank 0.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from mpi4py import MPI

from fabricsurf.cli import bias as bias_cli
from fabricsurf.discretise.output import rank0_print, write_json
from fabricsurf.discretise.solver import LoadStepError
from fabricsurf.inverse.data import DataError, Experiment, load_experiment

COMM = MPI.COMM_WORLD


def _common(p: argparse.ArgumentParser, terms_required: bool = True) -> None:
    p.add_argument("data", help="measurement directory (DESIGN §6)")
    p.add_argument("--terms", required=terms_required,
                   help="comma-separated effects, e.g. fibre_stretch,shear")
    p.add_argument("--params", help="JSON moduli {term: {param: value}} or a saved fit.json")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--h", type=float, default=None, help="element size in mm "
                   "(default: width/10)")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="fabricsurf", description="Fabric surface models vs "
                                 "measurements: compare, fit, diagnose the missing effect.")
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("compare", help="misfit of a model against the data, with figures")
    _common(p, terms_required=False)
    p.add_argument("--steps", help="comma-separated steps for the error map (default: "
                   "middle and last)")
    p.set_defaults(func=cmd_compare)
    p = sub.add_parser("fit", help="least-squares fit of the moduli (log-parametrised)")
    _common(p)
    p.set_defaults(func=cmd_fit)
    p = sub.add_parser("diagnose", help="rank the missing effects (DESIGN §7)")
    _common(p)
    p.add_argument("--confirm", type=int, default=2, help="candidates confirmed by refitting")
    p.add_argument("--add-best", action="store_true",
                   help="save the baseline+verdict model and its comparison")
    p.set_defaults(func=cmd_diagnose)
    p = sub.add_parser("bias", help="continuum bias-extension test: XDMF, force curve, log")
    bias_cli.add_arguments(p)
    p.set_defaults(func=cmd_bias)
    return ap


def cmd_bias(args) -> int:
    bias_cli.run(args)
    return 0


def _model(args, params: dict):
    from fabricsurf.model.terms import parse_terms

    terms = args.terms or ",".join(params)
    if not terms:
        raise DataError("--terms: no terms given (and no --params file naming them)")
    return parse_terms(terms, params)


def write_comparison(out: Path, exp: Experiment, preds: list, misfits: list,
                     steps: list[int] | None = None, stem: str = "") -> None:
    """misfit JSON, per-point CSV and the three figures (rank 0 writes)."""
    from fabricsurf.inverse import figures

    label, pred = preds[-1]
    m = misfits[-1][1]
    write_json(COMM, out / f"{stem}misfit.json",
               {k: v for k, v in m.items() if k != "row_error"} | {"model": label})
    if COMM.rank != 0:
        return
    with open(out / f"{stem}per_point.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["step", "X", "Y", "ux_meas", "uy_meas", "ux_model", "uy_model", "error"])
        for s, x, um, up, e in zip(exp.field_step, exp.X, exp.u, pred.u, m["row_error"]):
            w.writerow([int(s), *x, *um[:2], *up, e])
    steps = steps or figures.default_steps(exp)
    figures.error_map(exp, preds, steps, out / f"{stem}error_map.png")
    figures.force_curves(exp, preds, out / f"{stem}force.png")
    figures.error_vs_step(exp, misfits, out / f"{stem}error_vs_step.png", exp.noise_std)


def _summary(label: str, m: dict) -> str:
    return (f"{label}: field RMS {m['field_rms']:.4g} mm, force RMS {m['force_rms']:.4g} N, "
            f"combined misfit {m['combined']:.4g} (noise units), chi2 {m['chi2']:.5g} "
            f"over {m['n']} data; points outside the mesh: {m['points_outside']}")


def cmd_compare(args) -> int:
    from fabricsurf.inverse.compare import ForwardModel, misfit
    from fabricsurf.inverse.fit import load_params

    exp, params = load_experiment(args.data), load_params(args.params)
    model = _model(args, params)
    pred = ForwardModel(exp, model, h=args.h, comm=COMM).run()
    m = misfit(exp, pred)
    out = Path(args.out)
    steps = [int(s) for s in args.steps.split(",")] if args.steps else None
    label = "+".join(t.name for t in model)
    write_comparison(out, exp, [(label, pred)], [(label, m)], steps)
    rank0_print(COMM, _summary(label, m))
    return 0


def cmd_fit(args) -> int:
    from fabricsurf.inverse.compare import ForwardModel
    from fabricsurf.inverse.fit import fit, load_params

    exp, params = load_experiment(args.data), load_params(args.params)
    model = _model(args, params)
    fm = ForwardModel(exp, model, h=args.h, comm=COMM)
    res = fit(fm, verbose=True)
    out = Path(args.out)
    write_json(COMM, out / "fit.json", res.as_dict())
    label = "fit: " + "+".join(t.name for t in model)
    write_comparison(out, exp, [(label, res.prediction)], [(label, res.misfit)])
    for n, v, s in zip(res.names, res.values, res.std):
        rank0_print(COMM, f"  {n} = {v:.5g} ± {s:.2g}")
    rank0_print(COMM, _summary(label, res.misfit))
    return 0


def cmd_diagnose(args) -> int:
    from fabricsurf.inverse.diagnose import diagnose
    from fabricsurf.inverse.fit import load_params

    exp, params = load_experiment(args.data), load_params(args.params)
    baseline = [t.name for t in _model(args, params)]
    d = diagnose(exp, baseline, h=args.h, params=params, confirm=args.confirm, comm=COMM)
    out = Path(args.out)
    write_json(COMM, out / "diagnosis.json", d.as_dict())
    b = d.base_fit
    preds, mfs = [("baseline", b.prediction)], [("baseline", b.misfit)]
    write_comparison(out, exp, preds, mfs, stem="baseline_")
    rank0_print(COMM, _summary("baseline " + "+".join(baseline), b.misfit))
    for r in d.ranking:
        rank0_print(COMM, f"  {r['effect']:18s} score {r['score']:10.4g}  refit misfit "
                    f"{r['refit_misfit']}  significant {r['significant']}")
    rank0_print(COMM, f"verdict: {d.verdict}")
    if d.verdict is not None:
        after = d.refits[d.verdict]
        label = "baseline+" + d.verdict
        write_comparison(out, exp, preds + [(label, after.prediction)],
                         mfs + [(label, after.misfit)], stem="before_after_")
        if args.add_best:
            write_json(COMM, out / "model_best.json", after.as_dict())
            rank0_print(COMM, f"added {d.verdict}: combined misfit {b.misfit['combined']:.4g}"
                        f" -> {after.misfit['combined']:.4g}; model saved to "
                        f"{out / 'model_best.json'}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fabricsurf`` command."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (DataError, ValueError, OSError, LoadStepError) as e:
        rank0_print(COMM, f"fabricsurf {args.command}: error: {e}")
        return 2


if __name__ == "__main__":
    sys.exit(main())
