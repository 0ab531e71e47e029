"""The questions a diagnosis may be asked, checked in one place for the library and the command
line: the effects to try (``candidates``), the baseline terms held at known moduli (``fixed``)
and the round counts. No combination may silently answer another question (docs/diagnosis.md).

The messages name each choice as the caller spells it (:class:`Labels`): ``--fixed shear`` on
the command line, ``fixed ['shear']`` in :func:`~fabricsurf.inverse.diagnosis.diagnose.diagnose`.
"""

from __future__ import annotations

from dataclasses import dataclass

from fabricsurf.errors import InputError
from fabricsurf.model.terms import EFFECTS


@dataclass(frozen=True)
class Labels:
    """How the messages name the choices: ``candidates``, ``fixed`` and ``baseline`` as given,
    ``params`` where known moduli come from and ``params_where`` where they were looked for,
    ``confirm`` and ``max_effects`` the round counts' names."""

    candidates: str
    fixed: str
    baseline: str
    params: str = "params"
    params_where: str = "in params"
    confirm: str = "confirm"
    max_effects: str = "max_effects"


def library_labels(
    baseline: list[str], candidates: list[str] | None, fixed: list[str] | None
) -> Labels:
    """The names of :func:`~fabricsurf.inverse.diagnosis.diagnose.diagnose`'s arguments."""
    return Labels(f"candidates {candidates}", f"fixed {fixed}", f"baseline {baseline}")


def check_rounds(confirm: int, max_effects: int, labels: Labels) -> None:
    """At least one candidate confirmed per round; a non-negative number of effects added."""
    if confirm < 1:
        raise InputError(f"{labels.confirm} {confirm}: must be at least 1")
    if max_effects < 0:
        raise InputError(f"{labels.max_effects} {max_effects}: must be at least 0")


def check_names(names: list[str] | None, label: str) -> None:
    """A list of effects: not empty, each in the vocabulary, none twice."""
    if names is None:
        return
    if not names:
        raise InputError(f"{label}: names no effect")
    bad = [n for n in names if n not in EFFECTS]
    if bad:
        raise InputError(f"{label}: unknown term '{bad[0]}'; valid terms are: {', '.join(EFFECTS)}")
    dup = [n for n in names if names.count(n) > 1]
    if dup:
        raise InputError(f"{label}: '{dup[0]}' is given twice")


def check_fixed(fixed: list[str] | None, baseline: list[str], params: dict, labels: Labels) -> None:
    """Fixed terms are baseline terms with every modulus given, and leave one term free."""
    if fixed is None:
        return
    outside = [n for n in fixed if n not in baseline]
    if outside:
        raise InputError(
            f"{labels.fixed}: '{outside[0]}' is not a baseline term "
            f"({labels.baseline}); only baseline terms can be held fixed"
        )
    if set(fixed) == set(baseline):
        raise InputError(
            f"{labels.fixed}: every baseline term ({labels.baseline}) is fixed, so "
            "the baseline has no modulus to fit; leave at least one free "
            "(compare evaluates a model with given moduli)"
        )
    missing = [
        f"{n}.{p}" for n in fixed for p in EFFECTS[n].parameters() if p not in params.get(n, {})
    ]
    if missing:
        raise InputError(
            f"{labels.fixed}: a fixed term is held at its moduli from "
            f"{labels.params}, and {', '.join(missing)} is not given "
            f"{labels.params_where}; give the known moduli of every fixed term"
        )


def check_candidates(
    candidates: list[str] | None, baseline: list[str], visible: list[str], labels: Labels
) -> None:
    """Candidates the data can see (``visible``), not all of them in the baseline."""
    if candidates is None:
        return
    hidden = [c for c in candidates if c not in visible]
    if hidden:
        raise InputError(
            f"{labels.candidates}: these data cannot see {', '.join(hidden)} "
            "(planar data cannot see out-of-plane effects)"
        )
    if all(c in baseline for c in candidates):
        raise InputError(
            f"{labels.candidates}: every candidate is already in the baseline "
            f"({labels.baseline}), so nothing would be tested; name effects "
            "that are not in the baseline"
        )


def check_choices(
    baseline: list[str],
    candidates: list[str] | None,
    fixed: list[str] | None,
    params: dict,
    visible: list[str],
    confirm: int,
    max_effects: int,
    labels: Labels,
) -> None:
    """Every check above, in the order a user reads the options."""
    check_rounds(confirm, max_effects, labels)
    check_names(baseline, labels.baseline)
    check_names(candidates, labels.candidates)
    check_names(fixed, labels.fixed)
    check_fixed(fixed, baseline, params, labels)
    check_candidates(candidates, baseline, visible, labels)
