"""The figures of demos/demo_bias_extension.py (rank 0): force and shear angles against ū for
each comparison, deformed configurations (continuum χ against lattice nodes), the y-stretch
ρ_y, the continuum shear angle over the ideal zones of the bias test, the force convergence
under mesh refinement, and the bi-pantographic whole range (Barchiesi et al. 2020, Figs. 9–11)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fabricsurf.network.micromacro import grid_fields
from research.studies.bias_comparison import LENGTH, WIDTH


def plt_agg():
    """matplotlib's pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figures(out: Path, results: dict, extras: dict, conv: dict) -> None:
    """curves.png, deformed_*.png, rho_y_*.png, zones_*.png and force_convergence.png."""
    plt = plt_agg()
    curves_figure(plt, out, results, extras)
    for nm, ex in extras.items():
        deformed_figure(plt, out, nm, ex)
        rho_figure(plt, out, nm, ex)
        zones_figure(plt, out, nm, ex)
    if conv and len(conv["levels"]) > 2:
        convergence_figure(plt, out, conv)


def curves_figure(plt, out: Path, results: dict, extras: dict) -> None:
    """Force and shear angles at A and B against ū, continuum and lattice, per comparison."""
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


def deformed_figure(plt, out: Path, nm: str, ex: dict) -> None:
    """Continuum χ(x_i, y_j) against the lattice nodes p_ij at three loads."""
    nodes, Xn = ex["nodes"], ex["Xn"]
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


def rho_figure(plt, out: Path, nm: str, ex: dict) -> None:
    """The y-stretch ρ_y of the lattice (eq. 4) and of the continuum at the last load."""
    lat, Xn = ex["lat_obj"], ex["Xn"]
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


def zones_figure(plt, out: Path, nm: str, ex: dict) -> None:
    """The continuum shear angle on the reference, the ideal zones dashed."""
    Xn = ex["Xn"]
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


def convergence_figure(plt, out: Path, conv: dict) -> None:
    """Force differences between nested meshes against h, with rates 1 and 2."""
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
    plt = plt_agg()
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
