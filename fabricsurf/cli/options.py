"""Checks of the command-line options of ``fabricsurf compare|fit|diagnose|bias``, against
each other and against the data, made before any computation: every message names the option.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from fabricsurf.errors import InputError
from fabricsurf.inverse.fitting import preconditions as pre

MAX_ELEMENTS = 400_000
"""Default of ``--max-elements``: about 20 GB at KB_PER_ELEMENT, what a 24 GB machine holds."""
KB_PER_ELEMENT = 50.0
"""Memory per triangle, all ranks together (bias test, second-gradient model, MUMPS), with a
margin: it rises with the direct solver's fill-in (docs/uncertainty.md, costs)."""


def out_path(text: str) -> Path:
    """The type of ``--out``: an empty or blank name (an unset shell variable) is a usage error,
    not the working directory (which ``Path("")`` would be)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            f"{text!r} is empty (an unset variable?); give the output directory by name"
        )
    return Path(text)


def check_params_file(path) -> None:
    """``--params`` must be a regular file: a FIFO (or a device) would block the read or feed
    it without end."""
    from fabricsurf.inverse.contract.tables import special_file

    kind = special_file(Path(path)) if path else None
    if kind:
        raise InputError(
            f"--params {path}: {kind}, not a regular file; give the moduli as a JSON file"
        )


def add_max_elements(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--max-elements",
        type=int,
        default=MAX_ELEMENTS,
        help="refuse a --h whose meshes would have more elements than this, "
        f"estimated before meshing (~{KB_PER_ELEMENT:g} kB of memory each)",
    )


def _elements(length: float, width: float, h: float) -> float:
    """2 triangles per h × h square; a float (inf for a denormal h), never an overflow."""
    cells = [math.ceil(x) if x < 1e15 else x for x in (length / h, width / h)]
    return 2.0 * cells[0] * cells[1]


def _count(n: float) -> str:
    return f"{n:,.0f}" if n < 1e15 else f"{n:.2g}"


REFINED = " (fit and diagnose also solve there: the mesh check)"


def check_size(
    h: float, specimens: list[tuple[str, float, float]], max_elements: int, refine: int = 1
) -> None:
    """Refuse ``--h`` when the meshes of ``specimens`` ((name, length, width) in mm) would
    have more than ``max_elements`` triangles in all, estimated as 2 per h × h square before
    any meshing, with the memory they would take. ``refine``: the finest mesh the command
    builds is at h/refine (fit and diagnose: 2, their mesh check)."""
    if max_elements < 1:
        raise InputError(f"--max-elements {max_elements}: must be at least 1")
    n = sum(_elements(L, W, h / refine) for _, L, W in specimens)
    what = ", ".join(f"{name} {L:g} x {W:g} mm" for name, L, W in specimens)
    if refine > 1:
        what += f"; at h/{refine} = {h / refine:g} mm{REFINED}"
    if not math.isfinite(n):
        raise InputError(
            f"--h {h:g}: far too small an element size for {what} (the element "
            "count overflows); give a larger --h"
        )
    if n > max_elements:
        gb = n * KB_PER_ELEMENT / 1e6
        gb = f"{gb:,.0f}" if 10 <= gb < 1e15 else f"{gb:.2g}"
        raise InputError(
            f"--h {h:g}: about {_count(n)} elements ({what}), more than "
            f"--max-elements {max_elements:,}; they would take about "
            f"{gb} GB of memory (~{KB_PER_ELEMENT:g} kB "
            "per element): give a larger --h, or raise --max-elements if the "
            "machine has the memory"
        )


def check_default_size(exps: list, max_elements: int, refine: int = 1) -> None:
    """Without ``--h``, each experiment's mesh has its test's default element size: the same
    guard as :func:`check_size`, before any meshing, naming the default and the remedy."""
    from fabricsurf.experiments import get_test

    if max_elements < 1:
        raise InputError(f"--max-elements {max_elements}: must be at least 1")
    hs = [get_test(e.test).default_h(e.setup) for e in exps]
    n = sum(_elements(e.length, e.width, h / refine) for e, h in zip(exps, hs))
    if n > max_elements:
        what = ", ".join(
            f"'{e.name}' {e.length:g} x {e.width:g} mm at h = {h:.3g} mm" for e, h in zip(exps, hs)
        )
        if refine > 1:
            what += f", and at h/{refine}{REFINED}"
        raise InputError(
            f"no --h given: the tests' default element sizes ({what}) give about "
            f"{_count(n)} elements, more than --max-elements {max_elements:,} (about "
            f"{n * KB_PER_ELEMENT / 1e6:.3g} GB of memory); give a larger --h, "
            "or raise --max-elements if the machine has the memory"
        )


def mesh_budget(args):
    """``--max-dofs`` and ``--time-budget`` of diagnose (with ``--max-elements``) as the mesh
    selection's budget (:class:`~fabricsurf.inverse.diagnosis.mesh_choice.Budget`)."""
    from fabricsurf.inverse.diagnosis.mesh_choice import Budget

    if args.max_dofs < 1:
        raise InputError(
            f"--max-dofs {args.max_dofs}: must be at least 1 (displacement "
            "unknowns of the finest mesh the diagnosis may fit on)"
        )
    t = args.time_budget
    if not (math.isfinite(t) and t > 0):
        raise InputError(f"--time-budget {t:g}: must be a finite time in seconds > 0")
    return Budget(max_dofs=args.max_dofs, max_cells=args.max_elements, seconds=t)


