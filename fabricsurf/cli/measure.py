"""``fabricsurf compare|fit|diagnose DATA [DATA …]``: model against measurements.

Every command takes one or more measurement directories (contract version 2); with several,
one set of moduli serves all of them (one material, several tests) and misfits are reported per
experiment and overall. Outputs go to ``--out`` (checked before any computation, written
atomically) and record the terms, moduli, mesh sizes, inputs and software versions used.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import re
from collections.abc import Iterator

import numpy as np
from mpi4py import MPI

from fabricsurf.cli.outdir import OutputDir
from fabricsurf.discretise.output import on_rank0, rank0_print, write_json
from fabricsurf.discretise.solver import LoadStepError
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.data import load_experiment
from fabricsurf.inverse.fitting.misfit import converged_steps
from fabricsurf.inverse.fitting.params import load_params, parse_model, provenance
from fabricsurf.model.terms import EFFECTS

COMM = MPI.COMM_WORLD
MAX_ELEMENTS = 400_000
"""Default of ``--max-elements``: about 20 GB at KB_PER_ELEMENT, what a 24 GB machine holds."""
KB_PER_ELEMENT = 50.0
"""Memory per triangle, all ranks together: measured 26 kB (11 000 elements) and 38 kB (23 000;
bias test, second-gradient model, MUMPS), rising with the direct solver's fill-in."""


def add_common(p: argparse.ArgumentParser, terms_required: bool = True) -> None:
    p.add_argument("data", nargs="+", help="measurement directories (experiment.toml + CSV)")
    p.add_argument("--terms", required=terms_required, default=None,
                   help="comma-separated effects, each once, from: " + ", ".join(EFFECTS)
                   + (" (required)" if terms_required else
                      " (default: the terms named in --params)"))
    p.add_argument("--params", default=None, help='JSON moduli {"term": {"parameter": value}}, '
                   "first-gradient moduli in N/mm, second-gradient in N·mm (see `fabricsurf "
                   "terms`), or a saved fit.json; only terms of --terms (default: every modulus "
                   "1.0)")
    p.add_argument("--out", required=True, help="output directory (created if missing; must be "
                   "writable; results replace files of the same name)")
    p.add_argument("--h", type=float, default=None,
                   help="element size in mm (default: the test's own: min(length, width)/10 "
                   "for bias_extension, length/8 for picture_frame)")
    add_max_elements(p)


def add_max_elements(p: argparse.ArgumentParser) -> None:
    p.add_argument("--max-elements", type=int, default=MAX_ELEMENTS,
                   help="refuse a --h whose meshes would have more elements than this, "
                   f"estimated before meshing (~{KB_PER_ELEMENT:g} kB of memory each)")


def check_size(h: float, specimens: list[tuple[str, float, float]], max_elements: int) -> None:
    """Refuse ``--h`` when the meshes of ``specimens`` ((name, length, width) in mm) would
    have more than ``max_elements`` triangles in all, estimated as 2 per h × h square before
    any meshing, with the memory they would take."""
    if max_elements < 1:
        raise InputError(f"--max-elements {max_elements}: must be at least 1")
    n = sum(2 * math.ceil(L / h) * math.ceil(W / h) for _, L, W in specimens)
    if n > max_elements:
        what = ", ".join(f"{name} {L:g} x {W:g} mm" for name, L, W in specimens)
        gb = n * KB_PER_ELEMENT / 1e6
        gb = f"{gb:,.0f}" if gb >= 10 else f"{gb:.2g}"
        raise InputError(f"--h {h:g}: about {n:,} elements ({what}), more than --max-elements "
                         f"{max_elements:,}; they would take about "
                         f"{gb} GB of memory (~{KB_PER_ELEMENT:g} kB "
                         "per element): give a larger --h, or raise --max-elements if the "
                         "machine has the memory")


def check_h(h: float | None, exps: list | None = None) -> None:
    """``--h`` positive and at most half the smallest specimen side (two elements across)."""
    if h is None:
        return
    limit = 0.5 * min(min(e.length, e.width) for e in exps) if exps else float("inf")
    if not 0 < h <= limit:
        raise InputError(f"--h {h:g}: must be a positive element size in mm"
                         + (f", at most {limit:g} (two elements across the narrowest specimen)"
                            if exps else ""))


