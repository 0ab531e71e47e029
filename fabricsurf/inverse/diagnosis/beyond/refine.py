"""A feature's judgement repeated one mesh finer, when its evidence has not settled under
refinement (:func:`.finer_mesh.settled`).

The finer mesh's rule (:mod:`.finer_mesh`) takes the feature's evidence on the h/2 check's
residuals. Where the mesh's error falls slowly (an unresolved boundary layer: the fibre-bending
layer √(A/k_l) of a lattice's bending springs, below the diagnosis's h and its h/2), the h/2
residuals still carry part of it, and a feature that stands there may fall one level further
(the crimp interchange on the held-out lattice bending null, the lattice's own bending form
known: Δχ² = 25.8 at h = 3 mm, 17.8 on the h/2 check's residuals, 16.0 needed). So the search's
model is solved again at h/2 with the feature at zero, fitted, checked against h/4, and the
feature scored, refitted and judged there by the same rule. It costs one fit and one h/2 check
a level finer, only for a feature that passed on the fit's mesh and whose evidence moved.
"""

from __future__ import annotations

from mpi4py import MPI

from fabricsurf.inverse.diagnosis.beyond.rule import judge_round
from fabricsurf.inverse.fitting.fit import fit
from fabricsurf.inverse.forward.runs import ForwardSet


def judge_finer(
    exps: list, model: list, free_names: list[str], feature, h: list[float], m: int, comm: MPI.Comm
) -> dict:
    """The feature (a Term class of the library, registered) judged at ``h`` / 2 on the
    search's final ``model`` (its ``free_names`` fitted), at the level of a family of ``m``
    features (it was chosen among them). Returns the record's ``at_finer_mesh``."""
    h2 = [x / 2 for x in h]
    with ForwardSet(exps, [*model, feature(k=0.0)], h=h2, comm=comm) as fs:
        idx = {feature.name: [i for i, (t, _) in enumerate(fs.params) if t.name == feature.name]}
        free = [fs.names.index(n) for n in free_names]
        cur = fit(fs, free, scale_start=False, space="linear")
        cur.check_mesh(fs)
        fs.set_values(cur.values)
        rj = fs.residuals(fs.run(sens=True))
        rows, _ = judge_round(fs, cur, free, idx, 1, rj, cur.mesh_difference, m)
    q = rows[0]
    out = {"h_mm": h2[0], "misfit": cur.misfit["combined"], "chi2_h": cur.chi2_h}
    if q.get("refit_chi2") is None:
        return out | {"refitted": False, "delta_chi2": q["score"], "significant": False}
    keys = ("delta_chi2", "f_statistic", "f_needed", "wald_p", "wald_p_needed")
    keys += ("finer_mesh_delta_chi2", "finer_mesh_f", "stands_on_finer_mesh", "significant")
    return out | {"refitted": True} | {k: q[k] for k in keys}
