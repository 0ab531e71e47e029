# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # Dispersion: discrete chains and lattices against gradient continua
#
# Run with `mpirun -n 2 python demos/demo_dispersion.py --out out/dispersion`.
#
# Two questions, both answered with computed modes and checked against closed forms:
#
# 1. **The 1D chain of Mühlhaus & Oka 1996 §2**. N point masses m, linear springs k, spacing D.
#    How well do the continua obtained by truncating the Taylor expansion of the
#    difference operator (eq. 10) after the ∂², ∂⁴, ∂⁶ terms reproduce the exact discrete
#    dispersion (eq. 12)? Why is the ∂⁴ continuum ill-posed, and how does ∂⁶ repair it?
# 2. **Waves along the fibres of the Hencky fabric lattice** against the fabric continuum of
#    docs/theory.md with and without its gradient terms (`stretch_gradient`, `geodesic_bending`):
#    at which qε does each continuum depart from the lattice by more than 1 %?
#
# ## Part 1 — equations
#
# Linearised, eq. (6) is m ü_j = k(u_{j+1} - 2u_j + u_{j-1}). Plane waves u_j = A exp iq(jD - v_p t)
# give, with c0² = kD²/m (eq. 12),
#
# $$\omega^2 = \frac{2k}{m}(1-\cos qD),\qquad
#   \frac{v_p^2}{c_0^2} = \frac{2(1-\cos qD)}{(qD)^2}
#   = 1 - \frac{(qD)^2}{12} + \frac{(qD)^4}{360} - \frac{(qD)^6}{20160} + \dots$$
#
# Replacing u_{j±1} by the shift operator exp(±D∂x) (eqs. 7-9) and truncating gives eq. (10),
# rho ü = kD(u'' + D²/12 u'''' + D⁴/360 u⁽⁶⁾), rho = m/D, whose plane waves reproduce the first one,
# two or three terms of the series (eqs. 14, 15). As an energy per unit length (footnote, eq. 20)
#
# $$W = \tfrac12\int a\,u'^2 + b\,u''^2 + c\,u'''^2\,dx,\qquad
#   (a,b,c) = kD\,(1,\,-D^2/12,\,D^4/360),$$
#
# because the Euler-Lagrange equation of W is rho ü = a u'' - b u'''' + c u⁽⁶⁾. **b is negative**:
# the D²/12 term that improves the dispersion is *destabilising* (Mühlhaus & Oka 1996 footnote): W
# is not positive for short waves: rho ω² = a q² + b q⁴ < 0 for qD > √12, and since a continuum
# admits arbitrarily large q, the growth rate √(-ω²) ~ q² is unbounded — Hadamard ill-posedness. The
# ∂⁶ term adds c q⁶ > 0; 1 - x²/12 + x⁴/360 has no real root (1/144 < 4/360), so the sixth-order
# continuum is well-posed.
#
# **Computations.** The finite chain with fixed ends (N masses, u_0 = u_{N+1} = 0) has the modes
# sin(q_n jD), q_n = nπ/((N+1)D), with eigenvalues exactly eq. (12): we take its stiffness from
# the Hessian of the spring-network engine. The continuum on (0, (N+1)D) with u = 0 and u'' = 0 at
# the ends (and u'''' = 0, natural, for the ∂⁶ model) has the same sines as modes, so the two sets
# of eigenvalues are compared at identical q_n. The continuum eigenproblem K v = ω² M v is
# discretised in dolfinx with Lagrange P5 elements; the broken second/third derivatives are made
# consistent by C0 interior-penalty terms (docs/theory.md, dolfinx demo_biharmonic) on the interior
# points, and solved densely (the 1D problem is small; matrices are gathered to rank 0).

# %%
import json
import math
import sys
from pathlib import Path

# The research code (benchmarks/research/) is not installed: put benchmarks/ on the path.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import numpy as np
from dolfinx import fem, io
from mpi4py import MPI

from research.demos import dispersion_parts as parts
from research.demos.checks import verify
from research.demos.common import demo_parser, parse
from research.demos.dispersion_figures import chain_figure, fabric_figure

args = parse(demo_parser(__doc__, "out/dispersion"))  # --quick: a shorter β scan
comm = MPI.COMM_WORLD
out = args.out
out.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ### Truncation error against the order in qD
#
# The error of the ∂^p continuum is the first neglected term of the series: in ω² it is
# ≈ C_p c0² q² (qD)^p, i.e. of order (qD)^{p+2} (with C_2 = -1/12, C_4 = 1/360, C_6 = -1/20160),
# and of order (qD)^p in v_p² relative to the exact value. We measure it from the *computed*
# modes (engine chain minus dolfinx continuum), fit the slope on log-log axes over the modes whose
# error is well above round-off (|e| > 1e-6, qD ≤ 1.6), and compare the error with the predicted
# leading term at the smallest such qD.
#
# ### Where each truncation departs from the discrete chain by 1 % in phase velocity
#
# From the formulas on a fine qD grid, and from the computed modes (linear interpolation between
# neighbouring q_n); the two must agree to the spacing of the q_n, π/(N+1).

