"""The model-form part of a prediction to another specimen size (docs/uncertainty.md).

Effects with a length of their own (second-gradient boundary layers along the zone boundaries
and at the grips, in-plane bending of the fibres) change the force of a specimen by a share that
depends on its size. Fitted on one specimen without them, the moduli absorb what of such an
effect looks like a modulus, right for the calibrating size and wrong for another. No check
inside one data set sees the absorbed part; what one specimen can say is how large each
*candidate size effect* may be without contradicting its curve.

For a candidate term with modulus m (added to the fitted model), the profile over its length
ℓ = √(m/k), k the fitted shear modulus, on the grid ℓ = h/2, h, 2h, … below half the width
(h the mesh: a shorter layer is not resolved, and its force is the mesh's), and two more
lengths towards the end of the interval not excluded (:func:`refine`): at each ℓ the fitted
moduli are refitted on the calibrating data with m held, χ²(ℓ). The data do not exclude
the lengths with

    χ²(ℓ) − χ²_min ≤ F_0.95(1, ν) χ²_min/ν,    ν = n − P − 1

(the profile-likelihood interval of one parameter with the noise level estimated from the
residuals, Bates & Watts 1988 §6.1; χ²_min over ℓ = 0 and the grid). The size part of a
prediction is the largest |F(p_ℓ, m_ℓ) − F(p̂, 0)| over the lengths not excluded (p_ℓ the
refitted moduli), one forward run of the other specimen per length; that of a modulus the
largest |p_ℓ − p̂|. Both are the envelope of a 95 % set, hence 95 % half-widths, combined in
quadrature with the statistical and model-form parts. On the calibrating specimen itself the
part is at most what its own data allow. Coverage on synthetic pairs of sizes:
benchmarks/size_coverage.py.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward import ranks
from fabricsurf.log import detail
from fabricsurf.model.terms import EFFECTS, make_term

SIZE_CANDIDATES = ("geodesic_bending",)
"""The default candidates: the in-plane effect with a length whose boundary layers a planar
force curve sees (shear and stretch gradients are alternatives a caller may add)."""

ALTERNATIVES = ("shear_gradient", "stretch_gradient")
"""Candidates in the order to try when the default ones are fitted terms already."""

METHOD = (
    "profile over the length of each candidate size effect, the lengths the calibrating "
    "data do not exclude transferred to the other size (docs/uncertainty.md)"
)

LEVEL = 0.95

REFINE = 2
"""Secant steps towards the end of the interval not excluded (:func:`refine`)."""

PROFILE_TOL, PROFILE_ITER = 1e-4, 10
"""The profile's refits stop at a relative χ² change of 10⁻⁴ (the allowed rise is F(1, ν)/ν of
χ²_min, above 0.1 for the curves this is for: three decades coarser) or after 10 iterations."""


def default_candidates(fitted_terms) -> tuple[str, ...]:
    """:data:`SIZE_CANDIDATES`, or the first of :data:`ALTERNATIVES` not among the fitted
    terms when they all are."""
    left = [c for c in SIZE_CANDIDATES if c not in fitted_terms]
    return tuple(left) or tuple([c for c in ALTERNATIVES if c not in fitted_terms][:1])


def extended_model(model: list, candidates) -> list:
    """``model`` (fitted terms, their moduli as set) with each candidate not in it added at
    modulus 0, in vocabulary order (the order of the compiled forms of the diagnosis)."""
    have = {t.name for t in model}
    new = []
    for c in candidates:
        if c not in EFFECTS:
            raise ValueError(
                f"size candidates: '{c}' is not in the vocabulary ({', '.join(EFFECTS)})"
            )
        if c not in have:
            t = make_term(c)
            t.set(**{p: 0.0 for p in t.parameters()})
            new.append(t)
    order = list(EFFECTS)
    return sorted([*model, *new], key=lambda t: order.index(t.name))


def lengths(h: float, width: float) -> list[float]:
    """The profile's grid ℓ = h/2, h, 2h, … below half the width (module docstring)."""
    out, ell = [], h / 2
    while ell <= width / 2:
        out.append(ell)
        ell *= 2
    return out


