# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # The hyperbolic paraboloid: an exact solution of the fabric-surface theory
#
# Steigmann & dell'Isola 2015 (§5) show that the generalised hyperbolic paraboloids
#
# $$ r(\theta) = a\,\theta^1\theta^2 + b\,\theta^1 + c\,\theta^2 + d \qquad (98) $$
#
# are equilibria of the energy (60) when the fibres run along $\theta^1, \theta^2$, the
# membrane energy has no shear part, $w = w_1(\lambda) + w_2(\mu)$, and the cross-gradient and
# twist moduli coincide, $A_\Gamma = \bar k$. Then $g_l = g_m = 0$, $K_L = K_M = 0$,
# $\Gamma + T n = a$ (101–102), the double force $M^{\alpha\beta} = \tfrac12 A_\Gamma
# (L^\alpha M^\beta + M^\alpha L^\beta)a$ is uniform (103), and
# $T^\alpha_{|\alpha} = (w_\lambda l)_{,1} + (w_\mu m)_{,2} = 0$ (106). The loads that hold it
# are, by (94), the edge tractions $t = N^\alpha\nu_\alpha$ ($\pm w_\lambda l$ on
# $\theta^1 = $ const, $\pm w_\mu m$ on $\theta^2 = $ const), no edge double force, and corner
# forces $f = -[M^{\alpha\beta}\nu_\alpha\tau_\beta] = \pm A_\Gamma a$.
#
# This demo solves three problems with the C0 interior-penalty discretisation (degree 2):
#
# 1. **Dirichlet**: $u$ prescribed on the whole boundary, $\partial_n u$ free. The edge double
#    force $M^{\alpha\beta}\nu_\alpha\nu_\beta$ vanishes (103 has only mixed components), so
#    the natural condition on $\partial_n u$ holds; the placement is quadratic, so the discrete
#    solution must equal it to solver tolerance.
# 2. **Natural**: the tractions and corner forces above as dead loads; three corners pinned at
#    their exact positions. Pinning three corners (not just six rigid-motion components) is
#    needed because a shear-free net has zero-energy mechanisms: rotating $b$ or $c$ about $a$
#    leaves $\lambda$, $\mu$ and $r_{LM}$ unchanged, and homogeneous shear costs nothing in the
#    flat state. The corner forces computed from the solution's double force must equal
#    $A_\Gamma a$.
# 3. **Counter-check**: $\bar k = 2A_\Gamma$ with the same loads: no longer a hyperbolic
#    paraboloid.
#
# Run: `mpirun -n 2 python demos/demo_hypar.py --out out/hypar`.

# %%
import dataclasses
import logging

import numpy as np
from mpi4py import MPI

from fabricsurf.cli.demo import demo_parser, parse, require, verify
from fabricsurf.discretise.evaluation import eval_points
from fabricsurf.discretise.output import FieldWriter, write_json
from fabricsurf.geometry.specimen import square
from fabricsurf.log import rank0
from fabricsurf.verification.hypar import (
    CORNER_SIGNS,
    Hypar,
    computed_corner_forces,
    l2_error,
    solve_dirichlet,
    solve_natural,
)
from fabricsurf.verification.rates import rates

comm = MPI.COMM_WORLD
logger = logging.getLogger(__name__)
parser = demo_parser(__doc__.splitlines()[0] if __doc__ else None, "out/hypar")
parser.add_argument(
    "--sizes",
    type=float,
    nargs="+",
    default=[0.5, 0.35, 0.25],
    help="mesh sizes of the natural-case convergence study (coarse to fine)",
)
args = parse(parser)
if args.quick:  # the two coarser meshes: one rate
    args.sizes = args.sizes[:2]
hyp = Hypar()

# %% [markdown]
# ## 1. Dirichlet data on the whole boundary

# %%
p_dir, dirichlet_max_error = solve_dirichlet(square(1.0, 0.25), hyp)
rank0(logger, comm, f"Dirichlet case: max nodal error {dirichlet_max_error:.3e}")

