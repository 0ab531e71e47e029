"""A model against measurements at given moduli: :func:`compare` (``fabricsurf compare``).

One forward run per experiment at the model's moduli (one set for all experiments: one
material, several tests), the misfit of each and overall, and, at the moduli of a saved fit
(``band``), the 95 % prediction bands of the force curves and fields
(:func:`~fabricsurf.inverse.fitting.band.force_band`). The inputs are checked first, before
any solve, as the command line checks them (:func:`compare_preconditions`, worded with the
arguments' names where the command line names its options): tests not in the comparison loop,
terms the data cannot carry, moduli left at a term's default by a partial ``params``, moduli
beyond any sheet, an element size the specimens cannot take, experiments of one name, a band
from a file without a covariance. Unlike a fit, compare takes signed (negative) moduli and
moduli of 0. Writing the outputs (misfit.json, figures) is the caller's:
:func:`~fabricsurf.inverse.plots.outputs.write_comparison` and
:func:`~fabricsurf.inverse.plots.comparison_bands.write_band_files`.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.errors import InputError
from fabricsurf.inverse.contract.checks import unloading_warning
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.fitting.band import force_band, has_covariance
from fabricsurf.inverse.fitting.params import MAX_MODULUS
from fabricsurf.inverse.fitting.preconditions import (
    check_in_loop,
    check_terms_fit_data,
    terms_label,
)
from fabricsurf.inverse.fitting.result import strip_rows
from fabricsurf.inverse.fitting.stability_check import explained, fitted_tangent
from fabricsurf.inverse.forward.load_path import Prediction
from fabricsurf.model.stability import TangentCheck


@dataclass
class Comparison:
    """What :func:`compare` found: the model's ``label`` ("a+b"), its ``predictions`` (one per
    experiment, in their order), the ``misfit`` (:meth:`~.runs.ForwardSet.misfit`: combined,
    chi2, n and one entry per experiment, with the per-row errors), the mesh of each experiment
    (``meshes``: h, cells, unknowns, the mesh kind and h used), the discretisation record of
    each plug-in that keeps one (``discretisation``, by experiment name), the bands at a saved
    fit's moduli (``bands``, by experiment name, :func:`~.band.force_band`; None without
    ``band``) and the ``warnings`` about the inputs (a load path that turns back under a term
    valid for monotonic loading only), and for a model with a signed modulus the ``stability``
    of its energy over the states of the predictions (:mod:`.stability_check`; else None)."""

    label: str
    predictions: list[Prediction]
    misfit: dict
    meshes: list[dict]
    discretisation: dict
    bands: dict | None = None
    warnings: tuple[str, ...] = ()
    stability: TangentCheck | None = None

    @property
    def h(self) -> list[float]:
        """The element size of each experiment's mesh (mm)."""
        return [m["h"] for m in self.meshes]

    def band_summary(self) -> dict | None:
        """Per experiment: the force band's half-width per step, whether its linearisation
        holds (``reliable``, ``nonlinearity``) and the largest half-width of the field's band
        (misfit.json's ``force_bands``); None without bands."""
        if self.bands is None:
            return None
        out = {}
        for name, b in self.bands.items():
            field = b["field_half_width"]
            out[name] = {
                "half_width": b["half_width"],
                "reliable": b["reliable"],
                "nonlinearity": b["nonlinearity"],
                "field_half_width_max": None
                if field is None
                else float(np.nanmax(np.asarray(field, float))),
            }
        return out

    def as_dict(self) -> dict:
        """The misfit without its per-row arrays, the model's label and the meshes (with the
        band summary when there are bands): misfit.json's numbers."""
        out = strip_rows(self.misfit) | {"model": self.label, "meshes": self.meshes}
        return out | ({"force_bands": self.band_summary()} if self.bands is not None else {})


def _unit(term, p: str) -> str:
    return term.units.get(p, "")


def _default(term, p: str) -> float:
    """The modulus ``p`` a term of ``term``'s class takes when not given."""
    return next(f.default for f in dataclasses.fields(term) if f.name == p)


def _check_params(model: list, params: dict) -> None:
    """``params`` names terms and moduli of ``model`` only, and gives every modulus of it: a
    modulus left out would be compared at the term's default, nobody's estimate."""
    by_name = {t.name: t for t in model}
    label = terms_label(model)
    for name, vals in params.items():
        if name not in by_name:
            raise InputError(
                f"params: term '{name}' is not in the model ({label}); add it to "
                "the terms or remove it"
            )
        unknown = [p for p in vals if p not in by_name[name].parameters()]
        if unknown:
            raise InputError(
                f"params: term '{name}' has no parameter '{unknown[0]}' (it has "
                f"{', '.join(by_name[name].parameters())})"
            )
    missing = [(t, p) for t in model for p in t.parameters() if p not in params.get(t.name, {})]
    if missing:
        named = ", ".join(f"{t.name}.{p}" for t, p in missing)
        defaults = ", ".join(
            f"{t.name}.{p} = {_default(t, p):g} {_unit(t, p)}".rstrip() for t, p in missing
        )
        them = "them" if len(missing) > 1 else "it"
        raise InputError(
            f"params: gives no value for {named} of {label}, so compare would use "
            f"the default{'s' * (len(missing) > 1)} ({defaults}), nobody's "
            f"estimate; add {them} to params, or drop the term from the terms"
        )


def at_params(model: list, params: dict | None) -> list:
    """Copies of ``model``'s terms at the moduli ``params`` gives (``model`` itself without
    ``params``); the terms handed in are left as they are."""
    if params is None:
        return model
    out = [t.copy() for t in model]
    for t in out:
        try:
            t.set(**params.get(t.name, {}))
        except ValueError as e:
            raise InputError(f"params: {e}") from None
    return out


