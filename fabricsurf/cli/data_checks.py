"""Checks of the tests and terms of ``compare|fit|diagnose`` against the data, before any
computation: tests (or kinds of data) that are not yet in the comparison loop, effects a
planar experiment cannot carry, a cantilever without bending stiffness. Each message names the
key or option and the remedy."""

from __future__ import annotations

from fabricsurf.errors import InputError

NOT_IN_LOOP: dict[str, str] = {}
"""Tests that have a plug-in but are not yet compared with measurements, and why (none now:
the hemisphere's punch force and shear angles are in the loop, docs/forming.md)."""

FIELD_NOT_IN_LOOP = {"hemisphere": "a displacement field of a formed part is not yet compared "
                                   "(its points would need mapping onto the solved quarter with "
                                   "the mirrored components); compare the punch force "
                                   "(force.csv) and the shear angles at points (shear.csv, "
                                   "docs/contracts.md)"}
"""Tests whose forward model takes their force (and shear) data but not a displacement field."""


def check_in_loop(exps: list, data: list) -> None:
    """Refuse data of a test (or a kind of data of a test) the comparison does not support yet,
    naming the key."""
    for e, d in zip(exps, data):
        why = NOT_IN_LOOP.get(e.test)
        if why:
            raise InputError(f"{d}/experiment.toml: [loading] test = \"{e.test}\": {why}")
        why = FIELD_NOT_IN_LOOP.get(e.test) if e.has_field else None
        if why:
            raise InputError(f"{d}/experiment.toml: [data] field with [loading] test = "
                             f"\"{e.test}\": {why}")
        if e.test == "hemisphere":
            _stroke_within_reach(e, d)


def _stroke_within_reach(e, d) -> None:
    """A measured stroke the die and blank cannot allow is refused before the forward model
    follows it into a Newton failure (forming_blank.check_stroke)."""
    from fabricsurf.errors import DataError
    from fabricsurf.experiments import forming_blank

    i = int(max(range(len(e.path)), key=lambda j: e.path[j]))
    try:
        forming_blank.check_stroke(e.setup, float(e.path[i]))
    except DataError as err:
        raise InputError(f"{d}: step {int(e.steps[i])}: {err}") from None


BENDS = {"cantilever": "cantilever", "hemisphere": "hemisphere forming (the sheet bends over "
                                                  "the punch and the die's lip)"}
"""Tests whose answer needs a bending stiffness: a second-gradient term."""


def check_terms_fit_data(exps: list, model: list, spec: str) -> None:
    """Terms the data cannot carry, refused by name before any computation: an out-of-plane
    effect (normal bending, twist) on a planar test has no meaning there (it needs a placement
    in 3D), and a cantilever or a formed sheet without a second-gradient term has no bending
    stiffness."""
    from fabricsurf.experiments import get_test

    for e in exps:
        planar = get_test(e.test).d == 2
        out_of_plane = [t.name for t in model if not t.in_plane]
        if planar and out_of_plane:
            raise InputError(f"--terms {spec}: {', '.join(out_of_plane)} is an out-of-plane "
                             f"effect, and experiment '{e.name}' (test '{e.test}') is planar: "
                             "it has no out-of-plane placement, so its data cannot identify "
                             "it; remove it from --terms (or use out-of-plane data alone, "
                             "e.g. a cantilever)")
        if e.test in BENDS and not any(t.order == 2 for t in model):
            raise InputError(f"--terms {spec}: experiment '{e.name}' is a {BENDS[e.test]}, "
                             "and no term has a second gradient, so the sheet would have no "
                             "bending stiffness at all (its tangent is singular); add "
                             "normal_bending (and twist)")


def planar_candidates(exps: list, cands: list[str] | None) -> None:
    """Planar and out-of-plane data together: an out-of-plane candidate (by default every
    effect some data can see) would enter the planar experiments' models too, where it has no
    meaning; refused, naming the remedy."""
    from fabricsurf.experiments import get_test
    from fabricsurf.inverse.fitting.diagnose import visible_effects
    from fabricsurf.model.terms import in_plane_invisible

    planar = [e.name for e in exps if get_test(e.test).d == 2]
    pool = cands if cands is not None else visible_effects(exps)
    out_of_plane = [c for c in pool if c in in_plane_invisible()]
    if planar and len(planar) < len(exps) and out_of_plane:  # all planar: they cannot see it
        option = "--candidates " + ",".join(cands) if cands is not None else (
            "no --candidates given: the default candidates include")
        raise InputError(f"{option}: {', '.join(out_of_plane)} cannot be tried on planar "
                         f"experiment '{planar[0]}' (out-of-plane effects need a placement in "
                         "3D); diagnose planar and out-of-plane data apart, or give "
                         "--candidates without them")
