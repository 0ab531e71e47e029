"""``fabricsurf diagnose DATA [DATA …] --terms …``: which effect is missing, by the stepwise
diagnosis on a mesh chosen for the data (:mod:`~fabricsurf.inverse.diagnosis.mesh_choice`),
with the experiment that would separate a tie. Writes diagnosis.json, the baseline and
before/after comparisons, the misfit path (and a tie's difference map, model_best.json with
``--add-best``), and prints the ranking, the verdict and the final moduli. The inputs are those
of compare and fit, checked alike (:mod:`~fabricsurf.cli.measure`).
"""

from __future__ import annotations

import logging

from mpi4py import MPI

from fabricsurf.cli.measure import add_common, add_plausible, checked_setup, failure_report
from fabricsurf.cli.mesh_options import mesh_budget
from fabricsurf.cli.options import (
    diagnose_options,
    enough_data,
    grip_depths,
    input_paths,
    positive_start,
)
from fabricsurf.cli.outdir import OutputDir
from fabricsurf.discretise.output import on_rank0, write_json
from fabricsurf.errors import InputError
from fabricsurf.inverse.diagnosis.mesh_choice import (
    DEFAULT_MAX_DOFS,
    DEFAULT_SECONDS,
    LEVEL_GROWTH,
)
from fabricsurf.inverse.diagnosis.result_text import (
    excess_lines,
    implausible_lines,
    result_lines,
    tie_lines,
)
from fabricsurf.inverse.fitting.params import provenance
from fabricsurf.inverse.fitting.plausibility import parse_plausible
from fabricsurf.inverse.forward import profile
from fabricsurf.log import rank0

log = logging.getLogger(__name__)

COMM = MPI.COMM_WORLD


def cmd_diagnose(args) -> int:
    from fabricsurf.inverse.diagnosis.beyond import summary_lines
    from fabricsurf.inverse.diagnosis.discrimination import separate_tie
    from fabricsurf.inverse.diagnosis.mesh_choice import diagnose_on_mesh
    from fabricsurf.inverse.plots import figures
    from fabricsurf.inverse.plots.excess import excess_figure
    from fabricsurf.inverse.plots.outputs import write_comparison

    budget = mesh_budget(args)
    exps, model, params = checked_setup(args, refine=2)
    positive_start(model, args, "diagnose")
    depths = grip_depths(args.grip_depths, exps)
    candidates, fixed = diagnose_options(args, exps, model, params)
    parse_plausible(args.plausible)
    if args.yarn_spacing is not None and not 0 < args.yarn_spacing < float("inf"):
        raise InputError(f"--yarn-spacing {args.yarn_spacing:g}: must be a positive length in mm")
    enough_data(exps, model, fixed or [])
    params = {t.name: t.values() for t in model}
    od = OutputDir(args.out, COMM, files=("diagnosis.json",), inputs=input_paths(args, exps))
    with od as stage, failure_report(od, stage, model, args, exps):
        try:
            prof = profile.Profile(COMM)
            with profile.active(prof):
                d = diagnose_on_mesh(
                    exps,
                    [t.name for t in model],
                    h=args.h,
                    budget=budget,
                    params=params,
                    confirm=args.confirm,
                    max_effects=args.max_effects,
                    comm=COMM,
                    candidates=candidates,
                    fixed=fixed,
                    grip_depths=depths,
                    beyond_features=args.beyond_features,
                    yarn_spacing=args.yarn_spacing,
                    plausible=args.plausible,
                )
        except ValueError as e:
            raise InputError(str(e)) from None
        d, tie = separate_tie(d, exps, args.h, COMM)
        if tie is not None:
            on_rank0(
                COMM,
                figures.difference_map,
                tie.maps,
                tie.effects,
                stage / "tie_difference_map.png",
            )
        hs = [m["h"] for m in d.meshes]
        out = d.as_dict() | {
            "provenance": provenance(model, [str(x) for x in args.data], hs),
            "profile": prof.as_json(),  # collective
        }
        write_json(COMM, stage / "diagnosis.json", out)
        b, f = d.base_fit, d.final_fit
        preds, mfs = [("baseline", b.prediction)], [("baseline", b.misfit)]
        write_comparison(stage, exps, preds, mfs, stem="baseline_")
        if d.verdict is not None:
            label = "+".join(d.terms)
            write_comparison(
                stage,
                exps,
                preds + [(label, f.prediction)],
                mfs + [(label, f.misfit)],
                stem="before_after_",
            )
            if args.add_best:
                write_json(COMM, stage / "model_best.json", f.as_dict())
        on_rank0(COMM, figures.misfit_path, d.path, stage / "misfit_path.png")
        if (d.excess_location or {}).get("verdict") is not None:
            on_rank0(COMM, excess_figure, d.excess_location, stage / "excess_location.png")
        for found in (d.beyond or {}).get("found", []):  # the term to paste, as a module
            on_rank0(COMM, (stage / f"beyond_{found['feature']}.py").write_text, found["source"])
    if d.grip_depth is not None:
        rank0(
            log,
            COMM,
            f"grip depth: {d.grip_depth['best_mm']:g} mm (the best of "
            f"{[q['depth_mm'] for q in d.grip_depth['profile']]})",
        )
    rank0(log, COMM, f"baseline {'+'.join(d.baseline)}: misfit {b.misfit['combined']:.4g}")
    for r in d.ranking:
        rank0(
            log,
            COMM,
            f"  {r['effect']:18s} score {r['score']:10.4g}  refit misfit "
            f"{r['refit_misfit']}  Wald p {r.get('wald_p')}  significant "
            f"{r['significant']}",
        )
    for line in tie_lines(d):
        rank0(log, COMM, line)
    rank0(
        log,
        COMM,
        f"verdict: {d.verdict_text()}; final {'+'.join(d.terms)} misfit "
        f"{f.misfit['combined']:.4g}; adequate: {d.adequate}; {d.outcome()}",
    )
    for line in result_lines(out["final"]):
        rank0(log, COMM, line)
    for line in excess_lines(d.excess_location) + implausible_lines(d.implausible):
        rank0(log, COMM, line)
    if d.beyond is not None:
        for line in summary_lines(d.beyond):
            rank0(log, COMM, line)
    lead = (d.unexplained or {}).get("best_lead")
    if lead:
        wald = (
            "no Wald test"
            if lead["wald_p"] is None
            else f"Wald p = {lead['wald_p']:.3g} (must be below {lead['wald_p_needed']:.3g})"
        )
        rank0(
            log,
            COMM,
            f"best lead: {lead['effect']} removes {lead['share_of_excess']:.0%} of "
            f"the excess misfit; {wald}; F-test "
            f"{'passed' if lead['f_test_passed'] else 'failed'} (both are needed)",
        )
    return 0