def _check_moduli(model: list, params: dict | None = None) -> None:
    """Every modulus finite and within :data:`~.params.MAX_MODULUS` (the command line's bound
    on a --params file): beyond it the solver has no digits left for the other moduli. The
    message names ``params`` when the modulus came from there."""
    for t in model:
        for p, v in t.values().items():
            if not math.isfinite(v) or abs(v) > MAX_MODULUS:
                unit = _unit(t, p)
                where = "params" if p in (params or {}).get(t.name, {}) else terms_label(model)
                raise InputError(
                    f"{where}: {t.name}.{p} = {v:.3g} {unit} is beyond any sheet "
                    f"(at most {MAX_MODULUS:.0e} {unit}: a 10 mm steel plate is "
                    "~2e6 N/mm, a near-inextensible fibre penalty ~1e9 N/mm; more "
                    "leaves the solver no digits for the other moduli); check the "
                    "value and its unit (moduli in N/mm and N·mm, lengths in mm)"
                )


def _check_h(exps: list[Experiment], h) -> None:
    """``h`` (one element size, or one per experiment) positive and at most half the narrowest
    specimen side it meshes (two elements across), as ``--h``."""
    if h is None:
        return
    if isinstance(h, (list, tuple)):
        if len(h) != len(exps):
            raise InputError(
                f"h = {list(h)}: one element size per experiment, and there "
                f"are {len(exps)} experiments"
            )
        pairs = [(float(x), [e]) for x, e in zip(h, exps)]
    else:
        pairs = [(float(h), exps)]
    for x, es in pairs:
        limit = 0.5 * min(min(e.length, e.width) for e in es)
        if not (math.isfinite(x) and 0 < x <= limit):
            raise InputError(
                f"h = {x:g}: must be a positive element size in mm, at most "
                f"{limit:g} (two elements across the narrowest specimen)"
            )


def _check_band(model: list, band: dict) -> None:
    """A band needs a saved fit with a covariance, of moduli all in the model."""
    if not has_covariance(band):
        raise InputError(
            "band: the saved fit has no covariance (a fit.json or "
            "model_best.json written by fit or diagnose); without one there is "
            "no band"
        )
    names = {f"{t.name}.{p}" for t in model for p in t.parameters()}
    missing = sorted(set(band["uncertainty"]["covariance"]["names"]) - names)
    if missing:
        raise InputError(
            f"band: the saved fit's moduli {missing} are not in the model "
            f"({terms_label(model)}); a band needs the fitted model's terms"
        )


def records(fs) -> dict:
    """The discretisation record of each experiment's plug-in (the mesh kind, the h it used,
    the fibre treatment), by experiment name; None for a plug-in that keeps none."""
    return {m.exp.name: getattr(m.test, "discretisation", None) for m in fs.models}


def compare_preconditions(
    exps: list[Experiment],
    model: list,
    h=None,
    params: dict | None = None,
    band: dict | None = None,
) -> tuple[str, ...]:
    """Every refusal of ``fabricsurf compare`` that concerns the data, the model and the
    moduli, before any solve (module docstring; every error an
    :class:`~fabricsurf.errors.InputError`). Returns the warnings that do not refuse."""
    if not exps:
        raise InputError("compare: no experiments given")
    names = [e.name for e in exps]
    if len(set(names)) != len(names):
        raise InputError(f"experiments must have distinct names (Experiment.name), got {names}")
    if not model:
        raise InputError("compare: no terms given")
    terms = [t.name for t in model]
    twice = sorted({n for n in terms if terms.count(n) > 1})
    if twice:
        raise InputError(f"{terms_label(model)}: '{twice[0]}' is given twice")
    if params is not None:
        _check_params(model, params)
    model = at_params(model, params)
    _check_moduli(model, params)
    check_in_loop(exps)
    check_terms_fit_data(exps, model)
    _check_h(exps, h)
    if band is not None:
        _check_band(model, band)
    return tuple(w for w in (unloading_warning(e, model) for e in exps) if w)


def compare(
    exps: Experiment | list[Experiment],
    model: list,
    h=None,
    params: dict | None = None,
    band: dict | str | Path | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> Comparison:
    """The misfit of ``model`` against ``exps`` (one set of moduli for all) and its
    predictions, after :func:`compare_preconditions` (module docstring).

    ``h``: the element size (mm), one for all or one per experiment (default: each test's
    own); ``params``: moduli {term: {parameter: value}} to compare at, every modulus of the
    model given (set on copies of its terms: those handed in keep theirs; default: the terms'
    own moduli); ``band``: a saved fit (fit.json or model_best.json, with its covariance: its
    contents, or the file): the 95 % prediction band of each experiment at its moduli is
    computed too (two more forward runs per experiment). Collective over ``comm``."""
    from fabricsurf.inverse.forward.runs import ForwardSet

    exps = exps if isinstance(exps, list) else [exps]
    if isinstance(band, (str, Path)):
        band = json.loads(Path(band).read_text(encoding="utf-8"))
    warnings = compare_preconditions(exps, model, h, params, band)
    model = at_params(model, params)
    with ForwardSet(exps, model, h=h, comm=comm) as fs:
        try:
            preds = fs.run()
        except LoadStepError as e:
            raise explained(fs, e) from None  # a material limit point named as such
        stability = fitted_tangent(fs, run=False)  # at the states of this run
        misfit = fs.misfit(preds)
        meshes = fs.meshes()
        disc = records(fs)
        bands = None if band is None else {m.exp.name: force_band(m, band) for m in fs.models}
    label = "+".join(t.name for t in model)
    return Comparison(label, preds, misfit, meshes, disc, bands, warnings, stability)
