# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Bias extension: continuum versus spring network (seed 000)
#
# A 187 mm × 119 mm fabric with fibres at ±45° to the load is clamped at x = 0 and pulled at
# x = length (seed 000 eq. 7):
#
#   u = 0, ∂u/∂x = 0 at x = 0;     u = ū e_x, ∂u/∂x = 0 at x = length,
#
# the zero normal derivative imposed weakly (Nitsche) in the second-gradient continuum and, in
# the lattice, by holding two node layers (seed 000 Table 1). Two comparisons:
#
# **(a) Hencky.** The continuum `fibre_stretch + shear + geodesic_bending`,
#
#   W = ½k_l[(λ−1)² + (μ−1)²] + ½k_s γ² + ½A_g[(λ²η_l)² + (μ²η_m)²],
#
# against the Hencky fabric lattice (nodes at fibre crossings, spacing ε) whose stiffnesses come
# from the micro–macro identification of `docs/network.md`: k_e = k_l, k_sh = k_s ε², k_b = A_g.
# The spacing is ε = √2·w with w = 8.5 mm / k the x-distance between node columns, so that the
# node columns tile the specimen (length = 22k·w, width = 14k·w) and the points A, B of seed
# 000 Fig. 4 are nodes.
#
# **(b) Bi-pantographic.** The homogenised energy of seed 000 eq. (2) (`fabricsurf.model.materials`,
# K_S = 34 N/m, K_E = 0.33 J, K_F = 0.9 J of Table 3) against the 13-node-cell lattice of
# seed 000 §3 with the Table 3 micro parameters (k_E = 335 N/m, k_S = 9.36, k_F = 46.2 N·mm).
# The two parameter sets were fitted *independently* to the experiment in seed 000, so the
# models are not an identification of each other. The numerical homogenisation of the lattice
# (`fabricsurf.network.homogenize`: one pantographic beam, axis nodes on χ, side nodes relaxed)
# measures what the micro set corresponds to: K_S = 0.0145 N/mm (Table 3: 0.034) and a
# geodesic-bending coefficient a_θ(1) = 9.56 N·mm (Table 3's K_E K_F/(K_E + 18K_F) = 17.97):
# the Table 3 continuum is about twice as stiff in both terms that carry the bias force. A
# third run, **bipantographic_identified**, therefore gives eq. (2) the identified K_S and
# a_θ (K_F = a_θ, K_E → ∞, which also makes a_θ independent of ρ as it is for the lattice,
# within ~6 %) against the same lattice. What eq. (2) cannot match is reported, not hidden: the
# lattice's stretch-gradient coefficient a_ρ(1) ≈ 0.3 N·mm (2.4 with another O(ε) sampling
# convention) lies below eq. (2)'s lower bound
# 3a_θ(1) = 28.7 N·mm for any positive K_E, K_F.
#
# Quantities (seed 000 Figs. 9–11): grip reaction force vs ū; shear angle γ at A (centre of the
# square on the clamped side) and at B (specimen centre) vs ū; deformed configurations —
# continuum χ(x_i, y_j) against lattice nodes p_ij (eq. 3); the y-stretch ρ_y (eq. 4, the
# stretch along the second fibre family M, = μ). Lattice angles at A and B use the central
# differences of eq. (5) at the node there: γ = π/2 − arccos(a·b/|a||b|) with
# a = p_{i+1,j} − p_{i−1,j}, b = p_{i,j+1} − p_{i,j−1}.
#
# Checks: (1) continuum and Hencky lattice agree within the measured differences; (2) the
# three zones of the bias test (near-rigid triangles at the clamps, half-sheared zones, fully
# sheared centre); (3) the grip force converges under mesh refinement (rate reported); (4)
# bi-pantographic: kinematics agree with Table 3, the force factor is removed by the
# identified moduli down to the clamp-offset effect, which brackets the lattice force.
#
# Run: `mpirun -n 2 python demos/demo_bias_extension.py --out DIR` (`--quick` for a coarse,
# fast run).

# %%
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import rank0_print, write_json
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.model.materials import bipantographic
from fabricsurf.model.terms import FibreStretch, GeodesicBending, Shear
from fabricsurf.network import hencky_lattice, lattice_from_continuum, solve_steps
from fabricsurf.network.bipantographic import EPS_B, TABLE3, bipantographic_lattice
from fabricsurf.network.homogenize import identify_macro
from fabricsurf.network.micromacro import grid_fields
from fabricsurf.studies.bias_convergence import force_convergence