def saved_fit(args) -> dict | None:
    """The --params file's contents when it is a saved fit with a covariance (fit.json or
    model_best.json, whose prediction bands can then be given) and --no-band is not set; else
    None. Called after the file has been validated as --params."""
    import json

    from fabricsurf.inverse.fitting.band import has_covariance

    if args.params is None or args.no_band:
        return None
    with open(args.params, encoding="utf-8") as f:
        saved = json.load(f)
    return saved if has_covariance(saved) else None


def check_h(h: float | None, exps: list | None = None) -> None:
    """``--h`` positive and at most half the smallest specimen side (two elements across)."""
    if h is None:
        return
    limit = 0.5 * min(min(e.length, e.width) for e in exps) if exps else float("inf")
    if not 0 < h <= limit:
        raise InputError(
            f"--h {h:g}: must be a positive element size in mm"
            + (f", at most {limit:g} (two elements across the narrowest specimen)" if exps else "")
        )


def input_paths(args, exps: list) -> tuple[tuple[str, str], ...]:
    """(label, path) of every input, which --out must keep apart from (cli.outdir)."""
    found = [(f"DATA directory {d}", d) for d in args.data]
    found += [(f"file {f} of DATA {d}", f) for d, e in zip(args.data, exps) for f in e.files]
    return tuple(found + ([(f"--params {args.params}", args.params)] if args.params else []))


def _terms(model: list) -> str:
    return "--terms " + ",".join(t.name for t in model)


def enough_data(exps: list, model: list, fixed: list[str] | None = None) -> None:
    """:func:`~fabricsurf.inverse.fitting.preconditions.enough_data`, naming the options."""
    pre.enough_data(
        exps,
        model,
        fixed,
        _terms(model),
        " (fewer --terms, or --fixed)" if fixed is not None else " (fewer --terms)",
    )


def positive_start(model, args, command: str = "fit") -> None:
    """:func:`~fabricsurf.inverse.fitting.preconditions.positive_start` (and ``no_signed``)
    of every modulus of --terms, naming the options."""
    pre.positive_start(model, f"--params {args.params}", command, _terms(model))


def number_list(spec: str, option: str, cast: type, what: str):
    """``spec`` split at commas and converted by ``cast``; a bad item names the option."""
    try:
        return [cast(s) for s in spec.split(",")]
    except ValueError:
        raise InputError(f"{option} {spec}: expected comma-separated {what}") from None