def add_parser(sub, formatter) -> None:
    p = sub.add_parser(
        "diagnose",
        formatter_class=formatter,
        help="which effect is missing: rank, confirm, add (stepwise)",
    )
    add_common(p)
    p.add_argument(
        "--confirm",
        type=int,
        default=2,
        help="candidates confirmed by refitting in each round (≥ 1)",
    )
    p.add_argument(
        "--max-effects",
        type=int,
        default=2,
        help="at most this many effects added, one per round (≥ 0)",
    )
    p.add_argument(
        "--candidates",
        default=None,
        help="comma-separated effects to consider (default: every effect the data can see)",
    )
    p.add_argument(
        "--fixed",
        default=None,
        help="comma-separated baseline terms held at their --params moduli "
        "(default: none, every baseline modulus is fitted)",
    )
    p.add_argument(
        "--grip-depths",
        default=None,
        help="comma-separated grip depths in mm of the bias experiments, e.g. "
        "0,0.5,1: the depth is fitted as a nuisance parameter first (the best of "
        "these by baseline chi2), then the diagnosis uses it (default: the depth "
        "in the data)",
    )
    p.add_argument(
        "--max-dofs",
        type=int,
        default=DEFAULT_MAX_DOFS,
        help="mesh selection: when the h/2 check says the mesh is too coarse for the "
        "data, the diagnosis halves h and runs again, up to this many displacement "
        "unknowns (all experiments; the check solves on ~4x as many) and within "
        "--max-elements for the check's mesh (docs/diagnosis.md)",
    )
    p.add_argument(
        "--time-budget",
        type=float,
        default=DEFAULT_SECONDS,
        help="mesh selection: a refined level is started only if it is predicted "
        f"to end within this many seconds of the start ({LEVEL_GROWTH:g}x the last "
        "level's time)",
    )
    p.add_argument(
        "--beyond-features",
        type=int,
        default=1,
        help="when the named effects leave the model not adequate, search a library of "
        "energy features beyond the vocabulary for up to this many (0: no search; "
        "docs/diagnosis.md, 'Beyond the vocabulary'); each found is written as "
        "beyond_<feature>.py, a term to load with --effects",
    )
    p.add_argument(
        "--yarn-spacing",
        type=float,
        default=None,
        help="the fabric's yarn spacing in mm (the distance between neighbouring yarns of a "
        "family): the unit in which the final model's excess is located by its distance from "
        "the grips and zone boundaries (docs/diagnosis.md, 'Where the excess sits'; default: "
        "unknown, distances in mesh sizes h)",
    )
    add_plausible(p)
    p.add_argument(
        "--add-best",
        action="store_true",
        help="also save the final model as model_best.json (a --params file)",
    )
    p.set_defaults(func=cmd_diagnose)
