"""Checks of the command-line options of ``fabricsurf compare|fit|diagnose|bias``, against
each other and against the data, made before any computation: every message names the option.
The mesh sizes' (``--h``, ``--max-elements``, the mesh selection's budget) are in
:mod:`~fabricsurf.cli.mesh_options`.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from fabricsurf.cli.mesh_options import check_size
from fabricsurf.errors import InputError
from fabricsurf.inverse.fitting import preconditions as pre


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


def option_labels(args, terms: list[str], **more):
    """The choices' :class:`~fabricsurf.inverse.diagnosis.choices.Labels` named as the command
    line's options: --fixed, --terms, --params, and ``more``."""
    from fabricsurf.inverse.diagnosis.choices import Labels

    return Labels(
        fixed=f"--fixed {args.fixed}",
        baseline=f"--terms {','.join(terms)}",
        params="--params",
        params_where=(f"in --params {args.params}" if args.params else "(no --params file)"),
        **more,
    )


def fixed_terms(args, model: list, params: dict) -> list[str] | None:
    """``--fixed`` of fit: terms of --terms held at their --params moduli, checked as the
    diagnosis checks its own (:func:`~fabricsurf.inverse.diagnosis.choices.check_fixed`)."""
    from fabricsurf.inverse.diagnosis.choices import check_fixed, check_names

    fixed = name_list(args.fixed)
    terms = [t.name for t in model]
    labels = option_labels(args, terms, candidates="")
    check_names(fixed, labels.fixed)
    check_fixed(fixed, terms, params, labels)
    return fixed


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
    """--candidates, --fixed, --confirm, --max-effects and --beyond-features, checked against
    the vocabulary, the baseline (--terms), the data and --params
    (:mod:`~fabricsurf.inverse.diagnosis.choices`, the library's own checks, worded with the
    options' names)."""
    from fabricsurf.inverse.diagnosis.choices import check_choices
    from fabricsurf.inverse.diagnosis.diagnose import check_unsigned, visible_effects

    if args.beyond_features < 0:
        raise InputError(
            f"--beyond-features {args.beyond_features}: give 0 (no search beyond the "
            "vocabulary) or the most features the search may add"
        )
    baseline = [t.name for t in model]
    cands, fixed = name_list(args.candidates), name_list(args.fixed)
    labels = option_labels(
        args,
        baseline,
        candidates=f"--candidates {args.candidates}",
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


def check_bias_options(args) -> float:
    """Every option of ``bias`` against the others, before any computation (messages name
    them); the final grip displacement (``--ubar``, default a quarter of ``--length``)."""
    for option, v in (
        ("--length", args.length),
        ("--width", args.width),
        ("--h", args.h),
        ("--ubar", args.ubar),
    ):
        if v is not None and not math.isfinite(v):
            raise InputError(f"{option} {v}: must be a finite number (mm)")
    if not (args.length > 0 and args.width > 0):
        raise InputError(f"--length {args.length}, --width {args.width}: must be positive (mm)")
    if args.width > args.length:
        raise InputError(
            f"--width {args.width:g} exceeds --length {args.length:g}: the bias "
            "specimen has its long side along the load (x); swap them"
        )
    if not 0 < args.h <= 0.5 * min(args.length, args.width):
        raise InputError(
            f"--h {args.h}: must lie in (0, {0.5 * min(args.length, args.width):g}]"
            " mm (at least two elements across the width)"
        )
    check_size(args.h, [("specimen", args.length, args.width)], args.max_elements)
    if not 1 <= args.steps <= 1000:
        raise InputError(f"--steps {args.steps}: must lie in [1, 1000]")
    ubar = 0.25 * args.length if args.ubar is None else args.ubar
    if not 0 < ubar < args.length:
        raise InputError(f"--ubar {ubar}: must lie in (0, {args.length:g}) mm")
    return ubar
