"""What a fit or a diagnosis refuses before any computation, checked in one place for the
library (:func:`~fabricsurf.inverse.fitting.fit.fit`,
:func:`~fabricsurf.inverse.diagnosis.diagnose.diagnose`) and the command line: zero starting
moduli (the fit steps in log-moduli) and signed moduli in a diagnosis, more moduli than data
(under-determined), tests or kinds of data not yet in the comparison loop, and terms the data
cannot carry (out-of-plane effects on planar data, a bending test without bending stiffness).

The messages name each input as the caller spells it: ``terms`` (``--terms a,b`` on the command
line, ``terms ['a', 'b']`` in the library), ``params`` (``--params FILE`` or ``params``) and
the remedy's names (``remedy``); every error is an :class:`~fabricsurf.errors.InputError`.
"""

from __future__ import annotations

from pathlib import Path

from fabricsurf.errors import DataError, InputError
from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.model.terms import EFFECTS, in_plane_invisible

NOT_IN_LOOP: dict[str, str] = {}
"""Tests that have a plug-in but are not yet compared with measurements, and why (none now:
the hemisphere's punch force and shear angles are in the loop, docs/forming.md)."""


def terms_label(model: list) -> str:
    """How the library names a model's terms in a message."""
    return f"terms {[t.name for t in model]}"


def positive_moduli(
    names: list[str],
    values,
    signed: list[str],
    params: str = "params",
    command: str = "fit",
    terms: str = "terms",
) -> None:
    """A starting modulus ``values`` ≤ 0 cannot move in log scale, where fit and diagnose step
    the moduli ≥ 0; ``signed`` (moduli that may be negative, a term's ``signed``) are refused
    where they cannot be taken: the diagnosis scores its candidates at modulus 0 and scans
    by decades (a fit steps them linearly instead, and checks the fitted energy's stability:
    :mod:`.stability_check`). ``params``: where the moduli came from; ``terms``: the terms as
    the caller names them."""
    if signed:
        raise InputError(
            f"{terms}: {', '.join(signed)} "
            f"may be negative (signed), and {command} works with moduli ≥ 0 (it scores "
            "candidates at modulus 0 and scans by decades); fit signed moduli with fit, "
            "or compare them (docs/usage.md, 'Adding your own effect')"
        )
    for n, v in zip(names, values):
        if v <= 0:
            raise InputError(
                f"{params}: {n} = {v:g}: fit and "
                "diagnose start from these moduli in log scale; give a "
                "positive starting value"
            )


def positive_start(
    model: list, params: str = "params", command: str = "fit", terms: str | None = None
) -> None:
    """:func:`positive_moduli` of every modulus of ``model``: a signed modulus may start
    anywhere in a fit (it steps linearly), and is refused by any other ``command``."""
    pairs = [(t, p, v) for t in model for p, v in t.values().items()]
    signed = [(t, p, v) for t, p, v in pairs if p in getattr(t, "signed", ())]
    unsigned = [(t, p, v) for t, p, v in pairs if p not in getattr(t, "signed", ())]
    positive_moduli(
        [f"{t.name}.{p}" for t, p, _ in unsigned],
        [v for *_, v in unsigned],
        [] if command == "fit" else [f"{t.name}.{p}" for t, p, _ in signed],
        params,
        command,
        terms or terms_label(model),
    )