def error_map_steps(spec: str | None, exps: list) -> list[int] | None:
    if spec is None:
        return None
    steps = number_list(spec, "--steps", int, "step numbers, e.g. 1,3")
    for e in exps:
        bad = [s for s in steps if s not in set(int(k) for k in e.steps)]
        if bad:
            raise InputError(
                f"--steps {spec}: step {bad[0]} is not a step of experiment "
                f"'{e.name}' (steps {int(e.steps[0])}..{int(e.steps[-1])})"
            )
    return steps


def name_list(spec: str | None) -> list[str] | None:
    return None if spec is None else [n.strip() for n in spec.split(",") if n.strip()]


def grip_depths(spec: str | None, exps: list) -> list[float] | None:
    """``--grip-depths``: comma-separated depths in mm, checked against the experiments."""
    if spec is None:
        return None
    from fabricsurf.inverse.diagnosis.nuisance import check_depths

    depths = number_list(spec, "--grip-depths", float, "depths in mm, e.g. 0,0.5,1")
    try:
        check_depths(exps, depths, f"--grip-depths {spec}")
    except ValueError as e:
        raise InputError(str(e)) from None
    return depths


def diagnose_options(
    args, exps: list, model: list, params: dict
) -> tuple[list[str] | None, list[str] | None]:
    """--candidates, --fixed, --confirm and --max-effects, checked against the vocabulary, the
    baseline (--terms), the data and --params (:mod:`~fabricsurf.inverse.diagnosis.choices`,
    the library's own checks, worded with the options' names)."""
    from fabricsurf.inverse.diagnosis.choices import Labels, check_choices
    from fabricsurf.inverse.diagnosis.diagnose import check_unsigned, visible_effects

    baseline = [t.name for t in model]
    cands, fixed = name_list(args.candidates), name_list(args.fixed)
    labels = Labels(
        candidates=f"--candidates {args.candidates}",
        fixed=f"--fixed {args.fixed}",
        baseline=f"--terms {','.join(baseline)}",
        params="--params",
        params_where=(f"in --params {args.params}" if args.params else "(no --params file)"),
        confirm="--confirm",
        max_effects="--max-effects",
    )
    check_choices(
        baseline,
        cands,
        fixed,
        params,
        visible_effects(exps),
        args.confirm,
        args.max_effects,
        labels,
    )
    try:
        check_unsigned(cands or [])
    except ValueError as e:
        raise InputError(f"--candidates {args.candidates}: {e}") from None
    pre.planar_candidates(exps, cands, "--candidates")
    return cands, fixed


def defaulted_moduli(model: list, params: dict) -> list[str]:
    """The moduli of ``model`` that ``params`` (the --params file's) does not give, each as
    "term.param = value unit": they take the term's default."""
    return [
        f"{t.name}.{p} = {v:g} {t.units.get(p, '')}".rstrip()
        for t in model
        for p, v in t.values().items()
        if p not in params.get(t.name, {})
    ]


def compare_moduli(args, model: list, params: dict) -> str | None:
    """``compare`` compares a model whose every modulus was chosen. With a --params file, a
    modulus of --terms it does not give is refused (it would be compared at the term's default,
    1.0, which is nobody's estimate: a wrong answer without a word); without --params every
    modulus is the default, and the note returned says so (printed once the run starts)."""
    missing = defaulted_moduli(model, params)
    if not missing:
        return None
    if args.params is None:
        return (
            "note: no --params given: every modulus takes its default ("
            + ", ".join(missing)
            + "); give a --params file to compare your own moduli"
        )
    terms = ",".join(t.name for t in model)
    raise InputError(
        f"--params {args.params}: gives no value for "
        f"{', '.join(m.split(' = ')[0] for m in missing)} of --terms {terms}, so "
        f"compare would use the default{'s' * (len(missing) > 1)} "
        f"({', '.join(missing)}), nobody's estimate; add "
        f"{'them' if len(missing) > 1 else 'it'} to {args.params}, or drop the "
        "term from --terms (a saved fit: leave --terms out to compare the fit's "
        "own model)"
    )
