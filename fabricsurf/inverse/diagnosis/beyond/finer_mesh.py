"""A feature must stand on the finer mesh too: the search's rule against the mesh's own error.

The h/2 check measures the discretisation error as one number, χ²_h, and the adequacy test
compares it with the whole excess. A feature's test looks in one direction, and a coarse mesh's
error is systematic: where its sensitivities point along that error, a feature takes it up and
passes the corrected rule on data that need nothing. Measured on the held-out lattice null with
geodesic bending (±40°, docs/lattice_effects.md): the crimp interchange removed Δχ² = 22.6 at
h = 3 mm, 13.8 at 1.5 mm and 5.7 at 0.75 mm, against 16–18 needed, while the bending modulus
rose towards the lattice's. The fibre-bending boundary layer, √(A_g/k_l) ≈ 0.6 mm, was not
resolved: the "missing energy" was the mesh's.

The h/2 check gives the residual difference d = r_{h/2} − r_h at the fitted moduli
(:func:`~fabricsurf.inverse.uncertainty.systematic.mesh_difference`), so the feature's linearised
reduction can be taken again on the finer mesh's residuals r + d with the same sensitivities
(the direction a feature points in changes little under refinement; its size is what the
mesh's error shifts). The refit's Δχ² and F are scaled by the ratio of the two linearised
reductions, and the F must still pass the corrected test. The rule applies where d is at
hand: the first round, at the diagnosis's final model (a later round's model would need an h/2
run of its own).
"""

from __future__ import annotations

import numpy as np

from fabricsurf.inverse.diagnosis.ranking import scores


def finer_reductions(
    r: np.ndarray, d: np.ndarray, Jr: np.ndarray, vals: np.ndarray, free: list[int], cand: dict
) -> dict[str, float]:
    """Each feature's linearised χ² reduction on the finer mesh's residuals ``r + d``."""
    return {c: s for c, (s, _) in scores(r + d, Jr, vals, free, cand).items()}


def stands_on_finer_mesh(row: dict, finer: float) -> dict:
    """The rule for a judged ``row`` (its linearised ``score``, refit ``delta_chi2`` and F):
    both scaled by ``finer`` / score, the F against the row's ``f_needed``. Returns the parts
    the record keeps."""
    ratio = finer / row["score"] if row["score"] > 0 else 0.0
    F = row["f_statistic"] * ratio
    return {
        "finer_mesh_score": float(finer),
        "finer_mesh_delta_chi2": float(row["delta_chi2"] * ratio),
        "finer_mesh_f": float(F),
        "stands_on_finer_mesh": bool(F > row["f_needed"]),
    }


def settled(row: dict) -> bool:
    """Whether a feature that stands on the finer mesh would still stand if one more halving
    shifted its evidence as much again: with a = √score and b = √finer_mesh_score − a (the
    feature's projection and its shift per halving), the F scaled by ((a + 2b)/a)² passes.
    An error that falls as h (the slowest rate of a resolved solution) leaves r + 2d at h → 0;
    a shift that grows the evidence settles it. Otherwise :mod:`.refine` judges the feature
    again one mesh finer. A row without the finer mesh's numbers (a later round) is taken as
    it stands."""
    if "finer_mesh_score" not in row:
        return True
    a = np.sqrt(row["score"])
    b = np.sqrt(row["finer_mesh_score"]) - a
    if b >= 0.0:
        return True
    return bool(
        a + 2.0 * b > 0.0 and row["f_statistic"] * ((a + 2.0 * b) / a) ** 2 > row["f_needed"]
    )


def leans_text(q: dict) -> str:
    """Why a feature that passed on the fit's mesh was not found."""
    again = q.get("at_finer_mesh")
    if again is None:
        return (
            f"it removes Δχ² = {q['delta_chi2']:.3g} on this mesh but "
            f"{q['finer_mesh_delta_chi2']:.3g} on the h/2 check's (F = {q['finer_mesh_f']:.3g} "
            f"against {q['f_needed']:.3g} needed): part of its evidence is the discretisation "
            "error; refine h to tell"
        )
    there = f"judged again at h = {again['h_mm']:.3g} mm it removes {again['delta_chi2']:.3g}"
    if not again["refitted"]:
        there += " linearised, under a quarter of the need"
    elif again["f_statistic"] <= again["f_needed"]:
        there += f" (F = {again['f_statistic']:.3g} against {again['f_needed']:.3g} needed)"
    elif again["wald_p"] >= again["wald_p_needed"]:
        there += f" (Wald p = {again['wald_p']:.2g} against {again['wald_p_needed']:.2g} needed)"
    else:
        there += (
            f", and {again['finer_mesh_delta_chi2']:.3g} on that mesh's h/2 check (F = "
            f"{again['finer_mesh_f']:.3g} against {again['f_needed']:.3g} needed)"
        )
    return (
        f"it removes Δχ² = {q['delta_chi2']:.3g} on this mesh; {there}: part of its evidence "
        "is the discretisation error; refine h further to tell"
    )
