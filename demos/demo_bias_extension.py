# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Bias extension: continuum versus spring network (Barchiesi et al. 2020)
#
# A 187 mm × 119 mm fabric with fibres at ±45° to the load is clamped at x = 0 and pulled at
# x = length (Barchiesi et al. 2020, eq. 7):
#
#   u = 0, ∂u/∂x = 0 at x = 0;     u = ū e_x, ∂u/∂x = 0 at x = length,
#
# the zero normal derivative imposed weakly (Nitsche) in the second-gradient continuum and, in
# the lattice, by holding two node layers (Barchiesi et al. 2020, Table 1). Two comparisons:
#
# **(a) Hencky.** The continuum `fibre_stretch + shear + geodesic_bending`,
#
#   W = ½k_l[(λ−1)² + (μ−1)²] + ½k_s γ² + ½A_g[(λ²η_l)² + (μ²η_m)²],
#
# against the Hencky fabric lattice (nodes at fibre crossings, spacing ε) whose stiffnesses come
# from the micro–macro identification of `docs/network.md`: k_e = k_l, k_sh = k_s ε², k_b = A_g.
# The spacing is ε = √2·w with w = 8.5 mm / k the x-distance between node columns, so that the
# node columns tile the specimen (length = 22k·w, width = 14k·w) and the points A, B of
# Barchiesi et al. 2020, Fig. 4, are nodes.
#
# **(b) Bi-pantographic.** The homogenised energy of Barchiesi et al. 2020, eq. (2)
# (`fabricsurf.model.materials`, K_S = 34 N/m, K_E = 0.33 J, K_F = 0.9 J of Table 3) against
# the 13-node-cell lattice of their §3 with the Table 3 micro parameters (k_E = 335 N/m,
# k_S = 9.36, k_F = 46.2 N·mm). The two parameter sets were fitted *independently* to the
# experiment, so the models are not an identification of each other. The numerical
# homogenisation of the lattice
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
# **Whole range.** The bi-pantographic comparisons run to ū = 50 mm (27 % of the length,
# the paper's whole range). Eq. (2) needs three things there
# (`research.studies.bipantographic_range`): an interior penalty that follows the largest
# fibre stretch (its second-gradient coefficient a_ρ grows as 1/(1 − ρ²cos²γ); with the
# penalty frozen at ρ = 1 the discrete energy loses coercivity near the grip corners and
# Newton stalls near ū = 20 mm), and a backtracking line search that treats ρ cos γ ≥ 1 as
# a domain error. The same study runs both clamp variants on three
# nested meshes (`--range-levels`, rates of the force reported).
#
# Quantities (Barchiesi et al. 2020, Figs. 9–11): grip reaction force vs ū; shear angle γ at A
# (centre of the square on the clamped side) and at B (specimen centre) vs ū; deformed
# configurations — continuum χ(x_i, y_j) against lattice nodes p_ij (eq. 3); the y-stretch
# ρ_y (eq. 4, the stretch along the second fibre family M, = μ). Lattice angles at A and B
# use the central differences of eq. (5) at the node there: γ = π/2 − arccos(a·b/|a||b|) with
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
import sys
import time
from pathlib import Path

# The research code (benchmarks/research/) is not installed: put benchmarks/ on the path.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.output import rank0_print, write_json
from fabricsurf.network.micromacro import grid_fields
from research.studies.bias_comparison import LENGTH, WIDTH
from research.studies.bias_study import BiasStudySettings, run_bias_study


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=Path("out/bias_extension"))
    ap.add_argument("--h", type=float, default=4.0, help="continuum mesh size (mm)")
    ap.add_argument("--steps", type=int, default=10, help="load steps")
    ap.add_argument("--ubar-frac", type=float, default=0.25,
                    help="Hencky comparison: ū_max / length")
    ap.add_argument("--bip-ubar", type=float, default=50.0,
                    help="bi-pantographic comparison: ū_max (mm)")
    ap.add_argument("--bip-steps", type=int, default=20)
    ap.add_argument("--range-levels", type=str, default="2,4,8",
                    help="bi-pantographic whole-range study: nested graded mesh levels, both "
                         "clamp variants, to --bip-ubar ('' to skip)")
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
                    help="coarse and fast (tests): h = 8, 4 steps, ū ≤ 10%%, k = 2, levels 2,4,8;"
                         " bi-pantographic to 18.7 mm in 4 steps, no whole-range study")
    a = vars(ap.parse_args(argv))
    quick = a.pop("quick")
    s = BiasStudySettings(**a)
    return s.quick() if quick else s


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
# ū = 46.75 mm: 8.4°, 36.4°, 49.6°). Zone points and the ideal angle:
# `research.studies.bias_comparison` (`ZONE_POINTS`, `ideal_centre_shear_deg`).

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
# (`research.studies.bias_convergence.force_convergence`; benchmarks/bias_convergence.py
# adds level 16).