LENGTH, WIDTH = 187.0, 119.0  # mm
EPS_EXACT = LENGTH / (11 * math.sqrt(2))  # 12.0208 mm: 11 x 7 cells of side √2 ε = 17 mm tile
# the 187 x 119 mm specimen exactly (seed 000 rounds it to ε = 12.02 mm)
IDENTIFIED_K_E = 1e6  # N·mm: "K_E → ∞" (a_θ(1) = K_F / (1 + 18 K_F/K_E): within 2e-4 of K_F)
HENCKY_MODULI = {"k_l": 30.0, "k_s": 0.5, "A_g": 40.0}  # N/mm, N/mm, N·mm (bias.default_model)


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("out/bias_extension"))
    ap.add_argument("--h", type=float, default=4.0, help="continuum mesh size (mm)")
    ap.add_argument("--steps", type=int, default=10, help="load steps")
    ap.add_argument("--ubar-frac", type=float, default=0.25,
                    help="Hencky comparison: ū_max / length")
    ap.add_argument("--bip-ubar-frac", type=float, default=0.15,
                    help="bi-pantographic comparison: ū_max / length (the homogenised energy "
                         "reaches its geometric limit ρ cos γ = 1 near 0.155, see materials.py)")
    ap.add_argument("--lattice-k", type=int, default=6,
                    help="Hencky lattice refinement: column pitch w = 8.5 mm / k, ε = √2 w")
    ap.add_argument("--conv-levels", type=str, default="2,4,8",
                    help="refinement levels of the force-convergence study: graded meshes of "
                         "11·level × 7·level crossed squares (square side 17 mm / level)")
    ap.add_argument("--conv-grading", type=float, default=0.6,
                    help="edge grading of the convergence meshes (0: uniform)")
    ap.add_argument("--conv-steps", type=int, default=5)
    ap.add_argument("--skip-bip", action="store_true")
    ap.add_argument("--quick", action="store_true",
                    help="coarse and fast (tests): h = 8, 4 steps, ū ≤ 10%%, k = 2, levels 2,4,8")
    a = ap.parse_args(argv)
    if a.quick:
        a.h, a.steps, a.ubar_frac, a.bip_ubar_frac = 8.0, 4, 0.10, 0.10
        a.lattice_k, a.conv_levels, a.conv_steps = 2, "2,4,8", 2
    return a


# %% [markdown]
# ## Lattice helpers
#
# The lattice is pure numpy/scipy: it is solved on rank 0 and the node positions broadcast.

# %%
def solve_lattice(lat, ubar_max: float, steps: int, comm: MPI.Comm) -> dict:
    """Positions and grip force (x) at ū_k = k ū_max / steps, k = 1..steps (on every rank)."""
    data = None
    if comm.rank == 0:
        t0 = time.perf_counter()
        res = solve_steps(lat.net, lat.bias_bcs(ubar_max), steps,
                          reaction_sets={"grip": lat.grip})
        keep = [r for r in res if abs(r.t * steps - round(r.t * steps)) < 1e-9]
        data = {"ubar": [r.t * ubar_max for r in keep], "x": [r.x for r in keep],
                "force": [float(r.reactions["grip"][0]) for r in keep],
                "seconds": time.perf_counter() - t0}
    return comm.bcast(data, root=0)


def node_at(lat, point) -> tuple[int, int]:
    """Grid index (a, b) of the node at ``point`` (mm); it must be a node (within 1e-6 ε)."""
    X = lat.net.X
    ok = lat.grid >= 0
    d = np.where(ok, np.linalg.norm(X[np.maximum(lat.grid, 0)] - point, axis=-1), np.inf)
    a, b = np.unravel_index(np.argmin(d), d.shape)
    assert d[a, b] < 1e-6 * lat.spacing, f"no lattice node at {point} (nearest {d[a, b]:.3g} mm)"
    return int(a), int(b)


