"""The figures of demos/demo_dispersion.py (rank 0): the chain's phase velocity, truncation
error, sign problem and ill-posedness (dispersion_chain.png), and the fabric lattice's waves
against the continua and the transverse departure point against β (dispersion_fabric.png)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from research.demos.dispersion_parts import NEXT, ORDERS
from research.studies import dispersion as dp

COLOURS = ("C0", "C1", "C2")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def chain_figure(out: Path, a1: dict, ill: dict) -> None:
    """Part 1: ``a1`` the arrays of ``chain_modes``, ``ill`` its ill-posedness entries."""
    plt = _plt()
    qd, w2_chain, w2_fe = a1["qd"], a1["w2_chain"], a1["w2_fe"]
    fig, ax = plt.subplots(2, 2, figsize=(11, 8.5))
    xs = np.linspace(1e-3, np.pi, 400)
    a = ax[0, 0]
    a.plot(xs, np.sqrt(dp.vp2_exact(xs)), "k-", lw=2, label="discrete, eq. (12)")
    a.plot(qd, np.sqrt(w2_chain) / qd, "ko", ms=3, mfc="none", label="chain modes (engine)")
    for p, col in zip(ORDERS, COLOURS):
        a.plot(xs, np.sqrt(dp.vp2_truncated(xs, p)), "--", color=col, label=f"∂^{p} continuum")
        a.plot(qd, np.sqrt(w2_fe[p]) / qd, "+", color=col, label=f"∂^{p} modes (dolfinx)")
    a.set(xlabel="qD", ylabel="v_p / c0", title="Phase velocity, 1D chain (Mühlhaus & Oka 1996 §2)")
    a.legend(fontsize=7)
    a = ax[0, 1]
    xe = np.geomspace(0.05, np.pi, 200)
    for p, col in zip(ORDERS, COLOURS):
        a.loglog(qd, np.abs(w2_fe[p] / w2_chain - 1), "o", color=col, ms=3,
                 label=f"∂^{p}: |v_p²/v_p²(eq.12) - 1|")
        a.loglog(xe, np.abs(NEXT[p]) * xe**p, "-", color=col, lw=0.8, label=f"|C_{p}|(qD)^{p}")
    a.axhspan(1e-12, 3e-7, color="0.9", zorder=0)
    a.text(0.06, 1e-9, "round-off floor of the\n∂⁶ eigen-solve", fontsize=7)
    a.set(xlabel="qD", ylabel="relative error in ω² (modes)", title="Truncation error vs order",
          ylim=(1e-12, 1))
    a.legend(fontsize=7)
    a = ax[1, 0]
    xl = np.linspace(0, 6, 400)
    a.plot(xl, dp.omega2_chain(xl), "k-", lw=2, label="discrete, eq. (12)")
    for p, col in zip(ORDERS, COLOURS):
        a.plot(xl, xl**2 * dp.vp2_truncated(xl, p), "--", color=col, label=f"∂^{p} continuum")
    a.axhline(0, color="gray", lw=0.5)
    a.axvline(math.sqrt(12), color="C1", lw=0.5, ls=":")
    a.set(xlabel="qD", ylabel="mω²/k", ylim=(-4, 8),
          title="Sign problem: ∂⁴ gives ω² < 0 for qD > √12")
    a.legend(fontsize=7)
    a = ax[1, 1]
    hs, l4, l6 = (np.array(ill[k]) for k in ("h_over_D", "min_eigenvalue_order4",
                                             "min_eigenvalue_order6"))
    a.loglog(hs, -l4, "C1o-", label="∂⁴: -min ω² (unstable)")
    a.loglog(hs, l6, "C2s-", label="∂⁶: min ω² (first mode)")
    a.loglog(hs, -l4[0] * (hs / hs[0]) ** -4, "k:", lw=0.8, label="∝ h⁻⁴")
    a.set(xlabel="mesh size h / D", ylabel="|min eigenvalue| (k/m)",
          title="Ill-posedness under refinement")
    a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "dispersion_chain.png", dpi=120)
    plt.close(fig)


def fabric_figure(out: Path, res2: dict, a2: dict, rho: float) -> None:
    """Part 2: ``res2`` the summary entries of ``fabric_waves``, ``a2`` its arrays."""
    plt = _plt()
    xg, qg, wl, wt, names, vp = (a2[k] for k in ("xg", "qg", "wl", "wt", "continua",
                                                 "vp_ratio"))
    dep, beta = res2["departure_qeps_vp_1pct"], res2["beta"]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    a = ax[0]
    base = np.sqrt(wl * rho / res2["k_l"]) / qg
    a.plot(xg, base, "k-", lw=2, label="Hencky lattice (Bloch)")
    for name, col in zip(names[:3], ("C0", "C3", "C1")):
        a.plot(xg, vp[name] * base, "--", color=col, label=name.split(": ")[1])
    a.set(xlabel="qε", ylabel="v_p / √(k_l/rho)", title="Longitudinal wave along L",
          xlim=(0, np.pi))
    a.legend(fontsize=7)
    a = ax[1]
    base = np.sqrt(wt) / qg / np.sqrt(res2["k_s"] / rho)
    a.loglog(xg, base, "k-", lw=2, label="Hencky lattice (Bloch)")
    for name, col in zip(names[3:], ("C0", "C2")):
        a.loglog(xg, vp[name] * base, "--", color=col, label=name.split(": ")[1])
        a.axvline(dep[name], color=col, lw=0.6, ls=":")
    a.set(xlabel="qε", ylabel="v_p / √(k_s/rho)", title=f"Transverse wave along L, β = {beta:g}")
    a.legend(fontsize=7)
    a = ax[2]
    db = res2["departure_vs_beta"]
    betas = np.array(db["beta"])
    a.loglog(betas, db["shear"], "C0o-", label="shear only")
    a.loglog(betas, db["shear + geodesic_bending"], "C2s-", label="+ geodesic_bending")
    a.loglog(betas, np.sqrt(0.02 / betas), "k:", lw=0.8, label="√(0.02/β)")
    a.set(xlabel="β = A_g/(k_s ε²)", ylabel="qε at 1 % phase-velocity departure",
          title="Transverse departure point")
    a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "dispersion_fabric.png", dpi=120)
    plt.close(fig)
