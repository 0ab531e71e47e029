"""Where the excess misfit sits: at the yarn scale near the grips and zone boundaries (a
boundary or discreteness effect, which no energy term of a continuum will take) or spread
through the specimen (a missing energy). docs/diagnosis.md, "Where the excess sits", has the
rule's reasons and calibration.

Each field row of the final model has q = Σ z² over its c components (z in noise units), c at
the noise level. The rows are binned by distance from the nearest grip or zone boundary (the
plug-in's ``zone_distance``, in yarn spacings, else mesh sizes h) and by the model's shear
angle. :func:`locate` decides: **boundary** when the band within 1 unit holds ≥
:data:`NEAR_SHARE` of the excess beyond what the far rows at the same step and shear angle
hold, ≥ :data:`CONCENTRATION` times its share of the rows, and passes an F-test against that
expectation at the diagnosis's level; else **undecided** when the band holds so many of the rows
that no concentration could show; else **spread** when the far rows' χ² exceeds the
diagnosis's adequacy bound of their own (a missing energy, or a misfit of the specimen as a
whole: its size, grips or free edges, which where the excess sits cannot tell from one); else
**none** when the whole field's does not, and **undecided** when it does.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
from scipy import stats
from scipy.spatial import cKDTree

from fabricsurf.experiments import get_test
from fabricsurf.inverse.diagnosis import significance as sg
from fabricsurf.inverse.diagnosis.excess_text import reason
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.forward import misfit as mf

DISTANCE_EDGES = (0.0, 1.0, 2.0, 4.0, np.inf)
"""Distance bands (units: yarn spacings, or mesh sizes when the spacing is unknown)."""
SHEAR_EDGES_DEG = (0.0, 5.0, 15.0, 30.0, 45.0, np.inf)
"""Bands of the model's |shear angle| (deg) at the rows."""
NEAR_SHARE = 0.5
"""The near band (< 1 unit) must hold at least this share of the field's excess ..."""
CONCENTRATION = 2.0
"""... and at least this many times its share of the rows, for "boundary" (a band holding
1/CONCENTRATION of the rows or more cannot show it: the verdict is then "undecided")."""
NEAR_TOL = 1e-6
"""A row one unit away to round-off (the next yarn line of lattice or woven data) is beyond the
band: round-off split such rows between the two sides before (33 and 45 of one line)."""
NEIGHBOURS = 7
"""Points (itself included) of the local least-squares gradient behind a row's shear angle."""


def row_shear_deg(X: np.ndarray, u: np.ndarray, angles_deg) -> np.ndarray:
    """|γ| (deg) of the displacement ``u`` (n×c) at points ``X`` (n×2) of one step: the
    gradient of u by least squares over each point's :data:`NEIGHBOURS` nearest points, F =
    I + ∇u, γ the change of the angle between F·L and F·M."""
    n, c = u.shape
    if n < 3:
        return np.zeros(n)
    k = min(NEIGHBOURS, n)
    idx = cKDTree(X).query(X, k=k)[1]
    dX = X[idx] - X[:, None, :]
    A = np.concatenate([np.ones((n, k, 1)), dX], axis=2)
    AtA = np.einsum("nki,nkj->nij", A, A) + 1e-12 * np.eye(3)
    coef = np.linalg.solve(AtA, np.einsum("nki,nkc->nic", A, u[idx]))
    F = np.zeros((n, max(c, 2), 2))
    F[:, 0, 0] = F[:, 1, 1] = 1.0
    F[:, :c, :] += np.transpose(coef[:, 1:3, :], (0, 2, 1))
    L, M = (np.array([np.cos(np.radians(a)), np.sin(np.radians(a))]) for a in angles_deg)
    fl, fm = F @ L, F @ M
    cos = np.einsum("ni,ni->n", fl, fm) / np.maximum(
        np.linalg.norm(fl, axis=1) * np.linalg.norm(fm, axis=1), 1e-300
    )
    gamma = np.arccos(np.clip(L @ M, -1, 1)) - np.arccos(np.clip(cos, -1, 1))
    return np.degrees(np.abs(gamma))