def node_shear_deg(lat, x: np.ndarray, ab: tuple[int, int]) -> float:
    """Shear angle at grid node (a, b) from central differences of eq. (5), degrees."""
    a, b = ab
    g = lat.grid
    da = x[g[a + 1, b]] - x[g[a - 1, b]]
    db = x[g[a, b + 1]] - x[g[a, b - 1]]
    c = da @ db / (np.linalg.norm(da) * np.linalg.norm(db))
    return math.degrees(math.pi / 2 - math.acos(np.clip(c, -1, 1)))


# %% [markdown]
# ## One comparison
#
# The continuum runs with `BiasExtension` (XDMF `bias.xdmf` in a sub-directory); after each
# step the continuum u, λ, μ, γ are sampled at the lattice nodes of the micro–macro grid
# (`eval_points`, reduced over ranks).

# %%
def compare(name: str, model, lat, ubar_max: float, args, comm: MPI.Comm,
            latres: dict | None = None) -> tuple[dict, dict]:
    out = args.out / name
    nodes = lat.grid[lat.grid >= 0]
    # node positions rounded onto the specimen (nodes on the edges can be 1e-13 mm outside)
    Xn = np.clip(lat.net.X[nodes], 0.0, [LENGTH, WIDTH])
    rank0_print(comm, f"[{name}] lattice: {lat.net.n_nodes} nodes, {len(nodes)} grid nodes, "
                      f"eps = {lat.spacing:.4f} mm")
    if latres is None:
        latres = solve_lattice(lat, ubar_max, args.steps, comm)
        rank0_print(comm, f"[{name}] lattice solved in {latres['seconds']:.1f} s; forces "
                          + " ".join(f"{f:.3f}" for f in latres["force"]))
    bias = BiasExtension(model, LENGTH, WIDTH, h=args.h, comm=comm)
    samples = []

    Z = np.array(list(ZONE_POINTS.values()))

    def on_step(k, ubar):
        f = bias.fibre_fields_at(np.vstack([Xn, Z]))
        samples.append({"u": bias.displacement_at(Xn), "f": f[:len(Xn)],
                        "zones": np.degrees(f[len(Xn):, 2])})

    cres = bias.run(ubar_max, args.steps, out=out, on_step=on_step)
    n = min(len(cres.ubar), len(latres["ubar"]))
    assert n == args.steps, f"{name}: only {n} of {args.steps} steps converged"
    assert np.allclose(cres.ubar, latres["ubar"])
    iA, iB = node_at(lat, bias.points[0]), node_at(lat, bias.points[1])
    lat_A = [node_shear_deg(lat, x, iA) for x in latres["x"]]
    lat_B = [node_shear_deg(lat, x, iB) for x in latres["x"]]
    fc, fl = np.array(cres.force), np.array(latres["force"])
    rms = [float(np.sqrt(np.mean(np.sum((x[nodes] - (Xn + s["u"])) ** 2, axis=1))))
           for x, s in zip(latres["x"], samples)]
    assert all(np.isfinite(rms)), f"{name}: a lattice node is outside the continuum mesh"
    summary = {
        "force_rel_diff": float(np.max(np.abs(fc - fl) / np.abs(fl))),
        "angle_A_max_diff_deg": float(np.max(np.abs(np.array(cres.angle_A_deg) - lat_A))),
        "angle_B_max_diff_deg": float(np.max(np.abs(np.array(cres.angle_B_deg) - lat_B))),
        "position_rms_diff": float(max(rms)),
        "curves": {"ubar": cres.ubar, "force_continuum": cres.force,
                   "force_lattice": latres["force"],
                   "angle_A_continuum_deg": cres.angle_A_deg, "angle_A_lattice_deg": lat_A,
                   "angle_B_continuum_deg": cres.angle_B_deg, "angle_B_lattice_deg": lat_B,
                   "position_rms_diff": rms},
    }
    rank0_print(comm, f"[{name}] continuum {cres.seconds:.1f} s; force_rel_diff = "
                      f"{summary['force_rel_diff']:.4f}, angle A/B max diff = "
                      f"{summary['angle_A_max_diff_deg']:.2f}/{summary['angle_B_max_diff_deg']:.2f}"
                      f" deg, position rms (max over ū) = {summary['position_rms_diff']:.3f} mm")
    lam_max = float(np.nanmax(samples[-1]["f"][:, :2]))
    rank0_print(comm, f"[{name}] max fibre stretch at the nodes at ū_max: {lam_max:.4f}")
    zones = {kk: [float(sm["zones"][i]) for sm in samples] for i, kk in enumerate(ZONE_POINTS)}
    zones["ubar"] = list(cres.ubar)
    zones["ideal_centre_deg"] = [ideal_centre_shear_deg(u) for u in cres.ubar]
    extra = {"zones": zones, "lat": latres, "samples": samples, "nodes": nodes, "Xn": Xn,
             "bias": bias, "res": cres, "lam_max": lam_max}
    return summary, extra