def _setup(args):
    check_h(args.h)
    params = load_params(args.params, args.terms.split(",") if args.terms else None)
    model = parse_model(args.terms, params)
    exps = [load_experiment(d) for d in args.data]
    names = [e.name for e in exps]
    if len(set(names)) != len(names):
        raise InputError(f"experiments must have distinct names (experiment.toml: name), got "
                         f"{names} from {', '.join(map(str, args.data))}")
    if len(names) > 1:
        from fabricsurf.inverse.plots.outputs import slug

        seen: dict[str, str] = {}
        for n in names:
            other = seen.setdefault(slug(n).casefold(), n)
            if other != n:
                raise InputError(f"experiments '{other}' and '{n}' (experiment.toml: name) "
                                 f"give the same file name prefix '{slug(n)}_' in --out, so "
                                 "one set of figures would overwrite the other; rename one")
    check_h(args.h, exps)
    if args.h is not None:
        check_size(args.h, [(f"'{e.name}'", e.length, e.width) for e in exps],
                   args.max_elements)
    return exps, model, params


def _inputs(args, exps: list) -> tuple[tuple[str, str], ...]:
    """(label, path) of every input, which --out must keep apart from (cli.outdir)."""
    found = [(f"DATA directory {d}", d) for d in args.data]
    found += [(f"file {f} of DATA {d}", f) for d, e in zip(args.data, exps) for f in e.files]
    return tuple(found + ([(f"--params {args.params}", args.params)] if args.params else []))


def _enough_data(exps: list, model: list, fixed: list[str] | None = None) -> None:
    """Refuse a fit of more moduli than there are data (under-determined: its ± would be
    meaningless). Data: every force value, and every field row times the components the
    test compares."""
    from fabricsurf.experiments import get_test

    free = [f"{t.name}.{p}" for t in model if t.name not in (fixed or []) for p in t.values()]
    counts, n = [], 0
    for e in exps:
        nf = len(e.force) if e.has_force else 0
        comps = min(get_test(e.test).d, e.u.shape[1])
        nu = len(e.X) * comps if e.has_field else 0
        n += nf + nu
        rows = len(e.X)
        counts.append(f"'{e.name}': " + ", ".join(
            ([f"{nf} force value{'s' * (nf != 1)}"] if e.has_force else [])
            + ([f"{rows} field row{'s' * (rows != 1)} x {comps} components"]
               if e.has_field else [])))
    if n < len(free):
        raise InputError(f"--terms {','.join(t.name for t in model)}: {len(free)} moduli to fit "
                         f"({', '.join(free)}) from {n} measured value{'s' * (n != 1)} "
                         f"({'; '.join(counts)}): fewer data than moduli, the fit is "
                         "under-determined; give more data (load steps, field points) or fit "
                         "fewer moduli"
                         + (" (fewer --terms, or --fixed)" if fixed is not None else
                            " (fewer --terms)"))


def _positive_start(model, args) -> None:
    """fit and diagnose work in log-moduli: a starting modulus of 0 cannot move."""
    for t in model:
        for p, v in t.values().items():
            if v <= 0:
                raise InputError(f"--params {args.params}: {t.name}.{p} = {v:g}: fit and "
                                 "diagnose start from these moduli in log scale; give a "
                                 "positive starting value")


def _number_list(spec: str, option: str, cast: type, what: str):
    """``spec`` split at commas and converted by ``cast``; a bad item names the option."""
    try:
        return [cast(s) for s in spec.split(",")]
    except ValueError:
        raise InputError(f"{option} {spec}: expected comma-separated {what}") from None


def _error_map_steps(spec: str | None, exps: list) -> list[int] | None:
    if spec is None:
        return None
    steps = _number_list(spec, "--steps", int, "step numbers, e.g. 1,3")
    for e in exps:
        bad = [s for s in steps if s not in set(int(k) for k in e.steps)]
        if bad:
            raise InputError(f"--steps {spec}: step {bad[0]} is not a step of experiment "
                             f"'{e.name}' (steps {int(e.steps[0])}..{int(e.steps[-1])})")
    return steps