def _bins(q: np.ndarray, c: int, key: np.ndarray, edges, total: float) -> list[dict]:
    out = []
    for lo, hi in pairwise(edges):
        sel = (key >= lo) & (key < hi)
        rows = int(sel.sum())
        if not rows:
            continue
        chi2 = float(q[sel].sum())
        out.append(
            {
                "from": float(lo),
                "to": None if np.isinf(hi) else float(hi),
                "rows": rows,
                "share_of_rows": rows / len(q),
                "chi2": chi2,
                "mean_z2": chi2 / (c * rows),
                "excess": chi2 - c * rows,
                "share_of_excess": (chi2 - c * rows) / total if total > 0 else None,
            }
        )
    return out


def _beyond_bound(chi2: float, dof: int) -> bool:
    return dof > 0 and chi2 / dof > sg.adequacy_bound(dof, 0)


STRATUM_DEG = 5.0
"""Width (deg) of the shear-angle strata within a load step against which the near band is
compared (:func:`_expected_near`)."""


def _expected_near(
    q: np.ndarray, c: int, near: np.ndarray, strata: np.ndarray
) -> tuple[float, float]:
    """(χ², its degrees of freedom): the χ² the near rows would have if they misfit as the rows
    beyond them do at the same load step and shear angle (a stratum: step ×
    :data:`STRATUM_DEG` of |γ|), so that the near band is judged against a spread that follows
    the shear, not against the specimen's average (the zone boundaries border the most sheared
    zone). A stratum without far rows takes the far rows' mean of the whole data. The degrees
    of freedom are Satterthwaite's for the weighted sum of the strata's means."""
    far = ~near
    nf_all = int(far.sum())
    overall = q[far].sum() / (c * nf_all)
    expected, var = 0.0, 0.0
    for s in np.unique(strata[near]):
        at = strata == s
        nf = int((at & far).sum()) or nf_all
        mean = q[at & far].sum() / (c * nf) if (at & far).any() else overall
        part = c * int((at & near).sum()) * mean
        expected += part
        var += part**2 / (c * nf)
    return float(expected), float(expected**2 / max(var, 1e-300))


