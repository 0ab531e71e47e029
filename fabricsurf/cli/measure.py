"""``fabricsurf compare|fit DATA [DATA …]``: model against measurements, and the inputs that
``diagnose`` (:mod:`~fabricsurf.cli.diagnose_command`) shares with them.

Every command takes one or more measurement directories (contract version 2); with several,
one set of moduli serves all of them (one material, several tests) and misfits are reported per
experiment and overall. Outputs go to ``--out`` (checked before any computation, written
atomically) and record the terms, moduli, mesh sizes, inputs and software versions used.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
from collections.abc import Iterator

from mpi4py import MPI

from fabricsurf.cli.effects import add_effects
from fabricsurf.cli.mesh_options import (
    add_max_elements,
    check_default_size,
    check_h,
    check_size,
)
from fabricsurf.cli.options import (
    check_params_file,
    compare_moduli,
    enough_data,
    error_map_steps,
    fixed_terms,
    input_paths,
    out_path,
    positive_start,
    saved_fit,
)
from fabricsurf.cli.outdir import OutputDir
from fabricsurf.discretise.output import write_json
from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.checks import unloading_warning
from fabricsurf.inverse.contract.data import load_experiment
from fabricsurf.inverse.diagnosis.result_text import (
    implausible_lines,
    misfit_summary,
    result_lines,
)
from fabricsurf.inverse.fitting.params import load_params, parse_model, provenance
from fabricsurf.inverse.fitting.plausibility import parse_plausible
from fabricsurf.inverse.fitting.preconditions import check_in_loop, check_terms_fit_data
from fabricsurf.inverse.forward.misfit import converged_steps
from fabricsurf.log import rank0, warn
from fabricsurf.model.terms import EFFECTS

log = logging.getLogger(__name__)

COMM = MPI.COMM_WORLD


def add_common(p: argparse.ArgumentParser, terms_required: bool = True) -> None:
    p.add_argument("data", nargs="+", help="measurement directories (experiment.toml + CSV)")
    p.add_argument(
        "--terms",
        required=terms_required,
        default=None,
        help="comma-separated effects, each once, from: "
        + ", ".join(EFFECTS)
        + " and those of --effects"
        + (" (required)" if terms_required else " (default: the terms named in --params)"),
    )
    p.add_argument(
        "--params",
        default=None,
        help='JSON moduli {"term": {"parameter": value}}, '
        "first-gradient moduli in N/mm, second-gradient in N·mm (see `fabricsurf "
        "terms`), or a saved fit.json; only terms of --terms; compare needs every "
        "modulus of --terms, fit and diagnose start from them (default: every "
        "modulus 1.0)",
    )
    p.add_argument(
        "--out",
        required=True,
        type=out_path,
        help="output directory (created if "
        "missing; must be writable; one run's results: those of an earlier run there "
        "are replaced, docs/usage.md)",
    )
    p.add_argument(
        "--h",
        type=float,
        default=None,
        help="element size in mm (default: the test's own: min(length, width)/10 "
        "for bias_extension, length/8 for picture_frame)",
    )
    add_max_elements(p)
    add_effects(p)


def checked_setup(args, refine: int = 1):
    """The experiments, model and --params moduli, every input checked before any
    computation; ``refine``: the finest mesh the command builds is at h/refine."""
    check_h(args.h)
    check_params_file(args.params)
    params = load_params(args.params, args.terms.split(",") if args.terms else None)
    model = parse_model(args.terms, params)
    exps = [load_experiment(d) for d in args.data]
    names = [e.name for e in exps]
    if len(set(names)) != len(names):
        raise InputError(
            f"experiments must have distinct names (experiment.toml: name), got "
            f"{names} from {', '.join(map(str, args.data))}"
        )
    if len(names) > 1:
        from fabricsurf.inverse.plots.outputs import slug

        seen: dict[str, str] = {}
        for n in names:
            other = seen.setdefault(slug(n).casefold(), n)
            if other != n:
                raise InputError(
                    f"experiments '{other}' and '{n}' (experiment.toml: name) "
                    f"give the same file name prefix '{slug(n)}_' in --out, so "
                    "one set of figures would overwrite the other; rename one"
                )
    check_in_loop(exps, args.data)
    check_terms_fit_data(exps, model, ",".join(t.name for t in model))
    check_h(args.h, exps)
    for e in exps:
        warning = unloading_warning(e, model)
        if warning:
            warn(log, COMM, str(warning))
    if args.h is not None:
        check_size(
            args.h, [(f"'{e.name}'", e.length, e.width) for e in exps], args.max_elements, refine
        )
    else:
        check_default_size(exps, args.max_elements, refine)
    return exps, model, params


@contextlib.contextmanager
def failure_report(od: OutputDir, stage, model, args, exps) -> Iterator[None]:
    """A solver failure writes failure.json (the message and what was used), publishes it and
    ends with a message that names it."""
    try:
        yield
    except LoadStepError as e:
        partial, by_name = getattr(e, "partial", None), {x.name: x for x in exps}
        kept = (
            {}
            if partial is None
            else {
                "experiment": e.experiment,
                "converged_steps": converged_steps(by_name[e.experiment], partial),
            }
        )
        if e.step:  # where the load path stopped
            kept |= {"step": e.step, "load": e.target}
        write_json(
            COMM,
            stage / "failure.json",
            {"error": str(e)}
            | kept
            | {"provenance": provenance(model, [str(d) for d in args.data], args.h and [args.h])},
        )
        od.keep = True
        raise RuntimeError(f"{e}; the failure report is in {od.out / 'failure.json'}") from None


def _prov(model, args, h: list[float], discretisation: dict) -> dict:
    """The provenance of a compare or fit, with the mesh kind, size and fibre treatment each
    experiment actually got (``discretisation``: the plug-in's record, where it keeps one)."""
    prov = provenance(model, [str(d) for d in args.data], h)
    return {"provenance": prov | {"discretisation": discretisation}}


def cmd_compare(args) -> int:
    from fabricsurf.inverse.fitting.compare import compare
    from fabricsurf.inverse.plots.comparison_bands import write_band_files
    from fabricsurf.inverse.plots.outputs import write_comparison

    exps, model, params = checked_setup(args)
    steps = error_map_steps(args.steps, exps)
    note = compare_moduli(args, model, params)  # refuses moduli a --params file lacks
    saved = saved_fit(args)
    od = OutputDir(args.out, COMM, files=("misfit.json",), inputs=input_paths(args, exps))
    with od as stage, failure_report(od, stage, model, args, exps):
        if note:
            rank0(log, COMM, note)
        res = compare(exps, model, h=args.h, band=saved, comm=COMM)
        extra = _prov(model, args, res.h, res.discretisation)
        if res.bands is not None:
            write_band_files(stage, exps, res.bands, COMM)
            extra["force_bands"] = res.band_summary()
        if res.stability is not None:  # a model with a signed modulus
            extra["stability"] = res.stability.as_dict()
        write_comparison(
            stage,
            exps,
            [(res.label, res.predictions)],
            [(res.label, res.misfit)],
            steps,
            extra=extra,
        )
    rank0(log, COMM, misfit_summary(res.label, res.misfit))
    return 0


def cmd_fit(args) -> int:
    from fabricsurf.inverse.fitting.compare import records
    from fabricsurf.inverse.fitting.fit import fit
    from fabricsurf.inverse.forward.runs import ForwardSet
    from fabricsurf.inverse.plots.outputs import write_comparison

    exps, model, params = checked_setup(args, refine=2)
    fixed = fixed_terms(args, model, params)
    positive_start(model, args, "fit")
    parse_plausible(args.plausible)
    enough_data(exps, model, fixed)
    od = OutputDir(
        args.out, COMM, files=("fit.json", "misfit.json"), inputs=input_paths(args, exps)
    )
    with od as stage, failure_report(od, stage, model, args, exps):
        with ForwardSet(exps, model, h=args.h, comm=COMM) as fs:
            free = [k for k, (t, _) in enumerate(fs.params) if t.name not in (fixed or ())]
            res = fit(fs, free, plausible=args.plausible or True)
            res.check_mesh(fs)
            extra = _prov(model, args, [m.h for m in fs.models], records(fs))
        write_json(COMM, stage / "fit.json", res.as_dict() | extra)
        label = "fit: " + "+".join(t.name for t in model)
        write_comparison(stage, exps, [(label, res.prediction)], [(label, res.misfit)])
    for line in result_lines(res.as_dict()) + implausible_lines(res.implausible):
        rank0(log, COMM, line)
    rank0(log, COMM, misfit_summary(label, res.misfit))
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser(
        "compare",
        formatter_class=formatter,
        help="misfit of a model against the data, with figures",
    )
    add_common(p, terms_required=False)
    p.add_argument(
        "--steps",
        default=None,
        help="comma-separated step numbers (as in the "
        "data files, from 1) for the error map (default: the middle and the last)",
    )
    p.add_argument(
        "--no-band",
        action="store_true",
        help="no prediction band of the force "
        "curves even when --params is a saved fit (fit.json, model_best.json: the "
        "band costs two more forward runs per experiment)",
    )
    p.set_defaults(func=cmd_compare)
    p = sub.add_parser(
        "fit", formatter_class=formatter, help="least-squares fit of the moduli (log-parametrised)"
    )
    add_common(p)
    add_plausible(p)
    p.add_argument(
        "--fixed",
        default=None,
        help="comma-separated terms of --terms held at their --params moduli, e.g. "
        "fibre_stretch from a tensile test (default: none, every modulus is fitted)",
    )
    p.set_defaults(func=cmd_fit)


def add_plausible(p: argparse.ArgumentParser) -> None:
    """--plausible: the ranges the fitted moduli must keep (fit and diagnose)."""
    p.add_argument(
        "--plausible",
        default=None,
        help="comma-separated ranges the fitted moduli must keep, term.param=low:high in "
        "the modulus's unit, e.g. fibre_stretch.k_l=1000:1e5 (N/mm): one outside is "
        "reported with the effect it stands in for; fitted yarns soft enough to carry the "
        "shear the data impose are reported whatever the ranges (default: no ranges; "
        "docs/diagnosis.md, 'Moduli no fabric has')",
    )
