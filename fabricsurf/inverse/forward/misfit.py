"""Misfit between model and measurements, in noise units (docs/contracts.md).

Each datum gets a normalised residual
    field: r = (u_model − u_meas)/s_u  for every field row and compared component,
    force: r = (F_model − F_meas)/s_F  for every step,
    shear: r = (γ_model − γ_meas)/s_γ  for every measured shear angle (deg, a formed part),
with s_u = ``noise_std``, s_F = ``force_noise_std`` and s_γ = ``shear_noise_deg`` when the data
give them, otherwise s_u = 1 % of the largest measured displacement magnitude, s_F = 1 % of the
largest |force| and s_γ = 1 % of the largest |γ|.
The combined misfit is sqrt(mean r²) over all data (≈ 1 at the noise level when the noise is
given), χ² = Σ r². Field RMS (length) and force RMS (N) are reported unweighted. Rows whose
point lies outside the mesh are reported and left out.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.contract.experiment import Experiment


def noise_known(exp: Experiment) -> bool:
    """Whether the data state the noise of every kind of measurement they contain."""
    return (
        (not exp.has_field or exp.noise_std is not None)
        and (not exp.has_force or exp.force_noise_std is not None)
        and (not exp.has_shear or exp.shear_noise_deg is not None)
    )


def shear_scale(exp: Experiment) -> float:
    """s_γ (deg): the shear noise, or 1 % of the largest measured |γ| (module docstring)."""
    gmax = float(np.max(np.abs(exp.shear))) if exp.has_shear else 0.0
    return max(exp.shear_noise_deg or 0.01 * gmax, 1e-300)


def _shear_parts(exp: Experiment, pred) -> tuple[np.ndarray, np.ndarray | None]:
    """(normalised shear residuals, their rows of dr/dp) at the shear points inside the mesh."""
    if not exp.has_shear:
        return np.zeros(0), None
    s_g = shear_scale(exp)
    inside = np.isfinite(pred.shear)
    r = (pred.shear - exp.shear)[inside] / s_g
    return r, None if pred.dshear is None else pred.dshear[inside] / s_g


def scales(exp: Experiment) -> tuple[float, float]:
    """(s_u, s_F): the noise levels, or 1 % of the largest measured value (module docstring;
    the largest value is only sought when it is needed: a pass over 10⁶ rows per call)."""
    s_u = exp.noise_std or (
        0.01 * float(np.sqrt(np.max(np.einsum("ij,ij->i", exp.u, exp.u)))) if exp.has_field else 0.0
    )
    s_F = exp.force_noise_std or (0.01 * float(np.max(np.abs(exp.force))) if exp.has_force else 0.0)
    return max(s_u, 1e-300), max(s_F, 1e-300)


def residuals(exp: Experiment, pred) -> tuple[np.ndarray, np.ndarray | None]:
    """Normalised residual vector r (field rows inside the mesh, then forces) and dr/dp."""
    s_u, s_F = scales(exp)
    c = pred.u.shape[1]
    inside = np.isfinite(pred.u).all(axis=1)
    parts = [((pred.u - exp.u[:, :c])[inside] / s_u).ravel()]
    if exp.has_force:
        parts.append((pred.force - exp.force) / s_F)
    rg, Jg = _shear_parts(exp, pred)
    r = np.concatenate([*parts, rg])
    if pred.du is None:
        return r, None
    P = pred.du.shape[2]
    J = [(pred.du[inside] / s_u).reshape(-1, P)]
    if exp.has_force:
        J.append(pred.dforce / s_F)
    if Jg is not None:
        J.append(Jg)
    return r, np.vstack(J)


def misfit(exp: Experiment, pred) -> dict:
    """Overall and per-step misfits (module docstring) and per-row errors (length units)."""
    s_u, s_F = scales(exp)
    c = pred.u.shape[1]
    inside = np.isfinite(pred.u).all(axis=1)
    err = np.linalg.norm(pred.u - exp.u[:, :c], axis=1)
    dF = pred.force - exp.force if exp.has_force else None
    r, _ = residuals(exp, pred)
    gerr = pred.shear - exp.shear if exp.has_shear else np.zeros(0)
    gin = np.isfinite(gerr)
    s_g = shear_scale(exp)
    per_step = []
    for k, s in enumerate(exp.steps):
        rows = exp.step_rows(s)
        rows = rows[inside[rows]]
        grows = exp.shear_rows(s)
        grows = grows[gin[grows]]
        e2 = float(np.sum((pred.u[rows] - exp.u[rows, :c]) ** 2))
        g2 = float(np.sum(gerr[grows] ** 2))
        fk = float(dF[k]) if dF is not None else 0.0
        n = c * len(rows) + (1 if dF is not None else 0) + len(grows)
        row = {
            "step": int(s),
            "load": float(exp.path[k]),
            "field_rms": float(np.sqrt(e2 / max(c * len(rows), 1))) if len(rows) else None,
            "combined": float(
                np.sqrt(
                    (
                        (e2 / s_u**2 if len(rows) else 0.0)
                        + (fk / s_F) ** 2
                        + (g2 / s_g**2 if len(grows) else 0.0)
                    )
                    / max(n, 1)
                )
            ),
        }
        if exp.has_shear:
            row["shear_rms_deg"] = float(np.sqrt(g2 / len(grows))) if len(grows) else None
        if dF is not None:
            row |= {
                "force_model": float(pred.force[k]),
                "force_meas": float(exp.force[k]),
                "force_error": fk,
            }
        per_step.append(row)
    field_rms = float(np.sqrt(np.mean(err[inside] ** 2) / c)) if inside.any() else None
    return {
        "field_rms": field_rms,
        "force_rms": float(np.sqrt(np.mean(dF**2))) if dF is not None else None,
        "combined": float(np.sqrt(np.mean(r**2))),
        "chi2": float(np.sum(r**2)),
        "n": int(r.size),
        "s_u": s_u if exp.has_field else None,
        "s_F": s_F if exp.has_force else None,
        "points_outside": int(np.count_nonzero(~inside) + np.count_nonzero(~gin)),
        "per_step": per_step,
        "row_error": err,
    } | (
        {
            "shear_rms_deg": float(np.sqrt(np.mean(gerr[gin] ** 2))) if gin.any() else None,
            "s_shear_deg": s_g,
            "shear_error": gerr,
        }
        if exp.has_shear
        else {}
    )


def converged_steps(exp: Experiment, pred) -> list[dict]:
    """Model against data at the steps a failed run did converge (its NaN-free steps)."""
    rows = []
    for k, s in enumerate(exp.steps):
        sel = exp.step_rows(s)
        fk = None if pred.force is None else float(pred.force[k])
        if (fk is not None and not np.isfinite(fk)) or (
            len(sel) and not np.isfinite(pred.u[sel]).all()
        ):
            break
        c = pred.u.shape[1]
        row = {"step": int(s), "load": float(exp.path[k])}
        if len(sel):
            row["field_rms"] = float(np.sqrt(np.mean((pred.u[sel] - exp.u[sel, :c]) ** 2)))
        if fk is not None:
            row |= {"force_model": fk, "force_meas": float(exp.force[k])}
        rows.append(row)
    return rows