@contextlib.contextmanager
def _failure_report(od: OutputDir, stage, model, args, exps) -> Iterator[None]:
    """A solver failure writes failure.json (the message and what was used), publishes it and
    ends with a message that names it."""
    try:
        yield
    except LoadStepError as e:
        partial, by_name = getattr(e, "partial", None), {x.name: x for x in exps}
        kept = {} if partial is None else {"experiment": e.experiment, "converged_steps":
                                           converged_steps(by_name[e.experiment], partial)}
        if e.step:  # where the load path stopped
            kept |= {"step": e.step, "load": e.target}
        write_json(COMM, stage / "failure.json",
                   {"error": str(e)} | kept | {"provenance": provenance(
                       model, [str(d) for d in args.data], args.h and [args.h])})
        od.keep = True
        raise RuntimeError(f"{e}; the failure report is in {od.out / 'failure.json'}"
                           ) from None


def _summary(label: str, m: dict) -> str:
    parts = [f"{label}: combined misfit {m['combined']:.4g} (noise units), chi2 "
             f"{m['chi2']:.5g} over {m['n']} data"]
    for e in m["experiments"]:
        bits = [f"field RMS {e['field_rms']:.4g} mm" if e["field_rms"] is not None else "",
                f"force RMS {e['force_rms']:.4g} N" if e["force_rms"] is not None else ""]
        parts.append(f"  {e['experiment']}: misfit {e['combined']:.4g}; "
                     + ", ".join(b for b in bits if b)
                     + (f"; points outside the mesh: {e['points_outside']}"
                        if e["points_outside"] else ""))
    return "\n".join(parts)


def _prov(model, fs, args) -> dict:
    return {"provenance": provenance(model, [str(d) for d in args.data],
                                     [m.h for m in fs.models])}


def cmd_compare(args) -> int:
    from fabricsurf.inverse.fitting.forward import ForwardSet
    from fabricsurf.inverse.plots.outputs import write_comparison

    exps, model, _ = _setup(args)
    steps = _error_map_steps(args.steps, exps)
    od = OutputDir(args.out, COMM, files=("misfit.json",),
                   inputs=_inputs(args, exps))
    with od as stage, _failure_report(od, stage, model, args, exps):
        fs = ForwardSet(exps, model, h=args.h, comm=COMM)
        preds = fs.run()
        m = fs.misfit(preds)
        label = "+".join(t.name for t in model)
        write_comparison(stage, exps, [(label, preds)], [(label, m)], steps,
                         extra=_prov(model, fs, args))
    rank0_print(COMM, _summary(label, m))
    return 0


def result_lines(res) -> list[str]:
    """The fitted moduli, each with its ±, except where the data do not determine it: a
    modulus in a null direction of the Fisher matrix (its ± would be a meaningless 1e-13) or
    whose ± spans zero is said to be undetermined, with the combinations."""
    lost = {n for c in res.undetermined for n in re.findall(r"log (\S+)", c)}
    lines = []
    for n, v, s in zip(res.names, res.values, res.std):
        if n in lost:
            lines.append(f"  {n} = {v:.5g} (not determined by the data: see below)")
        elif not np.isfinite(s) or s >= v:
            lines.append(f"  {n} = {v:.5g} (not determined by the data: the ± {s:.2g} spans "
                         "zero)")
        else:
            lines.append(f"  {n} = {v:.5g} ± {s:.2g}")
    for c in res.undetermined:
        lines.append(f"  not determined by the data (rank-deficient Fisher matrix): {c}")
    return lines


def cmd_fit(args) -> int:
    from fabricsurf.inverse.fitting.fit import fit
    from fabricsurf.inverse.fitting.forward import ForwardSet
    from fabricsurf.inverse.plots.outputs import write_comparison

    exps, model, _ = _setup(args)
    _positive_start(model, args)
    _enough_data(exps, model)
    od = OutputDir(args.out, COMM, files=("fit.json", "misfit.json"),
                   inputs=_inputs(args, exps))
    with od as stage, _failure_report(od, stage, model, args, exps):
        fs = ForwardSet(exps, model, h=args.h, comm=COMM)
        res = fit(fs, verbose=True)
        write_json(COMM, stage / "fit.json", res.as_dict() | _prov(model, fs, args))
        label = "fit: " + "+".join(t.name for t in model)
        write_comparison(stage, exps, [(label, res.prediction)], [(label, res.misfit)])
    for line in result_lines(res):
        rank0_print(COMM, line)
    rank0_print(COMM, _summary(label, res.misfit))
    return 0


