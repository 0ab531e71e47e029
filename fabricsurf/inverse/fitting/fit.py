"""Least-squares fit of the moduli (Levenberg–Marquardt) with tangent sensitivities.

Each iteration is one forward run along the recorded load path that also returns
du/dp = −J⁻¹ ∂R/∂p at every converged step (:class:`~.forward.ForwardModel`): the
converged Jacobian's factorisation is reused, no finite differences of load paths. Two step
variables: log-moduli θ = log p (positive; the step in θ is limited to ±``max_step`` per
iteration), for fits that start decades away; or the moduli themselves, with Marquardt's scaling
(which makes the steps independent of the moduli's units) and the bound p ≥ 0 (a step that would
cross it cuts the modulus by ``BOUND_CUT``), for nested refits that start at an optimum with a
candidate near zero: there log steps crawl (∂χ²/∂θ = p ∂χ²/∂p vanishes at p → 0) and the valley
along which a stiffness trades against another (reactions are linear in the moduli) is straight
in p but curved in θ. The same holds after the scale scan, which leaves every modulus within a
decade of its optimum: the diagnosis fits its baseline in the moduli too (docs/diagnosis.md
compares the two on a stiff-fibre lattice).
In log-moduli a modulus whose optimum is at zero (or beyond it) asks for an ever larger step
down (its column p ∂r/∂p vanishes with p), and the cap on the step then shrinks every other
modulus's step with it: the fit crawls. A modulus that took the whole capped step down
:data:`COLLAPSE` iterations running switches the fit to the moduli themselves, with the bound
p ≥ 0, and says so.
A small relative χ² change does not stop a step that was cut to ``max_step`` (a modulus far
from its optimum, e.g. a candidate effect started near zero, changes χ² little per step); the
fit stops when not even the Gauss–Newton step promises a relative decrease of ``tol`` (at the
optimum every trial step would be rejected, each costing a forward run).
Uncertainties (docs/uncertainty.md; at the optimum, :mod:`~.optimum`): the cluster-robust
sandwich covariance over blocks of residuals (:mod:`~.uncertainty`), the model-form spread
between parts of the data and, after :meth:`FitResult.check_mesh`, the mesh shift
(:mod:`~.systematic`), combined into intervals and identifiable combinations
(:mod:`~.intervals`).
"""

from __future__ import annotations

import logging
from functools import partial

import numpy as np

from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.inverse.fitting.optimum import optimum_result
from fabricsurf.inverse.fitting.plausibility import check_moduli, parse_plausible
from fabricsurf.inverse.fitting.preconditions import forward_preconditions
from fabricsurf.inverse.fitting.result import FitResult, Forward
from fabricsurf.inverse.fitting.stability_check import fitted_tangent
from fabricsurf.inverse.fitting.start import held_terms, scan_terms
from fabricsurf.inverse.fitting.stiff_limit import StiffWatch, hold
from fabricsurf.inverse.forward import linalg as la
from fabricsurf.log import rank0

logger = logging.getLogger(__name__)


def _try(fm: Forward, free: list[int], vals: np.ndarray):
    fm.set_values(vals)
    try:
        pred = fm.run(sens=free)
    except LoadStepError:
        return None, None, np.inf
    r, Jr = fm.residuals(pred)
    if not np.isfinite(r).all():
        return None, None, np.inf
    return pred, (r, Jr), float(r @ r)


def _start(fm: Forward, free: list[int], vals: np.ndarray, first=None):
    """:func:`_try` at the start, where a failure ends the fit: the error names the starting
    moduli, the experiment, the step and the load (and keeps what had converged). ``first``:
    that run, already done by the caller (:func:`fit`)."""
    moduli = ", ".join(f"{fm.names[k]} = {vals[k]:.4g}" for k in free)
    fm.set_values(vals)
    try:
        pred = fm.run(sens=free) if first is None else first
    except LoadStepError as e:
        where = f" of experiment '{e.experiment}'" if e.experiment else ""
        raise e.carrying(
            f"fit: the initial model ({moduli}) does not follow the load path{where}: {e}"
        ) from None
    r, Jr = fm.residuals(pred)
    if not np.isfinite(r).all():
        raise LoadStepError(f"fit: the initial model ({moduli}) gives non-finite residuals")
    return pred, (r, Jr), float(r @ r)


def _scan_checked(fm: Forward, free: list[int], scanned: tuple, given: np.ndarray) -> tuple:
    """The scan's start (values, run, (r, J), χ²), unless the given moduli fit the data
    better on the fit's own mesh: the scout mesh ranks starts wrongly where its discretisation
    error outweighs theirs (a forming run on a mesh coarser than the die's lip, whose punch
    force is not converged, prefers soft yarns). One run more, the given start's."""
    pred, rj, chi2 = _try(fm, free, given)
    if not chi2 < scanned[3]:
        fm.set_values(scanned[0])
        return scanned
    _say(
        fm,
        f"  fit: the given moduli fit better on this mesh than the scanned start (chi2 "
        f"{chi2:.6g} against {scanned[3]:.6g}: the scout mesh ranked them otherwise); "
        "starting from the given moduli",
    )
    return given, pred, rj, chi2


