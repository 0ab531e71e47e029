"""Prediction band of a force curve from a fitted params file (docs/uncertainty.md).

The moduli's uncertainty of a fit.json (or model_best.json) is carried linearly through the
exact sensitivities g = dF/dp of a forward run at the fitted moduli, part by part as in the
moduli's intervals (:mod:`~.intervals`):
    half-width = √(t² gᵀCg + 1.96² Σ_i (g_i τ_i)² + w_size²) + MESH_FACTOR |gᵀδ|,
C the statistical covariance, τ the model-form and δ the mesh parts; w_size the model-form
part of a transfer to another specimen size (:mod:`~.size_form`) when the params file carries
its ``size_effects`` record, else 0, and the band says that it omits it (``parts_included``,
``omits``). The linearisation is
checked with one more run at the moduli moved along the covariance's leading direction to its
95 % extent: where the actual force change differs from gᵀΔp by more than NONLINEAR of the
band, the band is flagged unreliable (a refit, not a linear band, is then the answer).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.contract.experiment import template
from fabricsurf.inverse.fitting import size_form as sz
from fabricsurf.inverse.forward import linalg as la
from fabricsurf.inverse.forward.runs import ForwardModel
from fabricsurf.inverse.uncertainty.intervals import MESH_FACTOR, Z95

NONLINEAR = 0.2
"""The largest departure from linearity, as a share of the band, for which it is reliable."""


def _saved(params_file: str | Path | dict) -> dict:
    if isinstance(params_file, dict):
        return params_file
    return json.loads(Path(params_file).read_text(encoding="utf-8"))


OMITS_SIZE = (
    "the model-form part of a transfer to another specimen size (the params file "
    "has no size_effects record: docs/uncertainty.md)"
)
OMITS_SIZE_MODEL = (
    "the model-form part of a transfer to another specimen size (the model "
    "lacks the record's candidate terms: size_form.extended_model)"
)
OMITS_SIZE_FIELD = "the size part (computed for the force only)"


def _half_widths(
    g: np.ndarray,
    C: np.ndarray,
    tau: np.ndarray,
    shift: np.ndarray,
    t: float,
    size: np.ndarray | float = 0.0,
) -> tuple[np.ndarray, ...]:
    """(statistical, model-form, mesh, combined) 95 % half-widths of quantities with
    sensitivities ``g`` (..., P) and size part ``size`` (module docstring)."""
    stat = t * np.sqrt(np.maximum(((g @ C) * g).sum(axis=-1), 0.0))
    model = Z95 * np.sqrt((g**2 * tau**2).sum(axis=-1))
    mesh = MESH_FACTOR * np.abs(g @ shift)
    return stat, model, mesh, np.sqrt(stat**2 + model**2 + np.square(size)) + mesh


def force_band(fm: ForwardModel, params_file: str | Path | dict, check: bool = True) -> dict:
    """The predicted force curve of ``fm`` (its own set-up and load path, e.g. another
    specimen size) at the moduli of ``params_file`` with its 95 % band (module docstring), and
    the band of its displacements at the measurement points when it has a field.

    Returns {"load", "force", "lower", "upper", "half_width", "parts": {"statistical",
    "model_form", "mesh", "size_form"}, "parts_included", "omits", "size_effects",
    "nonlinearity", "reliable", "field_half_width"}: the force entries
    are None for a test without a measured force; "field_half_width" (an array rows ×
    components, mm, NaN outside the mesh) is None without a field; "nonlinearity" (the
    largest departure of the force from its linear change, as a share of the half-width) and
    "reliable" are None without ``check`` or a force. The moduli of ``fm`` are set to the
    file's and left there. The size part needs the record's candidate terms in ``fm``'s model
    (:func:`~.size_form.extended_model`, as :func:`predicted_band` builds it); without them
    the band omits it and says so."""
    saved = _saved(params_file)
    cov = (saved.get("uncertainty") or {}).get("covariance")
    if cov is None:
        raise ValueError(
            "force_band: the params file has no covariance (a fit.json or "
            "model_best.json written by fit or diagnose)"
        )
    vals = fm.values()
    for k, (t, p) in enumerate(fm.params):
        vals[k] = saved["params"].get(t.name, {}).get(p, vals[k])
    fm.set_values(vals)
    idx = [fm.names.index(n) for n in cov["names"]]
    record = saved.get("size_effects")
    omits = [] if record else [OMITS_SIZE]
    if record and any(n not in fm.names for n in record["candidates"]):
        record, omits = None, [OMITS_SIZE_MODEL]
    pred = fm.run(sens=idx)
    C, moduli = np.asarray(cov["statistical"]), saved["moduli"]
    tau = np.array([moduli[n].get("systematic_model") or 0.0 for n in cov["names"]])
    shift = np.array([moduli[n].get("mesh_shift_h_to_h2") or 0.0 for n in cov["names"]])
    t = saved["uncertainty"]["statistics"]["t95"]
    included = ["statistical", "model_form", "mesh"] + (["size_form"] if record else [])
    out = {
        "load": fm.exp.path.tolist(),
        "force": None,
        "lower": None,
        "upper": None,
        "half_width": None,
        "parts": None,
        "parts_included": included,
        "omits": omits,
        "size_effects": record,
        "nonlinearity": None,
        "reliable": None,
        "field_half_width": None,
    }
    if fm.exp.has_field and pred.du is not None:
        out["field_half_width"] = _half_widths(pred.du, C, tau, shift, t)[3]
        if record:
            out["omits"].append(OMITS_SIZE_FIELD)
    if not fm.exp.has_force:
        return out
    g = pred.dforce
    size = sz.band_half_width(fm, record, pred.force) if record else 0.0
    stat, model, mesh, half = _half_widths(g, C, tau, shift, t, size)
    out |= {
        "force": pred.force.tolist(),
        "lower": (pred.force - half).tolist(),
        "upper": (pred.force + half).tolist(),
        "half_width": half.tolist(),
        "parts": {
            "statistical": stat.tolist(),
            "model_form": model.tolist(),
            "mesh": mesh.tolist(),
            "size_form": np.broadcast_to(size, half.shape).tolist(),
        },
    }
    if check:
        out["nonlinearity"] = linearity(fm, vals, idx, g, C, t, pred.force, half)
        out["reliable"] = bool(out["nonlinearity"] <= NONLINEAR)
    return out


def has_covariance(saved: dict) -> bool:
    """Whether a params file's contents carry the covariance a band needs (fit.json or
    model_best.json written by fit or diagnose)."""
    return bool((saved.get("uncertainty") or {}).get("covariance"))


def write_band(path: str | Path, band: dict, load_label: str = "displacement") -> None:
    """The band as CSV with the columns ``<load_label>,force,lower,upper`` (the load path's
    unit, N); rank 0 writes (call it there)."""
    rows = np.column_stack([band["load"], band["force"], band["lower"], band["upper"]])
    np.savetxt(
        path, rows, delimiter=",", fmt="%.6g", header=f"{load_label},force,lower,upper", comments=""
    )


def linearity(
    fm: ForwardModel,
    vals: np.ndarray,
    idx: list[int],
    g: np.ndarray,
    C: np.ndarray,
    t: float,
    force: np.ndarray,
    half: np.ndarray,
) -> float:
    """max_k |F_k(p + Δp) − F_k(p) − g_k·Δp| / half-width_k, Δp the covariance's leading
    eigenvector at its 95 % extent (kept ≥ 0); the moduli are restored."""
    lam, V = la.eigh(C, "band: the covariance")
    dp = t * np.sqrt(max(lam[-1], 0.0)) * V[:, -1]
    moved = vals.copy()
    moved[idx] = np.maximum(vals[idx] + dp, 0.0)
    fm.set_values(moved)
    try:
        f2 = fm.run().force
    finally:
        fm.set_values(vals)
    lin = g @ (moved[idx] - vals[idx])
    return float(np.max(np.abs(f2 - force - lin) / np.maximum(half, 1e-300)))


def predicted_band(
    saved: dict,
    model: list,
    length: float,
    width: float,
    path,
    h: float,
    clamp: str = "gradient",
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> dict:
    """The force curve of a ``length`` × ``width`` bias specimen along the grip displacements
    ``path`` at the moduli of a saved fit, with its 95 % band (:func:`force_band`: statistical,
    model-form and mesh parts, the size part when the fit carries its ``size_effects`` record,
    and whether the linearisation holds): a prediction of another specimen size."""
    exp = template(
        length,
        width,
        path,
        np.zeros((0, 2)),
        clamp=clamp,
        name=f"prediction {length:g} x {width:g} mm",
    )
    record = saved.get("size_effects")
    if record:
        model = sz.extended_model(model, {n.split(".")[0] for n in record["candidates"]})
    with ForwardModel(exp, model, h=h, comm=comm) as fm:
        return force_band(fm, saved)
