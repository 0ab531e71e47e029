"""Spring-network benchmark: >= 100k-node Hencky lattice, bias-extension load steps.

Prints nodes, springs, Newton iterations per load step, time per Newton iteration, the
time of one Hessian assembly and of one factorisation + solve of the free block (the
floor), and the linear-solver statistics (factorisations, lagged-LU Krylov iterations).

    .venv/bin/python benchmarks/network.py [--cols 560] [--steps 2] [--u 4.0]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from fabricsurf.geometry.specimen import BIAS_LENGTH, BIAS_WIDTH
from fabricsurf.network.equilibrium import Dirichlet, solve_steps
from fabricsurf.network.hencky import hencky_lattice
from fabricsurf.network.hencky_moduli import lattice_from_continuum
from fabricsurf.network.linsolve import FreeDofSolver


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cols", type=int, default=560, help="node columns along the specimen length")
    ap.add_argument("--steps", type=int, default=2, help="load steps")
    ap.add_argument("--u", type=float, default=4.0, help="final grip displacement (mm)")
    a = ap.parse_args()
    length, width = BIAS_LENGTH, BIAS_WIDTH
    eps = np.sqrt(2) * length / a.cols  # +-45 deg fibres: x pitch eps/sqrt(2)
    k = lattice_from_continuum(k_l=10.0, k_s=0.05, A_g=5.0, spacing=eps)
    t0 = time.perf_counter()
    lat = hencky_lattice(length, width, eps, k_e=k["k_e"], k_sh=k["k_sh"], k_b=k["k_b"])
    net = lat.net
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    H = net.hessian(net.X)
    t_pattern = time.perf_counter() - t0
    t0 = time.perf_counter()
    H = net.hessian(net.X)
    t_hess = time.perf_counter() - t0
    bcs = [Dirichlet(lat.clamp), Dirichlet(lat.grip, [a.u, 0.0])]
    fixed = np.zeros((net.n_nodes, 2), bool)
    fixed[np.concatenate([lat.clamp, lat.grip])] = True
    t0 = time.perf_counter()
    lin = FreeDofSolver(net.X, H, ~fixed.ravel())
    t_order = time.perf_counter() - t0
    t0 = time.perf_counter()
    lin.solve(H, np.ones(int((~fixed).sum())))
    t_floor = time.perf_counter() - t0
    lin.lu = None
    lin.stats = {"factorisations": 0, "krylov_iterations": 0}
    print(
        f"nodes {net.n_nodes}, dofs {net.n_dofs}, extensional {len(net.ext)}, "
        f"rotational {len(net.rot)}, eps {eps:.4f} mm"
    )
    print(
        f"build {t_build:.2f} s, Hessian pattern {t_pattern:.2f} s, Hessian {t_hess:.2f} s, "
        f"ordering {t_order:.2f} s, factorisation+solve (floor) {t_floor:.2f} s"
    )
    t0 = time.perf_counter()
    res = solve_steps(
        net, bcs, n_steps=a.steps, reaction_sets={"grip": lat.grip}, newton_kw={"linear": lin}
    )
    total = time.perf_counter() - t0
    for r in res:
        per = r.seconds / max(r.iterations, 1)
        print(
            f"step t={r.t:.3f} u={a.u * r.t:.3f} mm: Newton iterations {r.iterations}, "
            f"{r.seconds:.2f} s ({per:.2f} s/iteration, {per / t_floor:.2f} x floor), "
            f"grip force {r.reactions['grip'][0]:.4f} N"
        )
    print(f"total {total:.2f} s for {len(res)} steps; linear solver {lin.stats}")


if __name__ == "__main__":
    main()