LAMBDA_START = 1e-3
"""Marquardt's damping at the first iteration (a nearly Gauss–Newton step)."""
LAMBDA_DOWN, LAMBDA_UP = 5.0, 8.0
"""The damping divided by LAMBDA_DOWN after an accepted step, multiplied by LAMBDA_UP after a
rejected one (asymmetric, so that a rejected region is left quickly)."""
LAMBDA_MIN, LAMBDA_MAX = 1e-7, 1e8
"""The damping's floor, and the ceiling at which the step search gives up (no decrease)."""
DIAG_FLOOR = 1e-12
"""Marquardt's scaling diag(JᵀJ) plus this fraction of its trace (a modulus with no
sensitivity still gets a bounded step)."""
STALL = 1e-5
"""The fit stops when no modulus (off the bound) moves by more than this in log."""
COLLAPSE = 3
"""Iterations running in which one modulus took the capped log step down (module docstring)."""
BOUND_CUT = 1e-3
"""Linear steps: a modulus the step would make ≤ 0 is cut by this factor instead (a few steps
take it to where it no longer matters: the bound at zero)."""


def _say(fm: Forward, text: str) -> None:
    rank0(logger, fm.comm, text)


def _steps(space: str, vals: np.ndarray, free: list[int], signed: np.ndarray):
    """(dr/dq scaling, update) of the step variable q: θ = log p, or p itself (module
    docstring); a ``signed`` modulus (may be negative) is always p itself, unbounded."""
    if space == "log":
        scale = np.where(signed, 1.0, vals[free])
        return scale, lambda v, s: np.where(signed, v + s, v * np.exp(np.where(signed, 0.0, s)))
    return np.ones(len(free)), lambda v, s: np.where(
        signed, v + s, np.maximum(v + s, v * BOUND_CUT)
    )


def _signed(fm: Forward, free: list[int]) -> np.ndarray:
    """Which of the free moduli may be negative (their term's ``signed``)."""
    return np.array(
        [p in getattr(t, "signed", ()) for t, p in (fm.params[k] for k in free)], dtype=bool
    )


def _moves(new: np.ndarray, old: np.ndarray, signed: np.ndarray) -> np.ndarray:
    """How far each modulus moved: |Δ log p|, or |Δp| / max(|p|) for a signed one."""
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(new - old) / np.maximum(np.maximum(np.abs(new), np.abs(old)), 1e-300)
        return np.where(signed, rel, np.abs(np.log(np.where(signed, 1.0, new / old))))


def fit(
    fm: Forward,
    free: list[int] | None = None,
    max_iter: int = 20,
    tol: float = 1e-6,
    max_step: float = 1.5,
    scale_start: bool = True,
    space: str = "log",
    first=None,
    plausible: bool | dict | str | None = None,
) -> FitResult:
    """Fit the moduli ``free`` (indices into ``fm.params``; default all) from their current
    values (which must be > 0, but for a term's ``signed`` moduli, which step linearly, are
    held in the scale scan, and whose fitted energy is checked for stability over the data's
    states: :mod:`.stability_check`); the other moduli stay fixed. ``scale_start``: first scan the
    free moduli by decades (:func:`~fabricsurf.inverse.fitting.start.scan_terms`). ``space``: the
    step variable, "log" (θ = log p, steps capped at ±``max_step``) or "linear" (module
    docstring). The inputs are checked first, before any solve (the command line's refusals,
    :func:`~.preconditions.forward_preconditions`). Each iteration is logged at PROGRESS (at
    DEBUG inside :func:`fabricsurf.log.detail`). ``plausible``: also check the fitted moduli
    for values no fabric has (:func:`~.plausibility.check_moduli`, into ``implausible`` of the
    result and warned): True for the rules alone, ranges {"term.param": (low, high)} or
    "term.param=low:high,…" for the rules and those ranges; None (the default, as the
    diagnosis's own fits) does not check."""
    if plausible not in (None, False, True):
        parse_plausible(plausible)  # a bad range is refused before any solve
    first = None if scale_start else first  # the scan moves the start: its run is not that
    res = _fit(fm, free, max_iter, tol, max_step, scale_start, space, first)
    if plausible not in (None, False):
        res.implausible = check_moduli(fm, res, None if plausible is True else plausible)
    return res