def threshold(chi2_min: float, n: int, p: int) -> float:
    """F_0.95(1, ν) χ²_min/ν with ν = n − p − 1: the χ² rise the data allow (module docstring)."""
    nu = max(n - p - 1, 1)
    return float(stats.f.ppf(LEVEL, 1, nu) * chi2_min / nu)


def _refit_at(
    fm, fit_fn, candidate: str, fitted: list[str], ell: float, k_ref: float, start: np.ndarray
) -> tuple[dict, np.ndarray, int]:
    """The fitted moduli refitted from ``start`` with the candidate held at k_ref ℓ²: its
    profile row, the refitted values and the number of residuals (raises LoadStepError)."""
    vals = start.copy()
    vals[fm.names.index(candidate)] = k_ref * ell**2
    fm.set_values(vals)
    res = fit_fn(fm, [fm.names.index(n) for n in fitted])
    row = {
        "length": ell,
        "value": float(k_ref * ell**2),
        "chi2": float(res.chi2),
        "moduli": {m: float(res.values[fm.names.index(m)]) for m in fitted},
    }
    return row, res.values.copy(), len(res.r)


def profile(
    fm, fit_fn, fitted: list[str], chi2_fit: float, candidate: str, k_ref: float, grid: list[float]
) -> tuple[list[dict], int]:
    """χ² and refitted moduli at each length of ``grid`` for the candidate modulus
    ``candidate`` of ``fm`` (held at k_ref ℓ²), and the number of residuals;
    ``fit_fn(fm, free)`` returns a FitResult. Stops at a length whose run fails or whose χ²
    exceeds ``chi2_fit`` by ten thresholds (the data exclude it and, the effect growing with
    ℓ, every longer one)."""
    base = fm.values()
    rows, start, n = [], base.copy(), 0
    try:
        for ell in grid:
            row, start, n = _refit_at(fm, fit_fn, candidate, fitted, ell, k_ref, start)
            rows.append(row)
            if row["chi2"] > chi2_fit + 10 * threshold(chi2_fit, n, len(fitted)):
                break
    except LoadStepError:
        pass
    fm.set_values(base)
    return rows, n


def refine(
    fm,
    fit_fn,
    fitted: list[str],
    chi2_fit: float,
    candidate: str,
    k_ref: float,
    rows: list[dict],
    level: float,
) -> list[dict]:
    """``rows`` with up to REFINE more lengths at the end of the interval not excluded, where
    the secant of χ²(ℓ) between the longest length with χ² ≤ ``level`` (or the fit itself,
    ℓ = 0) and the next longer one crosses ``level``, or at their midpoint when the secant
    moves less than a tenth of the way (the grid's factor 2 would otherwise leave up to half the
    interval's last length out of the envelope)."""
    base = fm.values()
    zero = {
        "length": 0.0,
        "chi2": chi2_fit,
        "moduli": {m: float(base[fm.names.index(m)]) for m in fitted},
    }
    try:
        for _ in range(REFINE):
            a = max([zero] + [r for r in rows if r["chi2"] <= level], key=lambda r: r["length"])
            beyond = [r for r in rows if r["length"] > a["length"]]
            if a["chi2"] > level or not beyond:
                break
            e = min(beyond, key=lambda r: r["length"])
            gap = e["length"] - a["length"]
            ell = a["length"] + (level - a["chi2"]) / (e["chi2"] - a["chi2"]) * gap
            if ell - a["length"] < 0.1 * gap:  # a steep χ²: the secant barely moves, bisect
                ell = a["length"] + 0.5 * gap
            start = base.copy()
            for m, v in a["moduli"].items():
                start[fm.names.index(m)] = v
            rows.append(_refit_at(fm, fit_fn, candidate, fitted, ell, k_ref, start)[0])
    except LoadStepError:
        pass
    fm.set_values(base)
    return sorted(rows, key=lambda r: r["length"])