def enough_data(
    exps: list,
    model: list,
    fixed: list[str] | None = None,
    terms: str | None = None,
    remedy: str | None = None,
) -> None:
    """Refuse a fit of more moduli than there are data (under-determined: its ± would be
    meaningless). Data: every force value, every field row times the components the test
    compares, and every measured shear angle. The moduli fitted: those of the terms of
    ``model`` not in ``fixed``; ``remedy``: how to fit fewer (default: the library's names)."""

    free = [f"{t.name}.{p}" for t in model if t.name not in (fixed or []) for p in t.values()]
    counts, n = [], 0
    for e in exps:
        nf = len(e.force) if e.has_force else 0
        comps = min(get_test(e.test).d, e.u.shape[1])
        nu = len(e.X) * comps if e.has_field else 0
        ns = len(e.shear) if e.has_shear else 0
        n += nf + nu + ns
        rows = len(e.X)
        counts.append(
            f"'{e.name}': "
            + ", ".join(
                ([f"{nf} force value{'s' * (nf != 1)}"] if e.has_force else [])
                + (
                    [f"{rows} field row{'s' * (rows != 1)} x {comps} components"]
                    if e.has_field
                    else []
                )
                + ([f"{ns} shear angle{'s' * (ns != 1)}"] if e.has_shear else [])
            )
        )
    if n < len(free):
        if remedy is None:
            remedy = " (fewer terms, or fixed)" if fixed is not None else " (fewer terms)"
        raise InputError(
            f"{terms or terms_label(model)}: {len(free)} moduli to fit "
            f"({', '.join(free)}) from {n} measured value{'s' * (n != 1)} "
            f"({'; '.join(counts)}): fewer data than moduli, the fit is "
            "under-determined; give more data (load steps, field points) or fit "
            "fewer moduli" + remedy
        )


def _origin(e) -> str:
    """Where an experiment came from, for a message: its directory, else its name."""
    return str(Path(e.files[0]).parent) if e.files else f"experiment '{e.name}'"


def check_in_loop(exps: list, data: list | None = None) -> None:
    """Refuse data of a test (or a kind of data of a test) the comparison does not support yet,
    naming the key; ``data``: the experiments' directories (default: where they were read)."""
    for e, d in zip(exps, data if data is not None else [_origin(e) for e in exps]):
        why = NOT_IN_LOOP.get(e.test)
        if why:
            raise InputError(f'{d}/experiment.toml: [loading] test = "{e.test}": {why}')
        plugin = get_test(e.test)
        why = plugin.field_not_compared if e.has_field else None
        if why:
            raise InputError(
                f'{d}/experiment.toml: [data] field with [loading] test = "{e.test}": {why}'
            )
        try:
            plugin.check_data(e.setup, e.steps, e.path, d)
        except DataError as err:
            raise InputError(str(err)) from None


def check_terms_fit_data(
    exps: list, model: list, spec: str | None = None, option: str = "--terms"
) -> None:
    """Terms the data cannot carry, refused by name before any computation: an out-of-plane
    effect (normal bending, twist) on a planar test has no meaning there (it needs a placement
    in 3D), and a cantilever or a formed sheet without a second-gradient term has no bending
    stiffness. ``spec``: the terms as given on the command line (``--terms spec``); without
    it the library's ``terms [...]``."""

    label = f"{option} {spec}" if spec is not None else terms_label(model)
    where = option if spec is not None else "the terms"
    for e in exps:
        planar = get_test(e.test).d == 2
        out_of_plane = [t.name for t in model if not t.in_plane]
        if planar and out_of_plane:
            raise InputError(
                f"{label}: {', '.join(out_of_plane)} is an out-of-plane "
                f"effect, and experiment '{e.name}' (test '{e.test}') is planar: "
                "it has no out-of-plane placement, so its data cannot identify "
                f"it; remove it from {where} (or use out-of-plane data alone, "
                "e.g. a cantilever)"
            )
        bends = get_test(e.test).bends
        if bends and not any(t.order == 2 for t in model):
            raise InputError(
                f"{label}: experiment '{e.name}' is a {bends}, "
                "and no term has a second gradient, so the sheet would have no "
                "bending stiffness at all (its tangent is singular); add "
                "normal_bending (and twist)"
            )