# %% [markdown]
# ## Figures (rank 0)

# %%
def figures(out: Path, results: dict, extras: dict, conv: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [nm for nm, r in results.items() if isinstance(r, dict) and "curves" in r]
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


def range_figure(out: Path, rng: dict) -> None:
    """Eq. (2), Table 3, to ū = 50 mm: force, γ_A, γ_B and the largest ρ cos γ against ū, per
    clamp variant and mesh level (Figs. 9 of Barchiesi et al. 2020 over its whole range)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 4, figsize=(17, 7.5), squeeze=False)
    for row, (clamp, data) in enumerate(rng.items()):
        for r in data["runs"]:
            if r["failure"]:
                continue
            lab = f"level {r['level']} ({r['dofs']} DOFs)"
            ax[row, 0].plot(r["ubar"], r["force"], "-", label=lab)
            ax[row, 1].plot(r["ubar"], r["angle_A_deg"], "-", label=lab)
            ax[row, 2].plot(r["ubar"], r["angle_B_deg"], "-", label=lab)
            ax[row, 3].plot([h["ubar"] for h in r["stretch"]],
                            [h["rho_cos_gamma"] for h in r["stretch"]], "-", label=lab)
        for col, yl in enumerate(("grip force (N)", "γ at A (deg)", "γ at B (deg)",
                                  "largest ρ cos γ (limit 1)")):
            ax[row, col].set(xlabel="ū (mm)", ylabel=yl, title=f"{clamp} clamps")
        ax[row, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "bipantographic_range.png", dpi=110)
    plt.close(fig)


# %% [markdown]
# ## Main: run, summarise, check

# %%
def main(argv=None) -> dict:
    args = parse_args(argv)
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    summary, extras = run_bias_study(args, comm)
    write_json(comm, args.out / "summary.json", summary)
    if comm.rank == 0:
        figures(args.out, summary, extras, summary["force_convergence"])
        if "bipantographic_range" in summary:
            range_figure(args.out, summary["bipantographic_range"])
    check(summary, args)
    if args.is_quick:
        check_quick(summary, args.out)
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
    loose = 2.0 if args.is_quick else 1.0
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
    if "bipantographic_range" in summary:
        check_range(summary["bipantographic_range"], args.bip_ubar)


def check_quick(summary: dict, out: Path) -> None:
    """The quick run's own figures, measured on 1 and 2 ranks (h = 8 mm, ε = 6.01 mm,
    ū ≤ 18.7 mm): continuum vs Hencky force 1.4 %, γ_A 0.08°, γ_B 0.42°, positions 0.12 mm
    (tolerances twice these, rounded up); zones γ = 1.8°, 13.6°, 23.1° at ū = 18.7 mm; grip
    force on levels 2, 4, 8: differences 0.229, 0.109 N, rate 1.07; Table 3 continuum/lattice
    force ratio 1.9–2.1, with the homogenised moduli within 0.3 of 1 and bracketed by the
    full-length and free-length continua; eq. (2) with the springs' ½ halves the force exactly
    (ratio 0.97–1.13)."""
    keys = {"force_rel_diff", "angle_A_max_diff_deg", "angle_B_max_diff_deg",
            "position_rms_diff", "curves", "failure"}
    bip = {"force_ratio_continuum_to_lattice", "max_stretch"}
    extra = {"hencky": set(), "bipantographic": bip, "bipantographic_half": bip,
             "bipantographic_identified": bip | {"clamp_offset"}}
    for name, more in extra.items():
        assert set(summary[name]) == keys | more, name
        assert len(summary[name]["curves"]["ubar"]) == 4 and summary[name]["failure"] is None
    hk = summary["hencky"]
    assert hk["force_rel_diff"] < 0.03 and hk["angle_A_max_diff_deg"] < 0.3
    assert hk["angle_B_max_diff_deg"] < 1.0 and hk["position_rms_diff"] < 0.25
    z = summary["three_zones"]["check"]
    assert abs(z["ubar"] - 18.7) < 1e-9
    assert 0.45 * z["centre_B"] < z["half_sheared"] < 0.7 * z["centre_B"]
    assert z["centre_B"] < z["ideal_centre_deg"]
    c = hk["curves"]
    assert 1.2 < c["angle_B_continuum_deg"][-1] / c["angle_A_continuum_deg"][-1] < 2.0
    conv = summary["force_convergence"]
    assert conv["levels"] == [2, 4, 8] and conv["differences"][1] < 0.6 * conv[
        "differences"][0]
    assert 0.8 < conv["rates"][0] < 2.5
    ident = summary["settings"]["bipantographic"]["identified"]
    assert abs(ident["K_S"] / 0.01446 - 1) < 1e-3 and abs(ident["a_theta"] / 9.557 - 1) < 1e-3
    assert min(summary["bipantographic"]["force_ratio_continuum_to_lattice"]) > 1.5
    r_id = summary["bipantographic_identified"]["force_ratio_continuum_to_lattice"]
    assert max(abs(r - 1) for r in r_id) < 0.3
    t3, half = summary["bipantographic"]["curves"], summary["bipantographic_half"]
    assert np.allclose(half["curves"]["force_continuum"],
                       0.5 * np.array(t3["force_continuum"]), rtol=1e-6)
    assert all(0.95 < r < 1.15 for r in half["force_ratio_continuum_to_lattice"])
    for f in ("hencky/bias.xdmf", "bipantographic/bias.xdmf",
              "bipantographic_identified/bias.xdmf"):
        assert (out / f).exists(), f


def check_convergence(conv: dict) -> None:
    """Differences fall monotonically, without changing sign, at a rate near 1 or above
    (measured, 2 ranks, ū = 46.75 mm, levels 2, 4, 8: differences 0.892, 0.406 N, rate 1.14;
    benchmarks/bias_convergence.py at ū = 18.7 mm, levels 2..16: rates 1.07, 1.43), and the
    finest force lies within 0.5 % of the Richardson limit (measured 0.19 %)."""
    d, F, rates = conv["differences"], conv["force"], conv["rates"]
    assert rates and all(r is not None and r > 0.8 for r in rates), conv
    assert all(d[i + 1] < d[i] for i in range(len(d) - 1)), conv
    assert conv["finest_error_estimate"] < 0.005 * abs(F[-1]), conv


def _upto(values: list, ubar: list, limit: float) -> list:
    return [v for v, u in zip(values, ubar) if u <= limit + 1e-9]


def check_bipantographic(summary: dict, limit: float = 0.15 * LENGTH) -> None:
    """Up to ū = 15 % of the length (28 mm, where these were measured): Table 3 continuum vs
    lattice: kinematics agree (measured 2.78°, 4.54°, 0.91 mm), the force does not (ratio
    1.82–2.07). With the identified moduli the force ratio is 0.74–0.86 and the angles agree
    within 1.3°; the rest is the clamp offset, bracketed by the continuum on the full and on
    the free length (measured at ū = 2.8 mm: 0.74 and 1.36 × the lattice force). Beyond, to
    50 mm, the curves are reported (summary.json, curves.png); the largest stretch of the
    continuum stays inside the energy's domain (ρ cos γ < 1) at every step. All three continua
    reach ū_max; the identified moduli come closest to the limit (measured on the uniform
    h = 4 mm mesh: ρ cos γ = 0.9956 at the grip corner (8, 0) mm at ū = 50 mm). A comparison
    that stopped earlier would cover its converged steps and record where ("failure")."""
    t3, idf = summary["bipantographic"], summary["bipantographic_identified"]
    for name in ("bipantographic", "bipantographic_half", "bipantographic_identified"):
        assert summary[name]["failure"] is None, (name, summary[name]["failure"])
    assert idf["curves"]["ubar"] == t3["curves"]["ubar"]
    for x in (t3, idf):
        assert all(h["rho_cos_gamma"] < 1 for h in x["max_stretch"]), x["max_stretch"]
    u = t3["curves"]["ubar"]

    def maxdiff(x, key):
        c = x["curves"]
        return max(abs(a - b) for a, b in zip(_upto(c[f"{key}_continuum_deg"], u, limit),
                                              c[f"{key}_lattice_deg"]))

    assert maxdiff(t3, "angle_A") < 3.5 and maxdiff(t3, "angle_B") < 5.5, t3
    rms = [_upto(x["curves"]["position_rms_diff"], u, limit) for x in (t3, idf)]
    assert max(rms[0]) < 1.2 and max(rms[1]) < 1.2, rms
    dev = [max(abs(r - 1) for r in _upto(x["force_ratio_continuum_to_lattice"], u, limit))
           for x in (t3, idf)]
    assert dev[1] < 0.3 and dev[1] < dev[0] / 3, dev
    assert maxdiff(idf, "angle_A") < 1.6 and maxdiff(idf, "angle_B") < 1.2, idf
    br = idf["clamp_offset"]
    full = idf["curves"]["force_continuum"]
    for f_full, f_lat, f_short in zip(full, br["force_lattice"], br["force_free_length"]):
        assert f_full < f_lat < f_short, br


def check_range(rng: dict, ubar: float) -> None:
    """Both clamp variants reach ū_max on every level, inside the domain, and the grip force
    converges: at every reported ū the differences between levels fall."""
    for clamp, data in rng.items():
        for r in data["runs"]:
            assert r["failure"] is None, (clamp, r["level"], r["failure"])
            assert abs(r["ubar"][-1] - ubar) < 1e-9
            assert all(h["rho_cos_gamma"] < 1 for h in r["stretch"])
        for u, c in data["convergence"].items():
            d = c["differences"]
            assert all(d[i + 1] < d[i] for i in range(len(d) - 1)), (clamp, u, c)


if __name__ == "__main__":
    main()
