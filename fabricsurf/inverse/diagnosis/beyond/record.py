"""The record of a search beyond the vocabulary: where a feature removes the misfit, its
share of the excess, the outcome's sentence and the text the command line prints."""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.diagnosis.beyond import features as ft
from fabricsurf.inverse.diagnosis.beyond.finer_mesh import leans_text
from fabricsurf.inverse.fitting.result import FitResult
from fabricsurf.inverse.forward import misfit as mf

NOTHING = "nothing beyond the vocabulary found"
REGIONS = 3
"""Regions per side of the specimen in the map of where a feature removes the misfit."""


def _where(exps: list[Experiment], before: list, after: list) -> list[dict]:
    """Where the refit removes the misfit: the share of Δχ² of each region (REGIONS ×
    REGIONS over the specimen) and of each experiment's force, largest first."""
    parts = []
    for e, pb, pa in zip(exps, before, after):
        rb, ra = mf.residuals(e, pb)[0], mf.residuals(e, pa)[0]
        gain = rb**2 - ra**2
        c = pb.u.shape[1]
        inside = np.isfinite(pb.u).all(axis=1)
        nf = c * int(inside.sum()) if e.has_field else 0
        if nf:
            X = e.X[inside]
            per_row = gain[:nf].reshape(-1, c).sum(axis=1)
            ix = np.minimum((X[:, 0] / e.length * REGIONS).astype(int), REGIONS - 1)
            iy = np.minimum((X[:, 1] / e.width * REGIONS).astype(int), REGIONS - 1)
            for i in range(REGIONS):
                for j in range(REGIONS):
                    parts.append(
                        {
                            "experiment": e.name,
                            "x_mm": [e.length * i / REGIONS, e.length * (i + 1) / REGIONS],
                            "y_mm": [e.width * j / REGIONS, e.width * (j + 1) / REGIONS],
                            "gain": float(per_row[(ix == i) & (iy == j)].sum()),
                        }
                    )
        if e.has_force:
            parts.append(
                {
                    "experiment": e.name,
                    "force": True,
                    "gain": float(gain[nf : nf + len(e.steps)].sum()),
                }
            )
    total = sum(q["gain"] for q in parts) or 1.0
    for q in parts:
        q["share"] = q.pop("gain") / total
    return sorted(parts, key=lambda q: -q["share"])


def _found(
    spec: ft.FeatureSpec, row: dict, rf: FitResult, cur: FitResult, exps: list, tie: list[str]
) -> dict:
    """The record of one significant feature (module docstring)."""
    name = f"{spec.name}.k"
    m = rf.uncertainty()["moduli"].get(
        name, {"value": float(rf.values[rf.names.index(name)]), "ci95": [None, None]}
    )
    after = rf.prediction if isinstance(rf.prediction, list) else [rf.prediction]
    before = cur.prediction if isinstance(cur.prediction, list) else [cur.prediction]
    return {
        "feature": spec.name,
        "proportional_to": spec.proportional_to,
        "energy": spec.energy,
        "reason": spec.reason,
        "share_of_excess": row["share_of_excess"],
        "modulus": {"name": "k", "value": m["value"], "ci95": m["ci95"], "unit": spec.unit},
        "chi2_before": cur.chi2,
        "refit_chi2": rf.chi2,
        "misfit_before": cur.misfit["combined"],
        "refit_misfit": rf.misfit["combined"],
        "wald_p": row["wald_p"],
        "wald_p_needed": row["wald_p_needed"],
        "f_statistic": row["f_statistic"],
        "f_needed": row["f_needed"],
        "indistinguishable_from": [t for t in tie if t != spec.name],
        "where": _where(exps, before, after),
        "source": spec.source,
    }


def share_text(share: float, dchi2: float) -> str:
    """ "61 % of the excess"; "all of the excess (107 %)" when the refit falls below ν; the χ²
    decrease when the model had no excess (a forced search)."""
    if not np.isfinite(share):
        return f"Δχ² = {dchi2:.3g} (the model had no excess)"
    return (
        f"all of the excess ({share * 100:.0f} %)"
        if share >= 1.0
        else f"{share * 100:.0f} % of the excess"
    )


def _outcome(found: list[dict], last: list[dict]) -> str:
    """The sentence of the module docstring (or why nothing, with the closest feature)."""
    if not found:
        tried = [q for q in last if q.get("refit_chi2") is not None]
        if not tried:
            best = max(last, key=lambda q: q["score"], default=None)
            return NOTHING + (
                f" (none refitted: the best, ∝ {ft.spec_of(best['effect']).proportional_to}, "
                f"removes Δχ² = {best['score']:.3g} linearised, under a quarter of the "
                "corrected rule's need)"
                if best
                else ""
            )
        q = tried[0]
        need = q["share_needed"]
        short = q["share_of_excess"] < need and q["wald_p"] < q["wald_p_needed"]
        closest = (
            f"{NOTHING} (closest: ∝ {ft.spec_of(q['effect']).proportional_to}, "
            f"{share_text(q['share_of_excess'], q['delta_chi2'])}"
        )
        if q.get("significant_on_this_mesh") and not q["significant"]:
            return f"{closest}; {leans_text(q)})"
        return f"{closest}, Wald p = {q['wald_p']:.2g} against {q['wald_p_needed']:.2g} needed" + (
            f"; under the {100 * need:.0f} % of the excess the rule needs)" if short else ")"
        )
    texts = []
    for f in found:
        alt = "".join(f" or ∝ {ft.spec_of(a).proportional_to}" for a in f["indistinguishable_from"])
        texts.append(
            f"an energy ∝ {f['proportional_to']}{alt} removes "
            + share_text(f["share_of_excess"], f["chi2_before"] - f["refit_chi2"])
            + (" (the data cannot tell them apart)" if alt else "")
        )
    return "; ".join(texts) + "; no named effect has this form"


def summary_lines(record: dict) -> list[str]:
    """The search as text (for the command line's output after the diagnosis)."""
    lines = [f"beyond the vocabulary: {record['outcome']}"]
    for f in record["found"]:
        lo, hi = f["modulus"]["ci95"]
        lines.append(
            f"  {f['energy']}: k = {f['modulus']['value']:.4g} {f['modulus']['unit']}"
            + (f", 95 % interval [{lo:.4g}, {hi:.4g}]" if lo is not None else "")
            + f"; misfit {f['misfit_before']:.4g} → {f['refit_misfit']:.4g}; "
            f"why a fabric could have it: {f['reason']}"
        )
        top = f["where"][0] if f["where"] else None
        if top and "x_mm" in top:
            lines.append(
                f"  most of it at x {top['x_mm'][0]:.3g}–{top['x_mm'][1]:.3g} mm, "
                f"y {top['y_mm'][0]:.3g}–{top['y_mm'][1]:.3g} mm "
                f"({top['share'] * 100:.0f} % of the reduction)"
            )
        lines.append('  as a term of your own (docs/usage.md, "Adding your own effect"):')
        lines += ["    " + s for s in f["source"].splitlines()]
    return lines
