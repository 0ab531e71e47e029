"""Intervals of the fitted moduli, and what the data determine (docs/uncertainty.md).

Per modulus: the statistical standard deviation σ (:mod:`~.uncertainty`), the model-form τ and
the mesh shift δ (:mod:`~.systematic`), combined into
    ci95 = p ± [√((t σ)² + (1.96 τ)² + w²) + MESH_FACTOR |δ|],
w the size part when a prediction to another specimen size is in question (:mod:`~.size_form`,
already a 95 % half-width), the random parts in quadrature, the mesh bias added in full (it is
an estimate of a bias, not a random error). A modulus is *identifiable* when it is not in a null
direction of the Fisher matrix and its interval excludes zero. For the moduli that are not, the
eigenvectors of their covariance in log-moduli name the combinations the data do determine, each
a weighted geometric mean Π p_i^{w_i} (Σ w_i = 1) whose log-interval half-width is below 1 (a
relative ± below 100 %, the same criterion to first order); the other directions are not
determined. A combination is only looked for among the directions the Jacobian determines: those
orthogonal to its null directions (:func:`null_directions`, the fit's ``undetermined``), so
that a direction the fit calls undetermined is never reported with an interval (the
pseudo-inverse gives it a variance of zero, which round-off from the other moduli's entries can
lift just above any eigenvalue threshold: a "zero-width" interval of an undetermined
ratio). The weak directions of the whole fit are the eigenvectors of the covariance of the
log-moduli whose 95 % half-width exceeds WEAK. A signed modulus (a coupling's, which may be
negative) has the same interval, not cut at zero, is identifiable when its interval excludes
zero on either side, and takes no part in the log-moduli combinations.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.forward import linalg as la

MESH_FACTOR = 2.0
"""The error at h is this multiple of the shift from h to h/2 when the error halves with h:
the slowest convergence accepted, so the bound is conservative for faster rates."""

WEAK = 0.5
"""A direction of log-moduli known only to ± 50 % or worse (95 %) is weak."""

Z95 = 1.959963984540054

NULL_TOL = 1e-12
"""Covariance eigenvalues below this fraction of the largest are the zeros the pseudo-inverse
puts in the null directions of the Fisher matrix: not determined, not known exactly."""

RANK_TOL = 1e-8
"""Singular values of the scaled Jacobian below this fraction of the largest are null
directions: the data do not determine that combination of log-moduli."""

NULL_OVERLAP = 1e-6
"""The null directions' components on the moduli considered span, above this (a singular value
of them), the combinations that get no interval: round-off below it touches none."""


def signed_mask(names: list[str]) -> np.ndarray:
    """Which of the moduli ``names`` ("term.param") may be negative (their term's ``signed``):
    they step linearly, their intervals may cross zero, they take no part in the log-moduli
    combinations."""
    from fabricsurf.model.terms import EFFECTS

    out = []
    for n in names:
        term, _, p = n.partition(".")
        out.append(term in EFFECTS and p in EFFECTS[term].signed)
    return np.array(out, dtype=bool)


def scaled_jacobian(J: np.ndarray, values: np.ndarray, names: list[str]) -> np.ndarray:
    """Jt = J·diag(s) whose null directions :func:`null_directions` finds: s = p (dr/d log p),
    and for a signed modulus (which may be near zero) s scales its column to the median norm
    of the others' (null directions are those of J whatever the column scales; the scale
    decides only what is "near" null)."""
    s = np.asarray(values, float).copy()
    signed = signed_mask(names)
    if signed.any():
        norms = np.linalg.norm(J, axis=0)
        typical = np.median(norms[~signed] * np.abs(s[~signed])) if (~signed).any() else 1.0
        s[signed] = typical / np.maximum(norms[signed], 1e-300)
    return J * s


def null_directions(Jt: np.ndarray) -> np.ndarray:
    """The null directions of the scaled Jacobian Jt = dr/d(log p) (singular values at most
    RANK_TOL of the largest), as the orthonormal columns of a p × k array (k = 0: full rank).
    From the SVD of Jt's p × p R factor (:func:`~.linalg.right_singular`): O(N·p) memory."""
    P = Jt.shape[1]
    if P == 0:
        return np.zeros((0, 0))
    sv, Vt = la.right_singular(Jt, "fit: identifiability (SVD of the scaled Jacobian)")
    top = sv[0] if sv[0] > 0 else 1.0
    return Vt[sv <= RANK_TOL * top].T


def half_width(
    sd: np.ndarray,
    t: float,
    tau: np.ndarray | None,
    shift: np.ndarray | None,
    size: np.ndarray | None = None,
) -> np.ndarray:
    """The combined 95 % half-width of the module docstring."""
    tau = np.zeros_like(sd) if tau is None else tau
    shift = np.zeros_like(sd) if shift is None else shift
    size = np.zeros_like(sd) if size is None else size
    return np.sqrt((t * sd) ** 2 + (Z95 * tau) ** 2 + size**2) + MESH_FACTOR * np.abs(shift)


def _text(v: np.ndarray, names: list[str]) -> str:
    terms = [(c, n) for c, n in zip(v, names) if abs(c) > 0.05 * np.abs(v).max()]
    return " ".join(f"{'-' if c < 0 else '+'} {abs(c):.2g} log {n}" for c, n in terms).lstrip("+ ")


