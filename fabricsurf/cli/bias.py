"""``fabricsurf bias``: the continuum bias-extension test (XDMF, force curve, step log).

    mpirun -n 2 python -m fabricsurf bias --out out/bias [--ubar 46.75] [--steps 10] [--h 6]
        [--terms fibre_stretch,shear,geodesic_bending] [--params params.json]

``--params`` is a JSON file {"term": {"parameter": value}} (units: N/mm, N·mm). Writes
OUT/bias.xdmf (u, λ, μ, γ, J per step), OUT/bias_steps.csv|json, OUT/bias_curve.json,
OUT/force.png and OUT/summary.json. When ``--params`` is a saved fit (fit.json or
model_best.json, with the moduli's covariance), the force curve also gets its 95 %
prediction band (docs/uncertainty.md): OUT/force_band.csv, OUT/force_band.png and
``force_band`` in summary.json; ``--no-band`` skips it (it costs two more forward runs).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.cli.effects import add_effects
from fabricsurf.cli.mesh_options import add_max_elements
from fabricsurf.cli.options import (
    check_bias_options,
    check_params_file,
    defaulted_moduli,
    out_path,
    saved_fit,
)
from fabricsurf.cli.outdir import OutputDir
from fabricsurf.discretise.energy import has_second_gradient
from fabricsurf.discretise.output import on_rank0, write_json
from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.errors import InputError
from fabricsurf.experiments.bias_extension import BiasExtension, default_model
from fabricsurf.inverse.fitting.params import load_params, parse_model, provenance
from fabricsurf.inverse.plots.bias_curves import bias_curves
from fabricsurf.log import rank0
from fabricsurf.model.terms import EFFECTS

log = logging.getLogger(__name__)

OUTPUTS = (
    "bias.xdmf",
    "bias.h5",
    "bias_steps.csv",
    "bias_steps.json",
    "bias_curve.json",
    "force.png",
    "force_band.csv",
    "force_band.png",
    "summary.json",
    "failure.json",
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--out",
        type=out_path,
        default=Path("out/bias"),
        help="output directory (created if missing; must be writable)",
    )
    p.add_argument("--length", type=float, default=187.0, help="specimen length along x (mm)")
    p.add_argument("--width", type=float, default=119.0, help="specimen width (mm)")
    p.add_argument("--h", type=float, default=6.0, help="mesh size (mm), at most half the width")
    p.add_argument(
        "--ubar",
        type=float,
        default=None,
        help="final grip displacement (mm), in (0, length) (default: 25%% of the length)",
    )
    p.add_argument(
        "--steps", type=int, default=10, help="number of equal requested load steps, 1 to 1000"
    )
    p.add_argument(
        "--terms",
        default=None,
        help="comma-separated effects, each once, from: "
        + ", ".join(EFFECTS)
        + " (default: "
        + "; ".join(
            t.name + " " + ", ".join(f"{k} = {v:g} {t.units[k]}" for k, v in t.values().items())
            for t in default_model()
        )
        + ")",
    )
    p.add_argument(
        "--params",
        type=Path,
        default=None,
        help='JSON moduli {"term": {"parameter": value}}, first-gradient moduli in '
        "N/mm, second-gradient in N·mm (see `fabricsurf terms`), or a saved "
        "fit.json; without --terms its terms are the model (default: none, the default "
        "model of --terms)",
    )
    p.add_argument(
        "--clamp",
        choices=("gradient", "position"),
        default="gradient",
        help="gradient: u and its normal derivative held; position: u only",
    )
    p.add_argument(
        "--no-band",
        action="store_true",
        help="no prediction band even when --params is a saved fit",
    )
    add_max_elements(p)
    add_effects(p)


ANGLE_A_NOTE = (
    "note: gamma_A is read at A of Barchiesi et al. 2020 Fig. 4, where the fibre lines from the "
    "clamp's corners cross and the unsheared, half-sheared and centre zones meet; a model "
    "without an in-plane second-gradient term (geodesic_bending, stretch_gradient, "
    "shear_gradient) has sharp zone boundaries, so the value there depends on the mesh "
    "(gamma_B and the force do not): add geodesic bending to read it"
)
"""Said when γ_A has no mesh-independent value (docs/theory.md, "Shear angles at A and B")."""


def _model(args) -> tuple[list, dict]:
    """(model, --params moduli): --terms (with --params moduli); else the terms of the --params
    file (a saved fit is the whole model: no default term is added silently); else the default
    model."""
    check_params_file(args.params)
    params = load_params(args.params, args.terms.split(",") if args.terms else None)
    if not (args.terms or params):
        return default_model(), params
    model = parse_model(args.terms, params)
    out_of_plane = [t.name for t in model if not t.in_plane]
    if out_of_plane:
        spec = args.terms or f"(the terms of --params {args.params})"
        raise InputError(
            f"--terms {spec}: {', '.join(out_of_plane)} is an out-of-plane effect, "
            "and the bias test is planar (no out-of-plane placement); remove it"
        )
    return model, params


def _band(args, model: list, ubar: float, saved: dict, stage: Path, comm) -> dict:
    """The band of this run's force curve
    (:func:`~fabricsurf.inverse.fitting.band.predicted_band`), with its CSV and figure."""
    from fabricsurf.inverse.fitting.band import predicted_band, write_band
    from fabricsurf.inverse.plots.figures import force_band as band_figure

    band = predicted_band(
        saved,
        model,
        args.length,
        args.width,
        np.linspace(ubar / args.steps, ubar, args.steps),
        args.h,
        args.clamp,
        comm,
    )
    on_rank0(comm, write_band, stage / "force_band.csv", band)
    on_rank0(
        comm,
        band_figure,
        band,
        stage / "force_band.png",
        f"bias {args.length:g} x {args.width:g} mm at the moduli of {args.params.name}",
    )
    return band


FIELD_FILES = ("bias.xdmf", "bias.h5")


def interrupted_report(stage: Path, summary: dict, converged: int, steps: int, out) -> str:
    """After SIGINT or SIGTERM (from the signal handler: no MPI call): drop the fields (the
    HDF5 file is open, with a step maybe half written, and cannot be read back: its XDMF would
    point to it), write failure.json, and return the rest of the message."""
    for name in FIELD_FILES:
        (stage / name).unlink(missing_ok=True)
    write_json(
        MPI.COMM_SELF,
        stage / "failure.json",
        summary
        | {
            "error": f"interrupted at step {converged + 1}",
            "converged_steps": converged,
            "fields": "not kept (bias.xdmf and bias.h5 of an interrupted run cannot be read back)",
        },
    )
    return (
        f" at step {converged + 1} of {steps}; the step log of the {converged} converged "
        f"steps (bias_steps.csv, .json) and failure.json are in {out}; the fields "
        "(bias.xdmf, bias.h5) are not kept: an interrupted HDF5 file cannot be read back"
    )


def run(args: argparse.Namespace) -> int:
    """The ``bias`` command; a solver failure keeps the converged steps and exits with 2."""
    comm = MPI.COMM_WORLD
    ubar = check_bias_options(args)
    model, params = _model(args)
    saved = saved_fit(args)
    od = OutputDir(
        args.out,
        comm,
        keep_on_error=True,
        files=OUTPUTS,
        inputs=((f"--params {args.params}", args.params),) if args.params else (),
    )
    rank0(
        log,
        comm,
        f"bias extension {args.length} x {args.width} mm, h = {args.h} mm, "
        f"terms {[t.name for t in model]}, ubar up to {ubar} mm "
        f"on {comm.size} rank(s)",
    )
    defaulted = defaulted_moduli(model, params) if args.params else []
    if defaulted:  # a partial --params file: the rest are the terms' defaults, said
        rank0(
            log,
            comm,
            f"note: --params {args.params} gives no value for "
            f"{', '.join(defaulted)}: the term's default is used",
        )
    with od as stage:
        test = BiasExtension(model, args.length, args.width, args.h, args.clamp)
        summary = {
            "provenance": provenance(model, [], [args.h]),
            "clamp": args.clamp,
            "discretisation": test.discretisation,
            "angle_A_mesh_dependent": not has_second_gradient(model),
        }
        if summary["angle_A_mesh_dependent"]:
            rank0(log, comm, ANGLE_A_NOTE)
        done: list[int] = []

        od.on_interrupt = lambda stage_dir: interrupted_report(  # no MPI call in there
            stage_dir, summary, len(done), args.steps, args.out
        )
        try:
            res = test.run(ubar, args.steps, out=stage, on_step=lambda k, u: done.append(k))
        except LoadStepError as e:
            write_json(comm, stage / "failure.json", summary | {"error": str(e)})
            raise RuntimeError(f"{e}; the converged steps are in {args.out}") from None
        summary |= {
            "ubar": res.ubar,
            "force": res.force,
            "angle_A_deg": res.angle_A_deg,
            "angle_B_deg": res.angle_B_deg,
            "newton_iterations": res.newton,
            "seconds": res.seconds,
            "ranks": comm.size,
        }
        if saved is not None:
            band = summary["force_band"] = _band(args, model, ubar, saved, stage, comm)
            half, F = band["half_width"][-1], band["force"][-1]
            rank0(
                log,
                comm,
                f"prediction band at ubar = {ubar:g} mm: {F:.4g} ± {half:.2g} N "
                f"(95 %; linearisation "
                f"{'holds' if band['reliable'] else 'fails: refit instead'})",
            )
        write_json(comm, stage / "summary.json", summary)
        on_rank0(comm, bias_curves, res, stage / "force.png")
    rank0(log, comm, f"done in {res.seconds:.1f} s; XDMF, force curve and summary in {args.out}")
    return 0


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="fabricsurf bias", description=__doc__.splitlines()[0])
    add_arguments(parser)
    run(parser.parse_args(argv))


if __name__ == "__main__":
    main()
