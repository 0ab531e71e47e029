"""A library of energy features beyond the vocabulary (docs/diagnosis.md, "Beyond the
vocabulary").

When the named effects leave an excess misfit, :mod:`.beyond` searches these. Each feature is an
energy density built from the sheet's kinematic quantities (products and powers of γ, λ − 1,
μ − 1, the shear angle's gradients along the fibres, the curvatures where 3D data exist) with one
modulus k ≥ 0 in which it is linear, so the diagnosis's exact sensitivities, linearised scores
and refits apply unchanged. A sign-indefinite form comes as two features, ``_plus`` and
``_minus`` (the diagnosis scores moduli ≥ 0). Where a named term of the fitted model can carry
the other sign, the pair is two unsigned forms instead: ½k·min(λ−1,0)² (yarns stiffer in
compression) and ½k·max(λ−1,0)² (stiffer in tension, i.e. softer in compression, with
``fibre_stretch`` carrying the compressive stiffness). They span the same energies as
±½k·min(λ−1,0)², but no modulus ≥ 0 makes the fibres' compressive stiffness negative: measured,
the refit of −½k·min(λ−1,0)² on null data crept to k = k_l (unstable fibres, 150–200 s of
failing load steps), that of ½k·max(λ−1,0)² stopped in 11 s. Each feature has a reason why a
fabric could have it.

Every feature is a :class:`~fabricsurf.model.term.Term` subclass made by executing the source
text a user would paste into a module of their own (:attr:`FeatureSpec.source`): the class the
search fits *is* that text, so what it reports is exactly what the user gets.

A feature is beyond the vocabulary only if no named effect has its form. :func:`library` leaves
out every feature whose density, on the random kinematic states of the linearity check
(:mod:`fabricsurf.model.user_effects`), lies in the span of the registered effects'
per-modulus densities (built-ins and a user's): ``shear_quartic`` is ``shear_locking``'s k₄ and
the warp/weft imbalance ½k[(λ−1)² − (μ−1)²] is ``fibre_stretch`` with k_l ≠ k_m, so both are
excluded; a user's registered shear–tension term excludes ``shear_tension_*``.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

import numpy as np

from fabricsurf.inverse.diagnosis.beyond.catalogue import SPECS
from fabricsurf.inverse.diagnosis.beyond.spec import FeatureSpec
from fabricsurf.model.term import Term
from fabricsurf.model.terms import EFFECTS

ORIGIN = "fabricsurf search beyond the vocabulary"
"""The registry origin of a feature while a search has it registered (:func:`registered`)."""
DUPLICATE_RTOL = 1e-6
"""A feature duplicates the vocabulary when its density's least-squares residual on the span of
the named effects' per-modulus densities is below this fraction of its norm (round-off of a
few operations per state; a distinct form leaves O(1))."""


@functools.lru_cache(maxsize=None)
def feature_class(spec: FeatureSpec) -> type[Term]:
    """The Term subclass of ``spec``: its :attr:`~FeatureSpec.source` executed (importable
    under this module's name, so a term of it pickles)."""
    namespace = {"__name__": __name__}
    exec(compile(spec.source, f"<feature {spec.name}>", "exec", dont_inherit=True), namespace)
    cls = namespace[spec.class_name]
    globals()[spec.class_name] = cls
    return cls


def _density_columns(cls: type[Term]) -> np.ndarray:
    """The density of each modulus of ``cls`` alone (= 1, others 0) on the linearity check's
    random kinematic states: one column per modulus (an adapter to the evaluator of
    :mod:`fabricsurf.model.user_effects`, private there)."""
    from fabricsurf.model.user_effects import density_evaluator

    w = density_evaluator(cls())
    names = cls.parameters()
    return np.column_stack([w({q: float(q == p) for q in names}) for p in names])


@functools.lru_cache(maxsize=None)
def _named_basis(named: tuple[tuple[str, type[Term]], ...]) -> tuple[np.ndarray, list[str]]:
    """The named effects' per-modulus densities, columns scaled to unit norm, and the effect
    of each column."""
    cols, owners = [], []
    for name, cls in named:
        c = _density_columns(cls)
        cols.append(c / np.maximum(np.linalg.norm(c, axis=0), 1e-300))
        owners += [name] * c.shape[1]
    return np.column_stack(cols), owners


def duplicated_by(spec: FeatureSpec) -> list[str]:
    """The named effects whose forms together give ``spec``'s density (empty: none has it)."""
    named = tuple((n, c) for n, c in EFFECTS.items() if EFFECTS.origin(n) != ORIGIN)
    B, owners = _named_basis(named)
    w = _density_columns(feature_class(spec))[:, 0]
    coef, *_ = np.linalg.lstsq(B, w, rcond=None)
    if np.linalg.norm(B @ coef - w) > DUPLICATE_RTOL * np.linalg.norm(w):
        return []
    big = np.abs(coef) > 1e-3 * np.abs(coef).max()
    return list(dict.fromkeys(o for o, b in zip(owners, big) if b))


def library(three_d: bool = False) -> tuple[list[FeatureSpec], list[dict]]:
    """(features, excluded): the features the data can see (curvature features only with
    ``three_d`` data) that no named effect duplicates, and every other feature with why not."""
    kept, excluded = [], []
    for spec in SPECS:
        if not (spec.in_plane or three_d):
            excluded.append(
                {"feature": spec.name, "reason": "planar (2D) data cannot see out-of-plane effects"}
            )
        elif spec.name in EFFECTS and EFFECTS.origin(spec.name) != ORIGIN:
            excluded.append(
                {
                    "feature": spec.name,
                    "reason": f"its name is taken by the effect from {EFFECTS.origin(spec.name)}",
                }
            )
        elif dup := duplicated_by(spec):
            excluded.append(
                {
                    "feature": spec.name,
                    "reason": "a named effect has this form: " + " + ".join(dup),
                    "duplicates": dup,
                }
            )
        else:
            kept.append(spec)
    return kept, excluded


@contextlib.contextmanager
def registered(specs: list[FeatureSpec]) -> Iterator[dict[str, type[Term]]]:
    """The features' classes in :data:`~fabricsurf.model.terms.EFFECTS` for a ``with`` block
    (the forward model accepts only registered effects), unregistered at its end. Registered
    without the user-effect checks: they are linear by construction
    (tests/test_beyond_vocabulary.py checks every one)."""
    done = []
    try:
        for spec in specs:
            done.append(EFFECTS.register(feature_class(spec), ORIGIN).name)
        yield {n: EFFECTS[n] for n in done}
    finally:
        for name in done:
            EFFECTS.unregister(name)


def spec_of(name: str) -> FeatureSpec:
    """The feature called ``name``."""
    return next(s for s in SPECS if s.name == name)
