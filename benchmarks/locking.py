"""Intra-ply shear locking of the bias test: force over the three-zone limit, and the cost of a
converged grip force, on gmsh's unstructured mesh and on the fibre-aligned one.

The real specimen of the Cao et al. 2008 benchmark (230 × 115 mm, ±45°, position clamps),
``fibre_stretch`` (K) + ``shear`` (k_s = 0.022 N/mm), grip displacement 30 mm in 6 steps. Prints,
for each mesh kind, h and K (and the exact constraint on the aligned mesh), the grip force at
30 mm over the ideal three-zone force (Cao et al. 2008 eqs. 13, 18), the DOFs and the seconds;
then, for K = ``--cost-k``, the coarsest h of each kind whose force is within 1 % of the
converged value (the finest aligned result) and the ratios of DOFs and seconds.

    .venv/bin/python benchmarks/locking.py --out out/locking
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import rank0_print, write_json
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.experiments.three_zone import kinematic_force
from fabricsurf.model.terms import FibreStretch, Shear

H, W, K_S, UBAR, STEPS = 230.0, 115.0, 0.022, 30.0, 6


def run(mesh: str, h: float, K: float | None, comm) -> dict:
    fibres = (FibreStretch(inextensible=True) if K is None
              else FibreStretch(k_l=K, k_m=K))
    t0 = time.perf_counter()
    b = BiasExtension([fibres, Shear(k_s=K_S)], length=H, width=W, h=h, clamp="position",
                      mesh=mesh, comm=comm)
    try:
        res = b.run(UBAR, STEPS, verbose=False)
        force = res.force[-1]
    except RuntimeError:
        force = float("nan")
    ideal = float(kinematic_force(np.array([UBAR]), H, W, {"shear": {"k_s": K_S}})[0])
    dofs = b.problem.V.dofmap.index_map.size_global * b.problem.V.dofmap.index_map_bs
    return {"mesh": mesh, "h": h, "K": K, "force": force, "ratio": force / ideal, "dofs": dofs,
            "seconds": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out/locking")
    ap.add_argument("--levels", type=int, default=4, help="h = W/10 · 2^-i, i < levels")
    ap.add_argument("--stiffness", default="1e2,1e3,1e4,1e5", help="K values (N/mm)")
    ap.add_argument("--cost-k", type=float, default=1e4, help="K of the cost comparison")
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    hs = [W / 10 / 2**i for i in range(a.levels)]
    Ks = [float(k) for k in a.stiffness.split(",")]
    rows = []
    for mesh in ("unstructured", "aligned"):
        for h in hs:
            for K in Ks + ([None] if mesh == "aligned" else []):
                if mesh == "unstructured" and h < W / 40 and K is not None and K > 1e3:
                    continue
                r = run(mesh, h, K, comm)
                rows.append(r)
                rank0_print(comm, f"{mesh:12s} h = {h:7.4f}  K = {K if K else 'exact':>6}  "
                            f"force/three-zone {r['ratio']:8.4f}  dofs {r['dofs']:7d}  "
                            f"{r['seconds']:6.1f} s")
    cost = {}
    ref = [r for r in rows if r["mesh"] == "aligned" and r["K"] == a.cost_k][-1]["force"]
    for mesh in ("unstructured", "aligned"):
        ok = [r for r in rows if r["mesh"] == mesh and r["K"] == a.cost_k
              and abs(r["force"] / ref - 1) < 0.01]
        cost[mesh] = ok[0] if ok else None
        rank0_print(comm, f"K = {a.cost_k:g}: {mesh} within 1 % of the converged force: "
                    + (f"h = {ok[0]['h']:.4f}, {ok[0]['dofs']} dofs, {ok[0]['seconds']:.1f} s"
                       if ok else "not reached on these meshes"))
    if all(cost.values()):
        rank0_print(comm, f"unstructured / aligned at equal accuracy: dofs "
                    f"{cost['unstructured']['dofs'] / cost['aligned']['dofs']:.1f}, seconds "
                    f"{cost['unstructured']['seconds'] / cost['aligned']['seconds']:.1f}")
    write_json(comm, Path(a.out) / "locking.json", {"rows": rows, "cost": cost, "ref": ref})


if __name__ == "__main__":
    main()
