"""Intra-ply shear locking of the bias test: the grip force over the ideal three-zone force
(Cao et al. 2008 eqs. 13 and 18) on specimens that admit no corner-to-corner fibre lattice, and
the cost of a converged grip force, per mesh kind and fibre treatment.

``--table`` (default): a family of specimen sizes, aspect ratios 2.2 to 3.8, none of which has a
corner-to-corner ±45° lattice at h = W/10; fibres ±45°, position clamps, ``fibre_stretch`` (K)
+ ``shear`` (k_s = 0.022 N/mm), grip displacement 0.13·L in 6 steps. For every size and
K/k_s (and the exact constraint) it prints the force ratio at the last step on the default mesh
(``auto``: two fibre lattices joined by a band, geometry/lattice_pair.py) and, with
``--compare``, on gmsh's mesh with fully integrated (today's fallback) and reduced fibre terms.

``--zones``: where no lattice serves (kind ``zones``: gmsh with the corner fibre lines as edges):
the 187 × 119 specimen at h = 17 and 25 against the aligned mesh at h = 15, and fibres at
30°/−60° on 250 × 115 at W/10 against W/20, with gmsh's plain mesh for comparison (ū = 20 mm in
4 steps).

``--exact``: exact inextensibility (``FibreStretch(inextensible=True)``) on the table's sizes and
on sizes with an exact corner-to-corner lattice (aligned): the force ratio, or NaN where a step
failed.

``--cost``: the 250 × 115 specimen (no corner-to-corner lattice) at K = ``--cost-k``: h halved
from W/10, the coarsest h of the default mesh and of gmsh's within 1 % of the converged force
(the finest default result), DOFs and seconds.

    .venv/bin/python benchmarks/locking.py --out out/locking [--compare|--exact|--cost|--zones]
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import write_json
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.experiments.three_zone import kinematic_force
from fabricsurf.log import configure, detail, rank0
from fabricsurf.model.terms import FibreStretch, Shear

logger = logging.getLogger(__name__)

K_S, STEPS = 0.022, 6
SIZES = (
    (250, 115),
    (320, 100),
    (350, 120),
    (245, 110),
    (270, 95),
    (300, 130),
    (215, 70),
    (380, 110),
    (290, 85),
    (260, 75),
    (400, 105),
    (230, 103),
)
"""Length × width (mm): no corner-to-corner ±45° lattice within 0.05° near h = W/10."""
RATIOS = (1e2, 1e3, 1e4, 1e6, 1e9)
"""K/k_s. Exact inextensibility has its own study (``--exact``)."""
EXACT_SIZES = SIZES + ((230, 115), (253, 115), (270, 115), (345, 115), (460, 115))
"""The table's sizes and five with a corner-to-corner lattice at W/10 or a centre zone of
other lengths."""
VARIANTS = {
    "default": ("auto", "auto"),
    "gmsh full": ("unstructured", "full"),
    "gmsh reduced": ("unstructured", "reduced"),
}
"""name: (mesh, fibre_treatment)."""


def run(
    length: float, width: float, h: float, ratio: float | None, mesh: str, treatment: str, comm
) -> dict:
    """One bias run; the force ratio at the last step (NaN if a step failed)."""
    fibres = (
        FibreStretch(inextensible=True)
        if ratio is None
        else FibreStretch(k_l=ratio * K_S, k_m=ratio * K_S)
    )
    t0 = time.perf_counter()
    ubar = 0.13 * length
    with detail():  # the run's notes and steps (its warnings stay warnings)
        b = BiasExtension(
            [fibres, Shear(k_s=K_S)],
            length=length,
            width=width,
            h=h,
            clamp="position",
            mesh=mesh,
            fibre_treatment=treatment,
            comm=comm,
        )
        try:
            force = b.run(ubar, STEPS).force[-1]
        except RuntimeError:
            force = float("nan")
    ideal = float(kinematic_force(np.array([ubar]), length, width, [Shear(k_s=K_S)])[0])
    dofs = b.problem.V.dofmap.index_map.size_global * b.problem.V.dofmap.index_map_bs
    return {
        "length": length,
        "width": width,
        "h": h,
        "ratio_K": ratio,
        "mesh": mesh,
        "treatment": treatment,
        "kind": b.discretisation["mesh_kind"],
        "force": force,
        "force_ratio": force / ideal,
        "dofs": dofs,
        "seconds": time.perf_counter() - t0,
    }


def table(variants: list[str], sizes: int, comm) -> list[dict]:
    rows = []
    for length, width in SIZES[:sizes]:
        for name in variants:
            mesh, treatment = VARIANTS[name]
            for ratio in RATIOS:
                r = run(length, width, width / 10, ratio, mesh, treatment, comm)
                rows.append(r | {"variant": name})
                rank0(
                    logger,
                    comm,
                    f"{length:4g} x {width:4g}  {name:13s} {r['kind']:13s} "
                    f"K/k_s = {ratio:6.0e}  force/three-zone "
                    f"{r['force_ratio']:10.4f}  {r['seconds']:5.1f} s",
                )
    return rows


def exact(comm) -> list[dict]:
    """Exact inextensibility on :data:`EXACT_SIZES` at h = W/10 (module docstring)."""
    rows = []
    for length, width in EXACT_SIZES:
        r = run(length, width, width / 10, None, "auto", "auto", comm)
        rows.append(r)
        rank0(
            logger,
            comm,
            f"{length:4g} x {width:4g}  exact  {r['kind']:13s} force/three-zone "
            f"{r['force_ratio']:12.8f}  {r['seconds']:5.1f} s",
        )
    return rows


def cost(K: float, levels: int, comm) -> dict:
    """DOFs and seconds to reach 1 % of the converged force on the 250 × 115 specimen."""
    rows = {
        name: [
            run(250.0, 115.0, 11.5 / 2**i, K / K_S, *VARIANTS[name], comm) for i in range(levels)
        ]
        for name in ("default", "gmsh full")
    }
    ref = rows["default"][-1]["force"]
    out = {"reference_force": ref}
    for name, rs in rows.items():
        for r in rs:
            rank0(
                logger,
                comm,
                f"{name:10s} h = {r['h']:7.4f}  force {r['force']:10.4f} N  "
                f"/ converged {r['force'] / ref:9.4f}  dofs {r['dofs']:7d}  "
                f"{r['seconds']:6.1f} s",
            )
        ok = [r for r in rs if abs(r["force"] / ref - 1) < 0.01]
        out[name] = ok[0] if ok else None
        rank0(
            logger,
            comm,
            f"K = {K:g}: {name} within 1 % of the converged force: "
            + (
                f"h = {ok[0]['h']:.4g}, {ok[0]['dofs']} dofs, {ok[0]['seconds']:.1f} s"
                if ok
                else "not reached at h >= " + f"{rs[-1]['h']:.4g}"
            ),
        )
    return out


def zones(comm) -> list[dict]:
    """Force ratios on the corner-line meshes (module docstring, ``--zones``)."""
    cases = [
        (
            (187.0, 119.0),
            (45.0, -45.0),
            (15.0, "aligned"),
            [(17.0, "auto"), (25.0, "auto"), (17.0, "unstructured")],
        ),
        ((250.0, 115.0), (30.0, -60.0), (5.75, "auto"), [(11.5, "auto"), (11.5, "unstructured")]),
    ]
    rows = []
    for (length, width), angles, ref, others in cases:
        for ratio in RATIOS:
            f = {}
            for h, mesh in [ref, *others]:
                with detail():
                    b = BiasExtension(
                        [FibreStretch(k_l=ratio * K_S, k_m=ratio * K_S), Shear(k_s=K_S)],
                        length=length,
                        width=width,
                        h=h,
                        clamp="position",
                        fibre_angles=angles,
                        mesh=mesh,
                        comm=comm,
                    )
                    try:
                        f[(h, b.discretisation["mesh_kind"])] = b.run(20.0, 4).force[-1]
                    except RuntimeError:
                        f[(h, b.discretisation["mesh_kind"])] = float("nan")
            base = next(iter(f.values()))
            ratios = ", ".join(f"{k} h = {h:g}: {v / base:.4f}" for (h, k), v in f.items())
            rank0(
                logger, comm, f"{length:g} x {width:g} at {angles}, K/k_s = {ratio:6.0e}: " + ratios
            )
            rows.append(
                {
                    "length": length,
                    "width": width,
                    "angles": angles,
                    "ratio_K": ratio,
                    "forces": {f"{k} h={h:g}": v for (h, k), v in f.items()},
                }
            )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out/locking")
    ap.add_argument(
        "--compare",
        action="store_true",
        help="also gmsh's mesh with full and with reduced fibre terms",
    )
    ap.add_argument("--cost", action="store_true", help="the cost table instead")
    ap.add_argument("--zones", action="store_true", help="the corner-line meshes instead")
    ap.add_argument("--exact", action="store_true", help="exact inextensibility instead")
    ap.add_argument("--cost-k", type=float, default=1e4, help="K of the cost table (N/mm)")
    ap.add_argument("--sizes", type=int, default=len(SIZES), help="the first N sizes only")
    ap.add_argument("--levels", type=int, default=3, help="h = W/10 · 2^-i, i < levels")
    a = ap.parse_args()
    configure()  # the messages: on rank 0, at PROGRESS
    comm = MPI.COMM_WORLD
    if a.zones:
        result = {"zones": zones(comm)}
    elif a.exact:
        result = {"exact": exact(comm)}
    elif a.cost:
        result = {"cost": cost(a.cost_k, a.levels, comm)}
    else:
        result = {"rows": table(list(VARIANTS) if a.compare else ["default"], a.sizes, comm)}
    name = (
        "locking_zones.json"
        if a.zones
        else "locking_exact.json"
        if a.exact
        else "locking_cost.json"
        if a.cost
        else "locking.json"
    )
    write_json(comm, Path(a.out) / name, result)


if __name__ == "__main__":
    main()