# %% [markdown]
# ## Three zones of the bias test
#
# For inextensible fibres (a pin-jointed net), the material points whose fibres both reach a
# clamp do not deform (triangles with the clamped short side as base, apex at A), those with one
# fibre reaching a clamp shear half as much as the centre, and the central zone (the rhombus with
# vertices A, (length − width/2, width/2) and (length/2, width/2 ± (length − width)/2)) shears
# uniformly. Its diagonal along the load is length − width in the reference and
# length − width + ū deformed, while its sides (along the fibres) keep their length, so
#
#   cos θ = (length − width + ū) / (√2 (length − width)),   γ_C = π/2 − 2θ,
#
# the standard bias-extension kinematics (Cao et al., Composites A 39 (2008) 1037; Boisse et al.,
# Composites A 100 (2017) 43, review of the bias-extension test). The ideal angles are a limit
# (zero bending stiffness, inextensible fibres): the continuum has a bending boundary layer
# √(A_g/k_s) ≈ 9 mm wide at every zone boundary and extensible fibres, so we check the pattern:
# γ at the centroid of the clamp triangle (width/6, width/2) ≪ γ_B, and γ at the centroid of a
# half-sheared zone (width/2, width/6) ≈ γ_B/2, at ū ≤ 10 % of the length. Beyond, the ideal
# centre reaches full shear (γ_C = 90° at ū = (√2 − 1)(length − width) = 28.2 mm): the fibres
# must stretch (λ up to 1.32 at ū = 25 %, k_l/k_s = 60) and the zones blur (measured at
# ū = 46.75 mm: 8.4°, 36.4°, 49.6°).

# %%
def ideal_centre_shear_deg(ubar: float, length: float = LENGTH, width: float = WIDTH) -> float:
    c = (length - width + ubar) / (math.sqrt(2) * (length - width))
    return math.degrees(math.pi / 2 - 2 * math.acos(min(c, 1.0)))


ZONE_CHECK_FRAC = 0.10  # the zone check is made at ū ≤ 10 % of the length (see above)
ZONE_POINTS = {"clamp_triangle": (WIDTH / 6, WIDTH / 2), "half_sheared": (WIDTH / 2, WIDTH / 6),
               "centre_B": (LENGTH / 2, WIDTH / 2)}


def zones_at(zones: dict, ubar: float) -> dict:
    """The zone angles (deg) at the last step with ū ≤ ``ubar``."""
    k = max(i for i, u in enumerate(zones["ubar"]) if u <= ubar + 1e-9)
    return {kk: v[k] for kk, v in zones.items()}


# %% [markdown]
# ## Mesh convergence of the grip force
#
# Continuum (a) at ū_max on nested meshes of 11·n × 7·n crossed squares (n = 2, 4, 8: square
# side 8.5, 4.25, 2.1 mm), graded towards the edges (`geometry.specimen.graded`, spacing 0.4×
# nominal at the edges, 1.6× in the middle). Grading matters here: the gradient clamp makes a
# fibre-bending boundary layer of width √(A_g/k_l) ≈ 1.2 mm, and the clamp corners (clamped
# edge meets free edge) are singular points of the second-gradient solution. On uniform gmsh
# meshes h = 16, 8, 4 mm the force differences changed sign (pre-asymptotic); on uniform
# structured meshes they grew until h ≈ 2 mm, then fell at rate 0.63 (h = 2.1 → 1.06 mm,
# 340 s on one rank). With F_n the force on level n and d_n = |F_n − F_2n|, the observed rate
# is log2(d_n / d_2n) and the finest force's error is estimated as d / (2^rate − 1)
# (`fabricsurf.studies.bias_convergence.force_convergence`; benchmarks/bias_convergence.py
# adds level 16).