def locate(
    q: np.ndarray, c: int, distance: np.ndarray, shear_deg: np.ndarray, step: np.ndarray
) -> dict:
    """The bins and the verdict of the module docstring for field rows with χ² ``q`` (Σ z²
    over ``c`` components each), ``distance`` in units (yarn spacings or h), the model's
    |shear angle| ``shear_deg`` and load ``step``. Pure arithmetic on arrays (no solve)."""
    n = len(q)
    Q = float(q.sum())
    total = Q - c * n
    near = distance < 1.0 - NEAR_TOL
    nn, nf = int(near.sum()), n - int(near.sum())
    qn, qf = float(q[near].sum()), float(q[~near].sum())
    share_rows = nn / max(n, 1)
    share_ex = (qn - c * nn) / total if total > 0 else 0.0
    F = p = expected = None
    if nn and nf and qf > 0:
        strata = np.asarray(step, dtype=np.int64) * 1000 + (shear_deg // STRATUM_DEG).astype(int)
        expected, dof = _expected_near(q, c, near, strata)
        F = qn / expected
        p = float(stats.f.sf(F, c * nn, dof))
    beyond = (qn - expected) / total if expected is not None and total > 0 else 0.0
    rec = {
        "rows": n,
        "components": c,
        "chi2": Q,
        "excess": total,
        "mean_z2": Q / max(c * n, 1),
        "adequacy_bound": sg.adequacy_bound(c * n, 0) if n else None,
        "significant": _beyond_bound(Q, c * n),
        "near": {
            "rows": nn,
            "share_of_rows": share_rows,
            "share_of_excess": share_ex if total > 0 else None,
            "share_beyond_shear": beyond if total > 0 else None,
            "mean_z2": qn / (c * nn) if nn else None,
            "mean_z2_elsewhere": qf / (c * nf) if nf else None,
            "mean_z2_expected": expected / (c * nn) if expected is not None else None,
            "f_statistic": F,
            "p": p,
            "p_needed": 1.0 - sg.LEVEL,
            "judgeable": CONCENTRATION * share_rows < 1.0,
        },
        "far_significant": _beyond_bound(qf, c * nf),
        "by_distance": _bins(q, c, distance, DISTANCE_EDGES, total),
        "by_shear_angle": _bins(q, c, shear_deg, SHEAR_EDGES_DEG, total),
    }
    concentrated = (
        beyond >= NEAR_SHARE
        and share_ex >= CONCENTRATION * share_rows
        and p is not None
        and p < 1.0 - sg.LEVEL
    )
    if concentrated:
        verdict = "boundary"
    elif not rec["near"]["judgeable"] and rec["significant"]:
        verdict = "undecided"
    elif rec["far_significant"]:
        verdict = "spread"
    else:
        verdict = "undecided" if rec["significant"] else "none"
    return rec | {"verdict": verdict}


def excess_location(
    exps: list,
    res: FitResult,
    yarn_spacing: float | None = None,
    h: list[float] | None = None,
) -> dict:
    """Where the field's excess of ``res`` (the final model) sits (module docstring), over the
    experiments whose plug-in knows its zones. The distances are in yarn spacings of
    ``yarn_spacing`` (mm), else in the mesh sizes ``h`` (one per experiment). The data and the
    predictions are the same on every rank, and so is the record."""
    preds = res.prediction if isinstance(res.prediction, list) else [res.prediction]
    unit = "yarn spacing" if yarn_spacing else "mesh size h"
    qs, ds, gs, ks, skipped, cs, units = [], [], [], [], [], set(), []
    force = [0.0, 0]
    for k, (e, pred) in enumerate(zip(exps, preds)):
        r = mf.residuals(e, pred)[0]
        c = pred.u.shape[1]
        inside = np.isfinite(pred.u).all(axis=1) if e.has_field else np.zeros(0, bool)
        nf = c * int(inside.sum())
        if e.has_force:
            force[0] += float(r[nf : nf + len(e.steps)] @ r[nf : nf + len(e.steps)])
            force[1] += len(e.steps)
        if not nf:
            continue
        dist = get_test(e.test).zone_distance(e.setup, e.X[inside])
        if dist is None:
            skipped.append(e.name)
            continue
        scale = float(yarn_spacing or (h[k] if h else 1.0))
        units.append(scale)
        q = (r[:nf].reshape(-1, c) ** 2).sum(axis=1)
        rows = np.flatnonzero(inside)
        g = np.zeros(len(rows))
        for s in np.unique(e.field_step[rows]):
            at = e.field_step[rows] == s
            g[at] = row_shear_deg(e.X[rows[at]], pred.u[rows[at]], e.fibre_angles_deg)
        qs.append(q)
        ds.append(dist / scale)
        gs.append(g)
        ks.append(e.field_step[rows] + 100_000 * k)
        cs.add(c)
    base = {
        "unit": unit,
        "unit_mm": units,
        "yarn_spacing_mm": yarn_spacing,
        "force": {"chi2": force[0], "excess": force[0] - force[1], "steps": force[1]},
        "experiments_without_zones": skipped,
    }
    if not qs or len(cs) != 1:
        why = (
            "no field data with zones to locate the excess in (force only, or a test without "
            "grips and zones)"
            if not qs
            else "the experiments compare different numbers of components"
        )
        return base | {"verdict": None, "reason": why}
    cat = np.concatenate
    rec = base | locate(cat(qs), cs.pop(), cat(ds), cat(gs), cat(ks))
    rec["reason"] = reason(rec, unit)
    if not yarn_spacing:
        rec["reason"] += (
            " (the yarn spacing is not known, --yarn-spacing: distances are in mesh sizes, so "
            "a concentrated excess may also be a boundary layer a gradient effect would take)"
        )
    return rec