def _log_cov(values, cov, tau, shift):
    p = np.maximum(values, 1e-300)
    C = cov / np.outer(p, p)
    t2 = np.zeros(len(p)) if tau is None else (tau / p) ** 2
    s = np.zeros(len(p)) if shift is None else shift / p
    return C, t2, s


def _determined_basis(null: np.ndarray | None, which: list[int]) -> np.ndarray:
    """Orthonormal columns spanning the combinations of the moduli ``which`` (weights on them
    only) that are orthogonal to every null direction: Q with N_whichᵀ Q = 0."""
    n = len(which)
    if null is None or null.size == 0:
        return np.eye(n)
    Nw = null[which, :]
    if not np.any(Nw):
        return np.eye(n)
    U, sv, _ = np.linalg.svd(Nw, full_matrices=True)
    rank = int(np.sum(sv > NULL_OVERLAP * max(1.0, sv[0])))
    return U[:, rank:]


def combinations(
    names, values, cov, t, tau, shift, which: list[int], null: np.ndarray | None = None
) -> list[dict]:
    """The determined combinations of the moduli ``which`` (module docstring); ``null``: the
    null directions of all the moduli ``names`` (:func:`null_directions`; None: none known)."""
    if len(which) < 2:
        return []
    C, t2, s = _log_cov(
        values[which],
        cov[np.ix_(which, which)],
        None if tau is None else tau[which],
        None if shift is None else shift[which],
    )
    Q = _determined_basis(null, which)
    if Q.shape[1] == 0:
        return []
    lam, Y = la.eigh(Q.T @ C @ Q, "intervals: the log-moduli covariance")
    V = Q @ Y
    out = []
    for k in range(Q.shape[1]):
        if lam[k] <= NULL_TOL * max(lam[-1], 1e-300):
            continue  # a null direction of the Fisher matrix (zero in its pseudo-inverse)
        v = V[:, k]
        w = v / v.sum() if abs(v.sum()) > 0.1 * np.abs(v).sum() else v / np.abs(v).max()
        sd = float(np.sqrt(max(w @ C @ w, 0.0)))
        half = float(
            np.sqrt((t * sd) ** 2 + Z95**2 * (np.abs(w) @ np.sqrt(t2)) ** 2)
            + MESH_FACTOR * abs(w @ s)
        )
        if half >= 1.0:
            continue
        logv = float(w @ np.log(values[which]))
        sub = [names[i] for i in which]
        out.append(
            {
                "combination": " · ".join(f"{n}^{c:.3g}" for c, n in zip(w, sub) if abs(c) > 1e-3),
                "weights": {n: float(c) for c, n in zip(w, sub)},
                "value": float(np.exp(logv)),
                "ci95": [float(np.exp(logv - half)), float(np.exp(logv + half))],
                "std_log": sd,
            }
        )
    return out


def weak_directions(names, values, cov) -> list[dict]:
    """Eigen-directions of the log-moduli covariance known worse than ± WEAK (95 %)."""
    signed = signed_mask(names)
    pos = [i for i in range(len(values)) if values[i] > 0 and not signed[i]]
    if not pos:
        return []
    C, _, _ = _log_cov(values[pos], cov[np.ix_(pos, pos)], None, None)
    lam, V = la.eigh(C, "intervals: the log-moduli covariance")
    sub = [names[i] for i in pos]
    return [
        {
            "direction": _text(V[:, k] * np.sign(V[np.argmax(np.abs(V[:, k])), k]), sub),
            "std_log": float(np.sqrt(max(lam[k], 0.0))),
        }
        for k in range(len(pos))[::-1]
        if Z95 * np.sqrt(max(lam[k], 0.0)) > WEAK
    ]


def summarise(
    names: list[str],
    values: np.ndarray,
    cov: np.ndarray,
    t: float,
    tau: np.ndarray | None,
    shift: np.ndarray | None,
    lost: set[str],
    size: np.ndarray | None = None,
    null: np.ndarray | None = None,
) -> dict:
    """{"moduli": {name: {value, ci95, std_statistical, systematic_mesh, systematic_model,
    [systematic_size,] identifiable}}, "identifiable_combinations", "weak_directions"} for the
    fitted moduli; ``lost``: the moduli in a null direction of the Fisher matrix; ``size``: the
    size part (95 % half-widths) when given; ``null``: the null directions
    (:func:`null_directions`), which no combination may lie along."""
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    half = half_width(sd, t, tau, shift, size)
    signed = signed_mask(names)
    moduli, weak = {}, []
    for i, n in enumerate(names):
        low = values[i] - half[i] if signed[i] else max(values[i] - half[i], 0.0)
        excludes_zero = values[i] - half[i] > 0 or (signed[i] and values[i] + half[i] < 0)
        ok = bool(n not in lost and np.isfinite(half[i]) and excludes_zero)
        moduli[n] = {
            "value": float(values[i]),
            "ci95": [float(low), float(values[i] + half[i])],
            "std_statistical": None if n in lost else float(sd[i]),
            "systematic_mesh": None if shift is None else float(MESH_FACTOR * abs(shift[i])),
            "mesh_shift_h_to_h2": None if shift is None else float(shift[i]),
            "systematic_model": None if tau is None else float(tau[i]),
            "identifiable": ok,
        }
        if size is not None:
            moduli[n]["systematic_size"] = float(size[i])
        if not ok and values[i] > 0 and not signed[i]:
            weak.append(i)
    return {
        "moduli": moduli,
        "identifiable_combinations": combinations(names, values, cov, t, tau, shift, weak, null),
        "weak_directions": weak_directions(names, values, cov),
    }
