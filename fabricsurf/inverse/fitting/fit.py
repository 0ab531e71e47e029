"""Least-squares fit of the moduli (Levenberg–Marquardt in log-moduli) with tangent sensitivities.

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
decade of its optimum: the diagnosis fits its baseline in the moduli too. Measured on the
issue-12 lattice (187 × 119 mm, k_l/k_s = 2500, complete model, h = 8 mm): log steps took 16
iterations and 26 forward runs (about every other trial rejected along the curved valley),
moduli steps 5 iterations and 6 runs, to the same optimum (χ² = 98670).
A small relative χ² change does not stop a step that was cut to ``max_step`` (a modulus far
from its optimum, e.g. a candidate effect started near zero, changes χ² little per step); the
fit stops when not even the Gauss–Newton step promises a relative decrease of ``tol`` (at the
optimum every trial step would be rejected, each costing a forward run).
Uncertainties: Cov(θ) = (JᵀJ)⁻¹ — the residuals are already divided by the noise level — times
the reduced χ² when the data give no ``noise_std``; σ_p = p σ_θ (first order).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fabricsurf.discretise.output import rank0_print
from fabricsurf.discretise.solver import LoadStepError
from fabricsurf.inverse.fitting.forward import ForwardModel, ForwardSet, Prediction
from fabricsurf.inverse.fitting.start import held_terms, scan_terms


@dataclass
class FitResult:
    """Fitted moduli (by parameter name "term.param"), their standard deviations, misfits."""

    names: list
    values: np.ndarray
    std: np.ndarray
    chi2: float
    misfit: dict
    prediction: Prediction | list[Prediction]
    iterations: int
    forward_runs: int
    history: list = field(default_factory=list)
    undetermined: list = field(default_factory=list)
    """Combinations of log-moduli the data do not determine (:func:`undetermined`)."""

    def params(self) -> dict:
        """{term: {param: value}} (the --params file format)."""
        out: dict = {}
        for n, v in zip(self.names, self.values):
            t, p = n.split(".")
            out.setdefault(t, {})[p] = float(v)
        return out

    def as_dict(self) -> dict:
        m = strip_rows(self.misfit)
        return {"terms": list(self.params()), "params": self.params(),
                "std": {n: float(s) for n, s in zip(self.names, self.std)},
                "chi2": self.chi2, "misfit": m, "iterations": self.iterations,
                "forward_runs": self.forward_runs, "history": self.history,
                "undetermined": self.undetermined}


Forward = ForwardModel | ForwardSet


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


def _start(fm: Forward, free: list[int], vals: np.ndarray):
    """:func:`_try` at the start, where a failure ends the fit: the error names the starting
    moduli, the experiment, the step and the load (and keeps what had converged)."""
    moduli = ", ".join(f"{fm.names[k]} = {vals[k]:.4g}" for k in free)
    fm.set_values(vals)
    try:
        pred = fm.run(sens=free)
    except LoadStepError as e:
        exp = getattr(e, "experiment", None)
        err = LoadStepError(f"fit: the initial model ({moduli}) does not follow the load path"
                            + (f" of experiment '{exp}'" if exp else "") + f": {e}", e.step,
                            e.target, e.last_load, e.reason, e.attempts)
        err.experiment, err.partial = exp, e.partial
        raise err from None
    r, Jr = fm.residuals(pred)
    if not np.isfinite(r).all():
        raise LoadStepError(f"fit: the initial model ({moduli}) gives non-finite residuals")
    return pred, (r, Jr), float(r @ r)


RANK_TOL = 1e-8
"""Singular values of the scaled Jacobian below this fraction of the largest are null
directions: the data do not determine that combination of log-moduli."""


def undetermined(names: list[str], Jt: np.ndarray) -> list[str]:
    """The null directions of the scaled Jacobian Jt = dr/d(log p) (a rank-deficient Fisher
    matrix JtᵀJt), each as its combination of log-moduli, e.g. "0.71 log a.k - 0.71 log b.k"
    (the ratio a.k/b.k is not determined)."""
    P = Jt.shape[1]
    if P == 0:
        return []
    _, sv, Vt = np.linalg.svd(Jt, full_matrices=True)
    sv = np.concatenate([sv, np.zeros(P - len(sv))])
    top = sv[0] if sv[0] > 0 else 1.0
    out = []
    for sval, v in zip(sv, Vt):
        if sval <= RANK_TOL * top:
            terms = [(c, n) for c, n in zip(v, names) if abs(c) > 0.05 * np.abs(v).max()]
            if terms[0][0] < 0:  # the first term positive
                terms = [(-c, n) for c, n in terms]
            out.append(" ".join(f"{'-' if c < 0 else '+'} {abs(c):.2g} log {n}"
                                for c, n in terms).lstrip("+ "))
    return out


def covariance(Jt: np.ndarray, chi2: float, noise_known: bool) -> np.ndarray:
    """(JᵀJ)⁻¹, scaled by the reduced χ² when the noise level is not known."""
    n, P = Jt.shape
    C = np.linalg.pinv(Jt.T @ Jt)
    return C if noise_known else C * chi2 / max(n - P, 1)


BOUND_CUT = 1e-3
"""Linear steps: a modulus the step would make ≤ 0 is cut by this factor instead (a few steps
take it to where it no longer matters: the bound at zero)."""


def _steps(space: str, vals: np.ndarray, free: list[int]):
    """(dr/dq scaling, update) of the step variable q: θ = log p, or p itself (module
    docstring)."""
    if space == "log":
        return vals[free], lambda v, s: v * np.exp(s)
    return np.ones(len(free)), lambda v, s: np.maximum(v + s, v * BOUND_CUT)


def fit(fm: Forward, free: list[int] | None = None, max_iter: int = 20,
        tol: float = 1e-6, max_step: float = 1.5, verbose: bool = True,
        scale_start: bool = True, space: str = "log") -> FitResult:
    """Fit the moduli ``free`` (indices into ``fm.params``; default all) from their current
    values (which must be > 0); the other moduli stay fixed. ``scale_start``: first scan the
    free moduli by decades (:func:`~fabricsurf.inverse.fitting.start.scan_terms`). ``space``: the
    step variable, "log" (θ = log p, steps capped at ±``max_step``) or "linear" (module
    docstring)."""
    if space not in ("log", "linear"):
        raise ValueError(f"fit: space = {space!r} is not 'log' or 'linear'")
    free = list(range(len(fm.params))) if free is None else list(free)
    vals = fm.values()
    if np.any(vals[free] <= 0):
        raise ValueError("fit: initial moduli must be > 0 (log-parametrisation): "
                         f"{dict(zip(fm.names, vals))}")
    runs0, given = fm.forward_runs, vals.copy()
    if scale_start:
        vals = scan_terms(fm, free, vals)
        held = held_terms(fm, free)
        if verbose and held:
            rank0_print(fm.comm, f"  fit: {', '.join(held)} held at the given moduli in the "
                        "scale scan (the experiments hardly see them)")
        if verbose:
            rank0_print(fm.comm, "  fit: start after the scale scan: " + "  ".join(
                f"{fm.names[k]} = {vals[k]:.4g}" for k in free))
    try:
        pred, rj, chi2 = _start(fm, free, vals)
    except LoadStepError as e:
        # the scout mesh carried the scanned moduli, the fit's mesh does not (moduli the data
        # hardly see, e.g. a cantilever's membrane, scanned down): start from those given
        if not scale_start or np.array_equal(vals, given):
            raise
        if verbose:
            rank0_print(fm.comm, f"  fit: the scanned start fails ({e}); starting from the "
                        "given moduli instead")
        vals = given
        pred, rj, chi2 = _start(fm, free, vals)
    r, Jr = rj
    lam, hist, it = 1e-3, [], 0
    at_bound = np.zeros(len(free), bool)
    for it in range(1, max_iter + 1):
        q_scale, update = _steps(space, vals, free)
        Jt = Jr * q_scale  # dr/dq
        g = Jt.T @ r
        act = ~(at_bound & (g > 0))  # a modulus at the bound that would go on down is held
        Ja = Jt[:, act]
        JTJ = Ja.T @ Ja
        D = np.diag(np.diag(JTJ)) + 1e-12 * np.trace(JTJ) * np.eye(len(JTJ))
        gn = np.linalg.lstsq(Ja, -r, rcond=None)[0]
        if float(r @ r - (r + Ja @ gn) @ (r + Ja @ gn)) < tol * chi2:
            break  # not even the Gauss-Newton step promises a relative decrease of tol
        accepted = False
        while lam < 1e8:
            step = np.zeros(len(free))
            step[act] = np.linalg.solve(JTJ + lam * D, -g[act])
            if space == "log":
                step *= min(1.0, max_step / max(np.max(np.abs(step)), 1e-300))
            trial = vals.copy()
            trial[free] = update(vals[free], step)
            p2, rj2, chi2_new = _try(fm, free, trial)
            if chi2_new < chi2:
                accepted, lam = True, max(lam / 5, 1e-7)
                break
            lam *= 8
        if not accepted:
            fm.set_values(vals)
            break
        rel = (chi2 - chi2_new) / max(chi2, 1e-300)
        dlog = np.abs(np.log(trial[free] / vals[free]))
        at_bound = (space == "linear") & (~act | (vals[free] + step <= 0))
        vals, pred, (r, Jr), chi2 = trial, p2, rj2, chi2_new
        hist.append({"iteration": it, "chi2": chi2, "values": vals.tolist()})
        if verbose:
            rank0_print(fm.comm, f"  fit iteration {it}: chi2 = {chi2:.6g}  "
                        + "  ".join(f"{fm.names[k]} = {vals[k]:.5g}" for k in free))
        moving = space == "log" and np.max(dlog) >= max_step * (1 - 1e-9)  # cut: go on
        if (rel < tol and not moving) or np.max(dlog[~at_bound], initial=0.0) < 1e-5:
            break
    fm.set_values(vals)
    Jt = Jr * vals[free]
    C = covariance(Jt, chi2, fm.noise_known)
    std = np.zeros(len(vals))
    std[free] = vals[free] * np.sqrt(np.maximum(np.diag(C), 0.0))
    return FitResult(list(fm.names), vals, std, chi2, fm.misfit(pred), pred, it,
                     fm.forward_runs - runs0, hist,
                     undetermined(list(np.array(fm.names)[free]), Jt))


def strip_rows(m: dict) -> dict:
    """A misfit dict without the per-row error arrays (for JSON)."""
    out = {k: v for k, v in m.items() if k != "row_error"}
    if "experiments" in out:
        out["experiments"] = [strip_rows(e) for e in out["experiments"]]
    return out


def load_params(path: str | Path | None) -> dict:
    """{term: {param: value}} from a JSON file: a plain mapping or a saved fit (key "params")."""
    if not path:
        return {}
    data = json.loads(Path(path).read_text())
    return data.get("params", data)