def _names(spec: str | None) -> list[str] | None:
    return None if spec is None else [n.strip() for n in spec.split(",") if n.strip()]


def _grip_depths(spec: str | None, exps: list) -> list[float] | None:
    """``--grip-depths``: comma-separated depths in mm, checked against the experiments."""
    if spec is None:
        return None
    from fabricsurf.inverse.fitting.nuisance import check_depths

    depths = _number_list(spec, "--grip-depths", float, "depths in mm, e.g. 0,0.5,1")
    try:
        check_depths(exps, depths, f"--grip-depths {spec}")
    except ValueError as e:
        raise InputError(str(e)) from None
    return depths


def _diagnose_options(args, exps: list, model: list, params: dict
                      ) -> tuple[list[str] | None, list[str] | None]:
    """--candidates and --fixed, checked against the vocabulary, the baseline (--terms), the
    data and --params: no combination that silently answers another question."""
    from fabricsurf.inverse.fitting.diagnose import visible_effects

    baseline = [t.name for t in model]
    terms = f"--terms {','.join(baseline)}"
    cands, fixed = _names(args.candidates), _names(args.fixed)
    for option, spec, names in (("--candidates", args.candidates, cands),
                                ("--fixed", args.fixed, fixed)):
        if names is None:
            continue
        if not names:
            raise InputError(f"{option} {spec!r}: names no effect")
        bad = [n for n in names if n not in EFFECTS]
        if bad:
            raise InputError(f"{option} {spec}: unknown term '{bad[0]}'; valid terms are: "
                             f"{', '.join(EFFECTS)}")
        dup = [n for n in names if names.count(n) > 1]
        if dup:
            raise InputError(f"{option} {spec}: '{dup[0]}' is given twice")
    if fixed is not None:
        outside = [n for n in fixed if n not in baseline]
        if outside:
            raise InputError(f"--fixed {args.fixed}: '{outside[0]}' is not a baseline term "
                             f"({terms}); only baseline terms can be held fixed")
        if set(fixed) == set(baseline):
            raise InputError(f"--fixed {args.fixed}: every baseline term ({terms}) is fixed, "
                             "so the baseline has no modulus to fit; leave at least one free "
                             "(compare evaluates a model with given moduli)")
        missing = [f"{n}.{p}" for n in fixed for p in EFFECTS[n].parameters()
                   if p not in params.get(n, {})]
        if missing:
            where = f"in --params {args.params}" if args.params else "(no --params file)"
            raise InputError(f"--fixed {args.fixed}: a fixed term is held at its moduli from "
                             f"--params, and {', '.join(missing)} is not given {where}; give "
                             "the known moduli of every fixed term")
    if cands is not None:
        hidden = [c for c in cands if c not in visible_effects(exps)]
        if hidden:
            raise InputError(f"--candidates {args.candidates}: these data cannot see "
                             f"{', '.join(hidden)} (planar data cannot see out-of-plane "
                             "effects)")
        if all(c in baseline for c in cands):
            raise InputError(f"--candidates {args.candidates}: every candidate is already in "
                             f"the baseline ({terms}), so nothing would be tested; name "
                             "effects that are not in --terms")
    return cands, fixed