# %%
def identified_model(ident: dict) -> list:
    """Eq. (2) with the lattice's K_S and a_θ(1): K_F = a_θ, K_E → ∞ (a_θ(ρ) ≡ K_F)."""
    return bipantographic(K_S=ident["K_S"], K_E=IDENTIFIED_K_E, K_F=ident["a_theta"])


def clamp_offset_bracket(ident: dict, latres: dict, args, comm: MPI.Comm) -> dict:
    """The identified continuum on the free length between the held lattice strips.

    The lattice clamps hold the vertex columns i = 0, 1 (and N − 1, N): a strip √2 ε = 17 mm
    wide at each end, where the continuum clamps a line. With ε this large (11 cells along the
    specimen) the clamp position is an O(1) effect; the continuum on [0, L] and on the free
    length L − 2√2 ε bracket it. Run to 80 % of ū_max (the short specimen reaches eq. 2's
    geometric limit ρ cos γ = 1 earlier).
    """
    n = max(1, int(0.8 * args.steps))
    short = LENGTH - 2 * math.sqrt(2) * EPS_EXACT
    b = BiasExtension(identified_model(ident), short, WIDTH, h=args.h, comm=comm)
    r = b.run(latres["ubar"][n - 1], n, verbose=False)
    rank0_print(comm, f"[bipantographic_identified] free length {short:.1f} mm: forces "
                      + " ".join(f"{f:.3f}" for f in r.force))
    return {"free_length_mm": short, "ubar": r.ubar, "force_free_length": r.force,
            "force_lattice": latres["force"][:n]}


def identification_summary(ident: dict) -> dict:
    """The identification as JSON: NaN (no K_E, K_F fits eq. 2) becomes null."""
    out = {k: (float(v) if math.isfinite(v) else None) for k, v in ident.items()
           if k in ("K_S", "a_theta", "a_rho", "K_E", "K_F")}
    return out | {"eq2_feasible": bool(ident["feasible"]), "K_E_used_Nmm": IDENTIFIED_K_E,
                  "K_F_used_Nmm": float(ident["a_theta"])}


def hencky_model():
    m = HENCKY_MODULI
    return [FibreStretch(k_l=m["k_l"], k_m=m["k_l"]), Shear(k_s=m["k_s"]),
            GeodesicBending(A_g=m["A_g"])]


# %% [markdown]
# ## Figures (rank 0)