# %%
N, D, k, m = 40, 1.0, 1.0, 1.0
res1, arrays1 = parts.chain_modes(comm, N, D, k, m)

# %% [markdown]
# ### The sign problem: the ∂⁴ continuum is ill-posed, the ∂⁶ continuum is not
#
# On a short domain (10 masses, L = 11D) we refine the continuum mesh. The ∂⁴ model has
# eigenvalues rho ω² ≈ b q⁴ < 0 for every resolved q beyond √12/D, so its most negative eigenvalue
# grows like h⁻⁴ and the growth rate √(-ω²_min) like h⁻²: no limit exists. The ∂⁶ model's
# smallest eigenvalue stays the first physical mode, ω_1² = c0² q_1² (1 - (q_1D)²/12 + (q_1D)⁴/360).

# %%
res1["ill_posedness"] = parts.ill_posedness(comm, 10, D, k, m)

# %% [markdown]
# ## Part 2 — waves along the fibres of the Hencky lattice
#
# **Continuum (docs/theory.md), linearised.** Fibres L, M orthonormal, r = X + u, wave along L
# (coordinate s = X·L). Longitudinal: u = w(s)L; transverse: u = v(s)M. To first order in u,
#
# * λ - 1 = |L + ∂_L u| - 1 ≈ L·∂_L u = w' (transverse: O(v'²));
# * sin gamma = l·m ≈ M·∂_L u + L·∂_M u = v' (longitudinal: 0);
# * g_l = r_LL = ∂_L∂_L u = w''L or v''M, and l ≈ L, p ≈ M, so
#   ∂_Lλ = g_l·l ≈ w'' and λ²η_l = g_l·p ≈ v'' (the other one vanishes to first order).
#
# Energy per area ½k_l w'² + ½A_s w''² (`fibre_stretch` + `stretch_gradient`), resp.
# ½k_s v'² + ½A_g v''² (`shear` + `geodesic_bending`), kinetic energy ½ rho |u̇|², so
#
# $$\rho\omega^2 = k_l q^2 + A_s q^4\ \text{(longitudinal)},\qquad
#   \rho\omega^2 = k_s q^2 + A_g q^4\ \text{(transverse)}.$$
#
# **Lattice** (`fabricsurf.network.hencky`, fibres at 0°/90°, spacing ε, node mass rho ε²): fibre
# springs k_e, bending springs k_b on fibre triples, four quadrant shear springs k_sh/4 per
# crossing; identification k_l = k_e, k_s = k_sh/ε², A_g = k_b. We compute ω²(q) by a Bloch
# analysis of the engine's Hessian: for u_j = U exp(iq X_j·L) the dynamical matrix of an interior
# node is Σ_j H_{0j} exp(iq (X_j - X_0)·L). In closed form (eq. 12 of Mühlhaus & Oka 1996 per
# spring family),
#
# $$\rho\omega^2 = k_l\Big(\tfrac{2}{\varepsilon}\sin\tfrac{q\varepsilon}{2}\Big)^2
#   = k_l q^2\big(1 - \tfrac{(q\varepsilon)^2}{12} + \dots\big),\qquad
#   \rho\omega^2 = k_s\Big(\tfrac{2}{\varepsilon}\sin\tfrac{q\varepsilon}{2}\Big)^2
#   + A_g\Big(\tfrac{2}{\varepsilon}\sin\tfrac{q\varepsilon}{2}\Big)^4
#   = k_s q^2\big(1 - \tfrac{(q\varepsilon)^2}{12}\big)
#   + A_g q^4\big(1 - \tfrac{(q\varepsilon)^2}{6}\big) + \dots$$
#
# Consequences: along the fibre the lattice behaves like a stretch-gradient continuum with A_s =
# -k_lε²/12 < 0 — exactly the destabilising sign of Mühlhaus & Oka 1996. A `stretch_gradient` with
# A_s ≥ 0 (the only admissible values: a stable energy) can only move the longitudinal departure
# point to *smaller* qε. Transversally the shear-only continuum misses the whole A_g q⁴ term: its
# relative phase-velocity error is ≈ ½β(qε)², β = A_g/(k_sε²), so it departs at qε ≈ √(0.02/β);
# `geodesic_bending` leaves only the O((qε)²) discreteness error. (Near β = 1/12 the two errors of
# the shear-only continuum, -(qε)²/12 from discreteness and +β(qε)² from the missing bending,
# cancel: a fortuitous late departure, visible in the β scan.)