# %% [markdown]
# ## 2. Edge tractions and corner forces (natural case), under refinement

# %%
errors = []
for h in args.sizes:
    p_nat = solve_natural(square(1.0, h), hyp)
    errors.append(l2_error(p_nat, hyp))
    rank0(logger, comm, f"natural case h = {h}: L2 error {errors[-1]:.3e}")
natural_rates = rates(errors, args.sizes)
corner = computed_corner_forces(p_nat)
corner_rel = max(
    np.linalg.norm(f - hyp.corner_force(c)) / np.linalg.norm(hyp.corner_force(c))
    for c, f in corner.items()
)
rank0(logger, comm, f"rates {np.round(natural_rates, 2)}; corner force rel. error {corner_rel:.2e}")
writer = FieldWriter(args.out / "hypar.xdmf", p_nat.u, p_nat.energy.kin)
writer.write(0.0)
writer.close()

# %% [markdown]
# ## 3. Counter-check: $A_\Gamma \neq \bar k$

# %%
mismatch = dataclasses.replace(hyp, k_t=2.0 * hyp.A_Gamma)
p_bad = solve_natural(square(1.0, args.sizes[-1]), mismatch)
departure = l2_error(p_bad, mismatch)
rank0(logger, comm, f"k_t = 2 A_Gamma: L2 distance from the hyperbolic paraboloid {departure:.3e}")

# %% [markdown]
# ## Figure and summary

# %%
g = np.linspace(0.0, 1.0, 21)
X = np.array([(x, y) for y in g for x in g])
u_nat, u_bad = eval_points(p_nat.u, X), eval_points(p_bad.u, X)
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(11, 4.6))
    for k, (u, title) in enumerate(
        ((u_nat, "natural loads, A_Γ = k̄"), (u_bad, "same loads, k̄ = 2A_Γ"))
    ):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        r = np.c_[X, np.zeros(len(X))] + u
        ax.plot_trisurf(r[:, 0], r[:, 1], r[:, 2], cmap="viridis", alpha=0.9)
        exact = np.c_[X, np.zeros(len(X))] + hyp.displacement_np(X)
        ax.scatter(exact[::7, 0], exact[::7, 1], exact[::7, 2], s=4, c="k", label="exact (98)")
        ax.set(title=title, xlabel="x", ylabel="y", zlabel="z")
        ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(args.out / "hypar.png", dpi=120)
    plt.close(fig)

summary = {
    "dirichlet_max_error": dirichlet_max_error,
    "natural_l2_errors": errors,
    "natural_mesh_sizes": args.sizes,
    "natural_rate": natural_rates[0],
    "natural_rates": natural_rates,
    "corner_force_rel_error": corner_rel,
    "corner_forces": {str(c): list(map(float, f)) for c, f in corner.items()},
    "corner_signs": {str(c): s for c, s in CORNER_SIGNS.items()},
    "mismatch_departure": departure,
}
write_json(comm, args.out / "summary.json", summary)

# %% [markdown]
# ## Checks
#
# * Dirichlet: the exact placement is in the discrete space, so the error is at solver
#   tolerance (< 1e-10).
# * Natural: the only discretisation error is the quadrature (3 Gauss points per edge, exact to
#   degree 5) of the non-polynomial dead tractions, so the error falls like $h^6$ until it
#   reaches round-off (~1e-12); every error must be < 1e-8 and the first rate > 4.
# * Corner forces from the computed double force equal $A_\Gamma a$ to 1e-6.
# * The counter-check departs by more than 1e4 times the natural-case error.

# %%
CHECKS = {
    "dirichlet_max_error": (0.0, 1e-10),
    "natural_l2_errors/*": (0.0, 1e-8),
    "corner_force_rel_error": (0.0, 1e-6),
    "natural_rates": ...,
}
verify(summary, CHECKS)
require(natural_rates[0] > 4.0 or errors[0] < 1e-11, natural_rates)
require(departure > 1e4 * max(errors), (departure, errors))
rank0(logger, comm, f"all checks passed; output in {args.out}")