# %%
def figures(out: Path, results: dict, extras: dict, conv: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    fig, ax = plt.subplots(len(names), 3, figsize=(14, 3.8 * len(names)), squeeze=False)
    for row, nm in enumerate(names):
        c = results[nm]["curves"]
        for col, (key, lab) in enumerate([("force", "reaction force (N)"),
                                          ("angle_A", "shear angle at A (deg)"),
                                          ("angle_B", "shear angle at B (deg)")]):
            suf = "" if key == "force" else "_deg"
            a = ax[row, col]
            a.plot(c["ubar"], c[f"{key}_continuum{suf}"], "o-", label="continuum")
            a.plot(c["ubar"], c[f"{key}_lattice{suf}"], "s--", label="lattice")
            br = extras.get(nm, {}).get("clamp_offset")
            if key == "force" and br:
                a.plot(br["ubar"], br["force_free_length"], "^:", label="continuum, free length "
                       f"{br['free_length_mm']:.0f} mm")
            a.set(xlabel="ū (mm)", ylabel=lab, title=f"{nm}")
            a.legend()
    fig.tight_layout()
    fig.savefig(out / "curves.png", dpi=110)
    plt.close(fig)

    for nm, ex in extras.items():
        lat, nodes, Xn = ex["lat_obj"], ex["nodes"], ex["Xn"]
        steps = len(ex["samples"])
        ks = sorted({max(0, steps // 3 - 1), max(0, 2 * steps // 3 - 1), steps - 1})
        fig, ax = plt.subplots(1, len(ks), figsize=(5.5 * len(ks), 4.2), squeeze=False)
        for a, k in zip(ax[0], ks):
            xl = ex["lat"]["x"][k][nodes]
            xc = Xn + ex["samples"][k]["u"]
            a.plot(*xl.T, "o", ms=2.5, mfc="none", color="C1", label="lattice p_ij")
            a.plot(*xc.T, "+", ms=3, color="C0", label="continuum χ(x_i, y_j)")
            a.set(title=f"{nm}: ū = {ex['lat']['ubar'][k]:.1f} mm", xlabel="x (mm)",
                  ylabel="y (mm)")
            a.set_aspect("equal")
        ax[0, 0].legend(loc="upper left", fontsize=7)
        fig.tight_layout()
        fig.savefig(out / f"deformed_{nm}.png", dpi=110)
        plt.close(fig)

        xk = ex["lat"]["x"][-1]
        gf = grid_fields(lat.grid, lat.net.X, xk, lat.spacing)
        okg = lat.grid >= 0
        rho_lat = gf["rho_y"][okg]
        pos_lat = xk[lat.grid[okg]]
        rho_c = ex["samples"][-1]["f"][:, 1]
        pos_c = Xn + ex["samples"][-1]["u"]
        vmin = float(np.nanmin([np.nanmin(rho_lat), np.nanmin(rho_c)]))
        vmax = float(np.nanmax([np.nanmax(rho_lat), np.nanmax(rho_c)]))
        fig, ax = plt.subplots(1, 2, figsize=(12, 4.2))
        for a, pos, val, t in ((ax[0], pos_lat, rho_lat, "lattice (eq. 4)"),
                               (ax[1], pos_c, rho_c, "continuum μ")):
            sc = a.scatter(*pos.T, c=val, s=12 if len(pos) > 2000 else 40, cmap="viridis",
                           vmin=vmin, vmax=vmax)
            a.set(title=f"{nm}: ρ_y, {t}, ū = {ex['lat']['ubar'][-1]:.1f} mm",
                  xlabel="x (mm)", ylabel="y (mm)")
            a.set_aspect("equal")
            fig.colorbar(sc, ax=a, shrink=0.8)
        fig.tight_layout()
        fig.savefig(out / f"rho_y_{nm}.png", dpi=110)
        plt.close(fig)

        fig, a = plt.subplots(figsize=(7, 4.2))
        gam = np.degrees(ex["samples"][-1]["f"][:, 2])
        sc = a.scatter(*Xn.T, c=gam, s=12 if len(Xn) > 2000 else 40, cmap="magma")
        W, L = WIDTH, LENGTH
        for xs, ys in (([0, W / 2, 0], [0, W / 2, W]), ([L, L - W / 2, L], [0, W / 2, W]),
                       ([W / 2, L / 2, L - W / 2, L / 2, W / 2],
                        [W / 2, W / 2 - (L - W) / 2, W / 2, W / 2 + (L - W) / 2, W / 2])):
            a.plot(xs, ys, "w--", lw=1)
        fig.colorbar(sc, ax=a, label="shear angle γ (deg)")
        a.set(title=f"{nm}: continuum shear angle on the reference, ū = "
                    f"{ex['lat']['ubar'][-1]:.1f} mm (ideal zones dashed)", xlabel="x (mm)",
              ylabel="y (mm)")
        a.title.set_fontsize(8)
        a.set_aspect("equal")
        fig.tight_layout()
        fig.savefig(out / f"zones_{nm}.png", dpi=110)
        plt.close(fig)

    if conv and len(conv["levels"]) > 2:
        fig, a = plt.subplots(figsize=(5, 4))
        h = np.array(conv["h_nominal_mm"][:-1])
        d = np.array(conv["differences"])
        a.loglog(h, d, "o-", label="|F_h − F_{h/2}|")
        for r, ls in ((1, ":"), (2, "--")):
            a.loglog(h, d[-1] * (h / h[-1]) ** r, ls, color="grey", label=f"rate {r}")
        a.set(xlabel="square side h (mm, graded)", ylabel="force difference (N)",
              title=f"grip force at ū = {conv['ubar']:.1f} mm, mesh convergence")
        a.legend()
        fig.tight_layout()
        fig.savefig(out / "force_convergence.png", dpi=110)
        plt.close(fig)


# %% [markdown]
# ## Main: run, summarise, check

# %%
def main(argv=None) -> dict:
    args = parse_args(argv)
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    results, extras = {}, {}

    # (a) Hencky: continuum moduli -> lattice by the identification of docs/network.md
    w = 8.5 / args.lattice_k
    eps = math.sqrt(2) * w
    m = HENCKY_MODULI
    k = lattice_from_continuum(m["k_l"], m["k_s"], m["A_g"], eps)
    rank0_print(comm, f"[hencky] continuum k_l = {m['k_l']} N/mm, k_s = {m['k_s']} N/mm, "
                      f"A_g = {m['A_g']} N mm -> lattice eps = {eps:.4f} mm, "
                      f"k_e = {k['k_e']:.4g} N/mm, k_sh = k_s eps^2 = {k['k_sh']:.4g} N mm, "
                      f"k_b = {k['k_b']:.4g} N mm")
    lat = hencky_lattice(LENGTH, WIDTH, eps, (45.0, -45.0), **k)
    ubar_h = args.ubar_frac * LENGTH
    results["hencky"], extras["hencky"] = compare("hencky", hencky_model(), lat, ubar_h, args,
                                                  comm)
    extras["hencky"]["lat_obj"] = lat
    zones = extras["hencky"]["zones"]
    zones["check"] = zones_at(zones, ZONE_CHECK_FRAC * LENGTH)
    rank0_print(comm, "[zones] " + ", ".join(f"{kk} = {v:.2f}"
                                             for kk, v in zones["check"].items()))

    # (b) bi-pantographic: Table 3 macro (eq. 2) vs Table 3 micro (13-node cells), then eq. (2)
    # with the moduli identified from the micro set by numerical homogenisation
    if not args.skip_bip:
        blat = bipantographic_lattice(eps=EPS_EXACT)
        ubar_b = args.bip_ubar_frac * LENGTH
        ident = comm.bcast(identify_macro(eps=EPS_EXACT) if comm.rank == 0 else None, root=0)
        rank0_print(comm, f"[bipantographic] macro K = 34 N/m, 0.33 J, 0.9 J; micro {TABLE3} "
                          f"(N/mm, N mm), eps = {EPS_EXACT:.4f} mm (seed: {EPS_B}); identified "
                          f"K_S = {ident['K_S']:.5f} N/mm, a_theta(1) = {ident['a_theta']:.3f} "
                          f"N mm, a_rho(1) = {ident['a_rho']:.3f} N mm")
        results["bipantographic"], extras["bipantographic"] = compare(
            "bipantographic", bipantographic(), blat, ubar_b, args, comm)
        extras["bipantographic"]["lat_obj"] = blat
        results["bipantographic_identified"], extras["bipantographic_identified"] = compare(
            "bipantographic_identified", identified_model(ident), blat, ubar_b, args, comm,
            latres=extras["bipantographic"]["lat"])
        extras["bipantographic_identified"]["lat_obj"] = blat
        extras["bipantographic_identified"]["clamp_offset"] = clamp_offset_bracket(
            ident, extras["bipantographic"]["lat"], args, comm)

    # mesh convergence of the grip force, continuum (a)
    levels = [int(s) for s in args.conv_levels.split(",")]
    conv = force_convergence(hencky_model(), levels, ubar_h, args.conv_steps,
                             grading=args.conv_grading, comm=comm)
    rank0_print(comm, f"[convergence] differences {conv['differences']}, rates {conv['rates']}")

    summary = {nm: {kk: r[kk] for kk in ("force_rel_diff", "angle_A_max_diff_deg",
                                         "angle_B_max_diff_deg", "position_rms_diff", "curves")}
               for nm, r in results.items()}
    for nm in ("bipantographic", "bipantographic_identified"):
        if nm in results:
            c = results[nm]["curves"]
            summary[nm]["force_ratio_continuum_to_lattice"] = [
                fc / fl for fc, fl in zip(c["force_continuum"], c["force_lattice"])]
            if "clamp_offset" in extras[nm]:
                summary[nm]["clamp_offset"] = extras[nm]["clamp_offset"]
    summary["three_zones"] = zones
    summary["force_convergence"] = conv
    summary["settings"] = {
        "length_mm": LENGTH, "width_mm": WIDTH, "h_mm": args.h, "steps": args.steps,
        "hencky": {"continuum": HENCKY_MODULI, "lattice": k, "eps_mm": eps,
                   "ubar_max_mm": ubar_h,
                   "lattice_nodes": int(lat.net.n_nodes)},
        "bipantographic": None if args.skip_bip else {
            "continuum": {"K_S_N_per_mm": 0.034, "K_E_Nmm": 330.0, "K_F_Nmm": 900.0,
                          "gamma_rad": math.pi / 6},
            "lattice": TABLE3, "eps_mm": EPS_EXACT, "ubar_max_mm": args.bip_ubar_frac * LENGTH,
            "max_fibre_stretch_continuum": extras["bipantographic"]["lam_max"],
            "identified": identification_summary(ident)},
        "ranks": comm.size, "seconds": time.perf_counter() - t0,
    }
    write_json(comm, args.out / "summary.json", summary)
    if comm.rank == 0:
        figures(args.out, results, extras, conv)

    # ---- checks ---------------------------------------------------------------------
    check(summary, args)
    rank0_print(comm, f"done in {time.perf_counter() - t0:.1f} s; summary: "
                      f"{args.out / 'summary.json'}")
    return summary


# %% [markdown]
# ## Checks
#
# Tolerances are the measured differences with a margin (see the module report /
# README of the demo): the continuum and the Hencky lattice differ by (i) the O(ε) offset of
# the lattice clamp (two held node layers, w = ε/√2 wide, versus a clamp line), (ii) the
# bending identification exact only at λ = 1 (relative difference 2(λ − 1)), (iii) the
# discretisation errors of both (P2 + C0-IP on h; lattice O(ε²) in the bulk).

# %%
def check(summary: dict, args) -> None:
    loose = 2.0 if args.quick else 1.0
    hk = summary["hencky"]
    assert hk["force_rel_diff"] < 0.03 * loose, hk["force_rel_diff"]
    assert hk["angle_A_max_diff_deg"] < 1.5 * loose, hk["angle_A_max_diff_deg"]
    assert hk["angle_B_max_diff_deg"] < 1.0 * loose, hk["angle_B_max_diff_deg"]
    assert hk["position_rms_diff"] < 0.5 * loose, hk["position_rms_diff"]
    z = summary["three_zones"]["check"]
    assert z["clamp_triangle"] < 0.15 * z["centre_B"], z
    assert 0.3 * z["centre_B"] < z["half_sheared"] < 0.7 * z["centre_B"], z
    check_convergence(summary["force_convergence"])
    if "bipantographic" in summary:
        check_bipantographic(summary)


def check_convergence(conv: dict) -> None:
    """Differences fall monotonically, without changing sign, at a rate near 1 or above
    (measured, 2 ranks, ū = 46.75 mm, levels 2, 4, 8: differences 0.892, 0.406 N, rate 1.14;
    benchmarks/bias_convergence.py at ū = 18.7 mm, levels 2..16: rates 1.07, 1.43), and the
    finest force lies within 0.5 % of the Richardson limit (measured 0.19 %)."""
    d, F, rates = conv["differences"], conv["force"], conv["rates"]
    assert rates and all(r is not None and r > 0.8 for r in rates), conv
    assert all(d[i + 1] < d[i] for i in range(len(d) - 1)), conv
    assert conv["finest_error_estimate"] < 0.005 * abs(F[-1]), conv


def check_bipantographic(summary: dict) -> None:
    """Table 3 continuum vs lattice: kinematics agree (measured 2.78°, 4.54°, 0.91 mm), the
    force does not (ratio 1.82–2.07). With the identified moduli the force ratio is
    0.74–0.86 and the angles agree within 1.3°; the rest is the clamp offset, bracketed by
    the continuum on the full and on the free length (measured at ū = 2.8 mm: 0.74 and
    1.36 × the lattice force)."""
    t3, idf = summary["bipantographic"], summary["bipantographic_identified"]
    assert t3["angle_A_max_diff_deg"] < 3.5 and t3["angle_B_max_diff_deg"] < 5.5, t3
    assert t3["position_rms_diff"] < 1.2 and idf["position_rms_diff"] < 1.2, idf
    dev = [max(abs(r - 1) for r in x["force_ratio_continuum_to_lattice"]) for x in (t3, idf)]
    assert dev[1] < 0.3 and dev[1] < dev[0] / 3, dev
    assert idf["angle_A_max_diff_deg"] < 1.6 and idf["angle_B_max_diff_deg"] < 1.2, idf
    br = idf["clamp_offset"]
    full = idf["curves"]["force_continuum"]
    for f_full, f_lat, f_short in zip(full, br["force_lattice"], br["force_free_length"]):
        assert f_full < f_lat < f_short, br


if __name__ == "__main__":
    main()