# %%
moduli = {"eps_mm": 1.0, "rho": 1.0, "k_l": 30.0, "k_s": 0.5, "A_g": 40.0}  # N/mm, N/mm, N mm
betas = np.geomspace(1e-2, 1e3, 6 if args.quick else 11)
res2, arrays2 = parts.fabric_waves(comm, arrays1["cont"], arrays1["qd"] / D, moduli, betas)

# %% [markdown]
# ## Figures, and a computed continuum mode for ParaView
# Mode n = 5 of the ∂², ∂⁴ and ∂⁶ continua (P5, interpolated to P1 for XDMF in dolfinx 0.5.2).

# %%
if comm.rank == 0:
    chain_figure(out, arrays1, res1["ill_posedness"])
    fabric_figure(out, res2, arrays2, moduli["rho"])
cont = arrays1["cont"]
V1 = fem.FunctionSpace(cont.msh, ("Lagrange", 1))
with io.XDMFFile(comm, out / "dispersion_modes.xdmf", "w") as xdmf:
    xdmf.write_mesh(cont.msh)
    for p in parts.ORDERS:
        f1 = fem.Function(V1, name=f"mode5_order{p}")
        f1.interpolate(cont.function(arrays1["modes"][p][4]))
        xdmf.write_function(f1)

# %% [markdown]
# ## Summary and checks against the references
#
# Exact: the engine's chain modes are eq. (12) and the Bloch waves of the lattice its closed
# form (to round-off). The dolfinx modes match their formulas (P5: to round-off at the low
# modes). Rates: the ω² error of the ∂^p continuum has order p + 2 and is the first neglected
# term at the smallest fitted qD; the ∂⁴ continuum's smallest eigenvalue grows like h⁻⁴,
# while the ∂⁶ one stays the first physical mode. Departure points: formula and modes agree
# to the mode spacing π/(N+1); the shear-only continuum departs at qε ≈ √(0.02/β) (from
# ½β(qε)² = 1 %), `geodesic_bending` moves it far out, and A_s > 0 moves the longitudinal one in.

# %%
summary = {"part1_chain": res1, "part2_hencky_fabric": res2}
if comm.rank == 0:
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
CHECKS = {
    "part1_chain/chain_engine_max_rel_err_vs_eq12": (0.0, 1e-12),
    "part1_chain/continuum/2/fe_max_rel_err_vs_formula_qD_le_1.5": (0.0, 1e-9),
    "part1_chain/continuum/4/fe_max_rel_err_vs_formula_qD_le_1.5": (0.0, 1e-6),
    "part1_chain/continuum/6/fe_max_rel_err_vs_formula_qD_le_1.5": (0.0, 1e-5),
    "part1_chain/continuum/2/omega2_error_order_measured": (3.9, 4.1),
    "part1_chain/continuum/4/omega2_error_order_measured": (5.9, 6.1),
    "part1_chain/continuum/6/omega2_error_order_measured": (7.9, 8.1),
    "part1_chain/ill_posedness/order4_min_eigenvalue_exponent_in_h": (-4.1, -3.9),
    "part1_chain/ill_posedness/min_eigenvalue_order6/*": (0.0, None),
    "part2_hencky_fabric/bloch_vs_closed_form_max_rel_err": (0.0, 1e-6),
    "part2_hencky_fabric/fe_max_rel_err_vs_formula/*/all": (0.0, 1e-4),
    "part2_hencky_fabric/geodesic_bending_moves_departure_by_factor": (5.0, None),
}
verify(summary, CHECKS)
c1, ill = res1["continuum"], res1["ill_posedness"]
for p in parts.ORDERS:
    assert abs(c1[str(p)]["error_over_leading_term_at_qD"][1] - 1) < 0.02, p
    d1 = res1["departure_qD_vp_1pct"][str(p)]
    assert abs(d1["formula"] - d1["computed"]) < np.pi / (N + 1), p
w2_first = ill["order6_first_mode_formula"]
assert max(abs(x / w2_first - 1) for x in ill["min_eigenvalue_order6"]) < 1e-3
for v in res2["fe_max_rel_err_vs_formula"].values():
    # low modes: limited by round-off, eps·max|λ|/ω_1² (a stiff A_g makes K ill-conditioned)
    assert v["q_eps_le_1.5"] < max(10 * v["roundoff_floor"], 1e-8), v
dep = res2["departure_qeps_vp_1pct"]
assert abs(dep["transverse: shear"] - math.sqrt(0.02 / res2["beta"])) < 0.1 * dep[
    "transverse: shear"]
assert dep["longitudinal: + stretch_gradient A_s=+k_l eps^2/12"] < dep[
    "longitudinal: fibre_stretch"]
if comm.rank == 0:
    print(f"all checks passed; wrote {out}/summary.json, figures and dispersion_modes.xdmf")