def _fit(
    fm: Forward,
    free: list[int] | None,
    max_iter: int,
    tol: float,
    max_step: float,
    scale_start: bool,
    space: str,
    first=None,
) -> FitResult:
    if space not in ("log", "linear"):
        raise ValueError(f"fit: space = {space!r} is not 'log' or 'linear'")
    free = list(range(len(fm.params))) if free is None else list(free)
    signed = _signed(fm, free)
    forward_preconditions(fm, free, signed)  # zero starting moduli among them too
    vals = fm.values()
    given = vals.copy()
    runs0 = fm.forward_runs - (0 if first is None else len(first) if isinstance(first, list) else 1)
    if scale_start:
        vals = scan_terms(fm, [k for k, s in zip(free, signed) if not s], vals)
        held = held_terms(fm, free)
        if held:
            _say(
                fm,
                f"  fit: {', '.join(held)} held at the given moduli in the "
                "scale scan (the experiments hardly see them)",
            )
        _say(
            fm,
            "  fit: start after the scale scan: "
            + "  ".join(f"{fm.names[k]} = {vals[k]:.4g}" for k in free),
        )
    try:
        pred, rj, chi2 = _start(fm, free, vals, first)
    except LoadStepError as e:
        # the scout mesh carried the scanned moduli, the fit's mesh does not (moduli the data
        # hardly see, e.g. a cantilever's membrane, scanned down): start from those given
        if not scale_start or np.array_equal(vals, given):
            raise
        _say(fm, f"  fit: the scanned start fails ({e}); starting from the given moduli instead")
        vals = given
        pred, rj, chi2 = _start(fm, free, vals)
    if scale_start and not np.array_equal(vals, given):
        vals, pred, rj, chi2 = _scan_checked(fm, free, (vals, pred, rj, chi2), given)
    r, Jr = rj
    lam, hist, it = LAMBDA_START, [], 0
    at_bound = np.zeros(len(free), bool)
    watch, trial_run = StiffWatch(signed), partial(_try, fm, free)
    falling = np.zeros(len(free), int)
    for it in range(1, max_iter + 1):
        if space == "log" and falling.max() >= COLLAPSE:  # module docstring
            space = "linear"
            gone = ", ".join(fm.names[free[j]] for j in np.flatnonzero(falling >= COLLAPSE))
            _say(fm, f"  fit: {gone} heading for zero, where log steps crawl: steps in moduli")
        q_scale, update = _steps(space, vals, free, signed)
        Jt = Jr * q_scale  # dr/dq
        g = Jt.T @ r
        act = ~(at_bound & (g > 0)) & ~watch.held  # at the bound going down, or stiff limit
        if not act.any():
            break
        Ja = Jt[:, act]
        JTJ = Ja.T @ Ja
        D = np.diag(np.diag(JTJ)) + DIAG_FLOOR * np.trace(JTJ) * np.eye(len(JTJ))
        gn = la.lstsq(Ja, -r, "fit: the Gauss-Newton step")
        if float(r @ r - (r + Ja @ gn) @ (r + Ja @ gn)) < tol * chi2:
            break  # not even the Gauss-Newton step promises a relative decrease of tol
        accepted = False
        while lam < LAMBDA_MAX:
            step = np.zeros(len(free))
            step[act] = la.finite(np.linalg.solve(JTJ + lam * D, -g[act]), "fit: the damped step")
            if space == "log":  # the cap on the log-moduli's steps
                top = np.max(np.abs(step[~signed]), initial=0.0)
                step[~signed] *= min(1.0, max_step / max(top, 1e-300))
            trial = vals.copy()
            trial[free] = update(vals[free], step)
            p2, rj2, chi2_new = _try(fm, free, trial)
            if chi2_new < chi2:
                accepted, lam = True, max(lam / LAMBDA_DOWN, LAMBDA_MIN)
                break
            lam *= LAMBDA_UP
        if not accepted:
            fm.set_values(vals)
            break
        rel = (chi2 - chi2_new) / max(chi2, 1e-300)
        dlog = _moves(trial[free], vals[free], signed)
        down = (space == "log") & ~signed & (step <= -max_step * (1 - 1e-9))
        falling = np.where(down, falling + 1, 0)
        at_bound = (space == "linear") & ~signed & (~act | (vals[free] + step <= 0))
        ripe = watch.observe(vals[free], trial[free], rel)
        vals, pred, (r, Jr), chi2 = trial, p2, rj2, chi2_new
        if ripe.any():
            vals, pred, r, Jr, chi2 = hold(
                fm, free, watch, ripe, (vals, pred, r, Jr, chi2), trial_run
            )
        hist.append({"iteration": it, "chi2": chi2, "values": vals.tolist()})
        _say(
            fm,
            f"  fit iteration {it}: chi2 = {chi2:.6g}  "
            + "  ".join(f"{fm.names[k]} = {vals[k]:.5g}" for k in free),
        )
        cut = np.max(dlog[~signed], initial=0.0) >= max_step * (1 - 1e-9)
        moving = space == "log" and cut  # a log step was cut: go on
        if (rel < tol and not moving) or np.max(dlog[~at_bound], initial=0.0) < STALL:
            break
    fm.set_values(vals)
    res = optimum_result(fm, free, vals, pred, r, Jr, chi2, it, fm.forward_runs - runs0, hist)
    res.at_limit = {
        fm.names[k]: float(g) for k, h, g in zip(free, watch.held, watch.left) if h
    } or None
    if signed.any():  # a coupling's sign: is the fitted energy stable where the data go?
        res.stability = fitted_tangent(fm)
    if res.lost():
        _say(
            fm,
            "  fit: not determined by the data (standard deviation "
            f"undetermined, reported as null): {'; '.join(res.undetermined)}",
        )
    return res