def planar_candidates(exps: list, cands: list[str] | None, option: str = "candidates") -> None:
    """Planar and out-of-plane data together: an out-of-plane candidate (by default every
    effect some data can see) would enter the planar experiments' models too, where it has no
    meaning; refused, naming the remedy. ``option``: the candidates' name (``--candidates``)."""

    planar = [e.name for e in exps if get_test(e.test).d == 2]
    pool = cands if cands is not None else visible_effects(exps)
    out_of_plane = [c for c in pool if c in in_plane_invisible()]
    if planar and len(planar) < len(exps) and out_of_plane:  # all planar: they cannot see it
        given = (
            f"{option} " + ",".join(cands)
            if cands is not None
            else (f"no {option} given: the default candidates include")
        )
        raise InputError(
            f"{given}: {', '.join(out_of_plane)} cannot be tried on planar "
            f"experiment '{planar[0]}' (out-of-plane effects need a placement in "
            "3D); diagnose planar and out-of-plane data apart, or give "
            f"{option} without them"
        )


def fit_preconditions(
    exps: list,
    model: list,
    fixed: list[str] | None = None,
    command: str = "fit",
    start: list | None = None,
) -> None:
    """Every check above, in the command line's order, for a fit of ``model`` (its terms not
    in ``fixed``) to ``exps``, as the library names its arguments (the command line calls
    each with its options' names); ``start``: the terms whose starting moduli are checked
    (default: all of ``model``)."""
    check_in_loop(exps)
    check_terms_fit_data(exps, model)
    positive_start(model if start is None else start, "params", command, terms_label(model))
    enough_data(exps, model, fixed)


def visible_effects(exps: list[Experiment]) -> list[str]:
    """The vocabulary effects these data can see: out-of-plane ones only with 3D data (a 3D
    field, or the force and shear angles of a test solved in 3D: a formed part). The
    vocabulary is the registry :data:`EFFECTS`: a user's registered effect is seen (and is a
    candidate by default) like a built-in, unless it has signed moduli."""
    three_d = any(get_test(e.test).d == 3 and (not e.has_field or e.u.shape[1] == 3) for e in exps)
    return [n for n in EFFECTS if three_d or EFFECTS[n].in_plane]


SIGNED_REASON = (
    "a modulus that may be negative (signed): not a candidate, the diagnosis "
    "scores and fits moduli ≥ 0"
)
"""Why an effect with a signed modulus is not among the candidates."""


def check_unsigned(names: list[str]) -> None:
    """Refuse effects with signed moduli in a diagnosis (baseline or named candidates): its
    scores, refits and log-scale baseline fit take moduli ≥ 0. They are left out of the
    default candidates (and reported as not tried, :data:`SIGNED_REASON`)."""
    bad = [n for n in names if n in EFFECTS and EFFECTS[n].signed]
    if bad:
        raise ValueError(
            f"diagnose: {', '.join(bad)} has moduli that may be negative "
            f"({', '.join(f'{n}.{p}' for n in bad for p in EFFECTS[n].signed)}); "
            "the diagnosis works with moduli ≥ 0, so signed effects can be "
            "compared but not diagnosed yet"
        )


def forward_preconditions(fm, free: list[int], signed) -> None:
    """:func:`fit_preconditions` on the terms of the forward model ``fm`` that take part in a
    fit of the moduli ``free``: those with a free modulus, and those held at a modulus > 0 (a
    diagnosis's candidates at 0 are absent); for a forward model that does not tell its data,
    the free moduli's checks alone. ``signed``: which free moduli may be negative (any start)."""
    exps = getattr(fm, "experiments", None)
    if exps:
        names = {fm.params[k][0].name for k in free}
        model = list({id(t): t for t, _ in fm.params}.values())
        active = [t for t in model if t.name in names or any(v > 0 for v in t.values().values())]
        held = [t.name for t in active if t.name not in names]
        fit_preconditions(
            exps,
            active,
            held or None,  # a held signed modulus is fine
            start=[t for t in active if t.name in names],
        )
    logs = [k for k, s in zip(free, signed) if not s]
    positive_moduli([fm.names[k] for k in logs], fm.values()[logs], [])