def cmd_diagnose(args) -> int:
    from fabricsurf.inverse.fitting.diagnose import diagnose
    from fabricsurf.inverse.plots import figures
    from fabricsurf.inverse.plots.outputs import write_comparison

    if args.confirm < 1:
        raise InputError(f"--confirm {args.confirm}: must be at least 1")
    if args.max_effects < 0:
        raise InputError(f"--max-effects {args.max_effects}: must be at least 0")
    exps, model, params = _setup(args)
    _positive_start(model, args)
    depths = _grip_depths(args.grip_depths, exps)
    candidates, fixed = _diagnose_options(args, exps, model, params)
    _enough_data(exps, model, fixed or [])
    params = {t.name: t.values() for t in model}
    od = OutputDir(args.out, COMM, files=("diagnosis.json",),
                   inputs=_inputs(args, exps))
    with od as stage, _failure_report(od, stage, model, args, exps):
        try:
            d = diagnose(exps, [t.name for t in model], h=args.h, params=params,
                         confirm=args.confirm, max_effects=args.max_effects, comm=COMM,
                         candidates=candidates, fixed=fixed,
                         grip_depths=depths)
        except ValueError as e:
            raise InputError(str(e)) from None
        out = d.as_dict() | {"provenance": provenance(model, [str(x) for x in args.data],
                                                      args.h and [args.h])}
        write_json(COMM, stage / "diagnosis.json", out)
        b, f = d.base_fit, d.final_fit
        preds, mfs = [("baseline", b.prediction)], [("baseline", b.misfit)]
        write_comparison(stage, exps, preds, mfs, stem="baseline_")
        if d.verdict is not None:
            label = "+".join(d.terms)
            write_comparison(stage, exps, preds + [(label, f.prediction)],
                             mfs + [(label, f.misfit)], stem="before_after_")
            if args.add_best:
                write_json(COMM, stage / "model_best.json", f.as_dict())
        on_rank0(COMM, figures.misfit_path, d.path, stage / "misfit_path.png")
    if d.grip_depth is not None:
        rank0_print(COMM, f"grip depth: {d.grip_depth['best_mm']:g} mm (the best of "
                    f"{[q['depth_mm'] for q in d.grip_depth['profile']]})")
    rank0_print(COMM, f"baseline {'+'.join(d.baseline)}: misfit {b.misfit['combined']:.4g}")
    for r in d.ranking:
        rank0_print(COMM, f"  {r['effect']:18s} score {r['score']:10.4g}  refit misfit "
                    f"{r['refit_misfit']}  significant {r['significant']}")
    rank0_print(COMM, f"verdict: {d.verdict}; final {'+'.join(d.terms)} misfit "
                f"{f.misfit['combined']:.4g}; adequate: {d.adequate}; {d.outcome()}")
    lead = (d.unexplained or {}).get("best_lead")
    if lead:
        rank0_print(COMM, f"best lead: {lead['effect']} removes {lead['share_of_excess']:.0%} of "
                    f"the excess misfit ({lead['share_needed']:.0%} needed; F-test passed: "
                    f"{lead['f_test_passed']})")
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("compare", formatter_class=formatter,
                       help="misfit of a model against the data, with figures")
    add_common(p, terms_required=False)
    p.add_argument("--steps", default=None, help="comma-separated step numbers (as in the "
                   "data files, from 1) for the error map (default: the middle and the last)")
    p.set_defaults(func=cmd_compare)
    p = sub.add_parser("fit", formatter_class=formatter,
                       help="least-squares fit of the moduli (log-parametrised)")
    add_common(p)
    p.set_defaults(func=cmd_fit)
    p = sub.add_parser("diagnose", formatter_class=formatter,
                       help="which effect is missing: rank, confirm, add (stepwise)")
    add_common(p)
    p.add_argument("--confirm", type=int, default=2,
                   help="candidates confirmed by refitting in each round (≥ 1)")
    p.add_argument("--max-effects", type=int, default=2,
                   help="at most this many effects added, one per round (≥ 0)")
    p.add_argument("--candidates", default=None,
                   help="comma-separated effects to consider (default: every effect the data "
                   "can see)")
    p.add_argument("--fixed", default=None,
                   help="comma-separated baseline terms held at their --params moduli "
                   "(default: none, every baseline modulus is fitted)")
    p.add_argument("--grip-depths", default=None,
                   help="comma-separated grip depths in mm of the bias experiments, e.g. "
                   "0,0.5,1: the depth is fitted as a nuisance parameter first (the best of "
                   "these by baseline chi2), then the diagnosis uses it (default: the depth "
                   "in the data)")
    p.add_argument("--add-best", action="store_true",
                   help="also save the final model as model_best.json (a --params file)")
    p.set_defaults(func=cmd_diagnose)
