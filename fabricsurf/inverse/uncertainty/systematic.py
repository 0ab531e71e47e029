"""The systematic parts of the moduli's uncertainty, mesh and model form (docs/uncertainty.md).

*Mesh*: with d = r_{h/2} − r_h, the difference of the normalised residuals between the fit's
mesh and the mesh refined by 2 at the fitted moduli, a fit on the finer mesh would move the
moduli by δp = −(JᵀJ)⁺Jᵀd (one Gauss–Newton step from the optimum, where Jᵀr = 0): one forward
run without sensitivities. ‖d‖² is the discretisation χ²_h of the diagnosis.

*Model form*: the moduli refitted, linearised at the optimum, on disjoint parts S of the data
(each experiment when there are several, else each load step),
p_S = p̂ − (J_SᵀJ_S)⁻¹J_Sᵀr_S with the sandwich variances V_S of each part. A model that fits
every part with the same moduli leaves only noise between them; the variance between the parts
beyond what their own V_S explain is the model-form variance τ², estimated by the
method of moments of DerSimonian & Laird 1986.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.forward import misfit as mf
from fabricsurf.inverse.forward.load_path import Prediction
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.uncertainty.statistical import sandwich

RANK_TOL = 1e-6
"""A part whose scaled Jacobian has a singular value below this fraction of the largest does
not determine every modulus and is left out of the model-form spread."""


def _models(fm) -> list:
    return list(getattr(fm, "models", [fm]))


def mesh_difference(fm, preds, comm) -> np.ndarray:
    """d = r_{h/2} − r_h (module docstring), in the order of ``fm.residuals(preds)``; rows
    outside the finer mesh contribute 0."""
    preds = preds if isinstance(preds, list) else [preds]
    out = []
    for m, p in zip(_models(fm), preds):
        with ForwardModel(m.exp, m.model, h=m.h / 2, comm=comm) as fm_fine:
            fine = fm_fine.run()
        u = np.where(np.isfinite(fine.u).all(axis=1)[:, None], fine.u, p.u)
        r_h, _ = mf.residuals(m.exp, p)
        g = None if p.shear is None else np.where(np.isfinite(fine.shear), fine.shear, p.shear)
        r_f, _ = mf.residuals(m.exp, Prediction(u, fine.force, shear=g))
        out.append(r_f - r_h)
    return np.concatenate(out)


def mesh_shift(J: np.ndarray, d: np.ndarray) -> np.ndarray:
    """δp = −(JᵀJ)⁺Jᵀd: the moduli's shift from the fit's mesh to one refined by 2."""
    return -la.gram_pinv(J, "mesh shift: (JᵀJ)⁺") @ la.finite(J.T @ d, "mesh shift: Jᵀd")


def residual_steps(fm, preds) -> np.ndarray:
    """(experiment, load step) index of every stacked residual, as experiment·10⁶ + step."""
    preds = preds if isinstance(preds, list) else [preds]
    out = []
    for e, (m, p) in enumerate(zip(_models(fm), preds)):
        exp, c = m.exp, p.u.shape[1]
        inside = np.isfinite(p.u).all(axis=1)
        k = np.searchsorted(exp.steps, exp.field_step)
        parts = [np.repeat(k[inside], c)]
        if exp.has_force:
            parts.append(np.arange(len(exp.steps)))
        if exp.has_shear:
            parts.append(np.searchsorted(exp.steps, exp.shear_step)[np.isfinite(p.shear)])
        out.append(e * 10**6 + np.concatenate(parts))
    return np.concatenate(out)


def parts(fm, preds) -> list[np.ndarray]:
    """Masks of the disjoint parts of the data (module docstring): the experiments when there
    are several, else the load steps."""
    preds = preds if isinstance(preds, list) else [preds]
    if not all(isinstance(p, Prediction) for p in preds) or not all(
        hasattr(m, "exp") for m in _models(fm)
    ):
        return []
    idx = residual_steps(fm, preds)
    exp_of = idx // 10**6
    key = exp_of if len(np.unique(exp_of)) > 1 else idx
    return [key == k for k in np.unique(key)]


def model_form(
    J: np.ndarray,
    r: np.ndarray,
    masks: list[np.ndarray],
    labels: np.ndarray | None,
    noise_known: bool,
) -> np.ndarray | None:
    """τ per modulus (module docstring); None when fewer than two parts determine them (a
    part that does not determine every modulus alone is left out)."""
    fits = []
    col = np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    for s in masks:
        Js, rs = J[s], r[s]
        if Js.shape[0] <= Js.shape[1]:
            continue
        sv = la.singular_values(Js / col, "model form: SVD of a part's Jacobian")
        if sv[-1] <= RANK_TOL * sv[0]:
            continue
        dp = -la.finite(np.linalg.solve(Js.T @ Js, Js.T @ rs), "model form: a part's refit")
        V = np.diag(sandwich(Js, rs, None if labels is None else labels[s], noise_known).cov)
        fits.append((dp, np.maximum(V, 1e-300)))
    if len(fits) < 2:
        return None
    theta = np.array([f[0] for f in fits])
    w = 1.0 / np.array([f[1] for f in fits])
    total = w.sum(axis=0)
    u = w / total  # normalised weights: DerSimonian–Laird's sums without overflow (1/V ≤ 1e300)
    mean = (u * theta).sum(axis=0)
    spread = (u * (theta - mean) ** 2).sum(axis=0) - (len(fits) - 1) / total  # (Q − (k−1))/Σw
    return np.sqrt(np.maximum(0.0, spread / np.maximum(1.0 - (u**2).sum(axis=0), 1e-300)))