def size_record(
    fm,
    fitted: list[str],
    chi2_fit: float,
    h: float,
    width: float,
    candidates=SIZE_CANDIDATES,
    k_ref: float | None = None,
) -> dict:
    """The size part's record for a forward model ``fm`` of the calibrating data whose model
    is :func:`extended_model` at the fitted moduli (as set; ``fitted`` their names, ``chi2_fit``
    their χ²): per candidate its profile and the lengths not excluded (module docstring)."""

    vals = fm.values()
    if k_ref is None and "shear.k_s" not in fm.names:
        raise ValueError(
            "size form: the model has no shear.k_s to scale the candidates' "
            "lengths by; give k_ref (N/mm)"
        )
    k_ref = k_ref or float(vals[fm.names.index("shear.k_s")])

    def fit_fn(f, free):
        with detail():  # a profile's many fits: their iterations are detail (DEBUG)
            return fit(
                f, free, scale_start=False, space="linear", tol=PROFILE_TOL, max_iter=PROFILE_ITER
            )

    if not any(t.name in candidates and f"{t.name}.{p}" not in fitted for t, p in fm.params):
        raise ValueError(
            f"size form: none of the candidates {list(candidates)} is in the "
            "model unfitted (extend it with extended_model; a fitted effect is "
            "no candidate)"
        )
    cands = {}
    for t, p in fm.params:
        name = f"{t.name}.{p}"
        if t.name not in candidates or name in fitted:
            continue
        rows, n = profile(fm, fit_fn, fitted, chi2_fit, name, k_ref, lengths(h, width))
        chi2_min = min([chi2_fit] + [r["chi2"] for r in rows])
        rows = refine(
            fm,
            fit_fn,
            fitted,
            chi2_fit,
            name,
            k_ref,
            rows,
            chi2_min + threshold(chi2_min, n, len(fitted)),
        )
        chi2_min = min([chi2_fit] + [r["chi2"] for r in rows])
        allow = threshold(chi2_min, n, len(fitted))
        for r in rows:
            r["excluded"] = bool(r["chi2"] - chi2_min > allow)
        cands[name] = {
            "profile": rows,
            "residuals": n,
            "chi2_allowed": chi2_min + allow,
            "longest_not_excluded": max(
                [r["length"] for r in rows if not r["excluded"]], default=0.0
            ),
        }
    return {
        "method": METHOD,
        "fitted": list(fitted),
        "chi2_fit": chi2_fit,
        "k_ref": k_ref,
        "candidates": cands,
        "moduli_half_width": moduli_half_width(cands, fm, fitted),
    }


def allowed(record: dict) -> list[tuple[str, dict]]:
    """(candidate, profile row) of every length the data do not exclude."""
    return [
        (c, r) for c, v in record["candidates"].items() for r in v["profile"] if not r["excluded"]
    ]


def moduli_half_width(cands: dict, fm, fitted: list[str]) -> dict:
    """{modulus: max |p_ℓ − p̂|} over the lengths not excluded."""
    vals = fm.values()
    rec = {"candidates": cands}
    return {
        m: max(
            [abs(r["moduli"][m] - vals[fm.names.index(m)]) for _, r in allowed(rec)], default=0.0
        )
        for m in fitted
    }


def band_half_width(fm, record: dict, force: np.ndarray) -> np.ndarray:
    """max |F(p_ℓ, m_ℓ) − F| over the lengths not excluded, at every point of ``fm``'s load
    path (``force``: its prediction at the fitted moduli, the values of ``fm`` as set); one
    forward run per length (shared among the ranks), the values restored."""
    base = fm.values()

    def deviation(item: tuple[str, dict]) -> np.ndarray:
        cand, row = item
        vals = base.copy()
        vals[fm.names.index(cand)] = row["value"]
        for m, v in row["moduli"].items():
            vals[fm.names.index(m)] = v
        fm.set_values(vals)
        return np.abs(fm.run().force - force)

    try:  # the runs shared among the ranks when fm solves rank-local (local.py)
        devs = ranks.spread(fm, allowed(record), deviation)
    finally:
        fm.set_values(base)
    return np.max([np.zeros(len(force)), *devs], axis=0)
