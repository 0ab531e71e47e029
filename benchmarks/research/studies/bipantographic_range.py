"""The bi-pantographic bias test over its whole range (Barchiesi et al. 2020, Figs. 9–11: ū up
to 25 % of the length), on nested meshes, with both clamp variants.

What makes the homogenised energy (Barchiesi et al. 2020, eq. 2) followable to ū = 50 mm
(measured and explained in docs/bipantographic.md, "Interior penalty"):

* the interior-penalty scale follows the largest fibre stretch of the solution
  (:class:`PenaltyFollower`, after every converged step; fem.Constant, no recompilation) —
  with the scale frozen at ρ = 1 the discrete energy loses coercivity near the grip corners
  and Newton stalls, whatever the line search or Jacobian. The scale must keep following up
  to the limit: with a fixed ceiling ρ_p cos γ ≤ 0.97 it stopped once the corner stretch passed
  0.97 and the finest position-clamp run stalled; the ceiling is now halfway from ρ to the
  limit;
* the domain-aware solver options (:data:`~fabricsurf.discretise.solver.DOMAIN_AWARE`):
  a backtracking line search that shrinks steps leaving ρ cos γ < 1.

With these, the default Jacobian (no extra form to compile) converges in a few Newton
iterations per step. The exact Jacobian (``jacobian: exact``) needs hardly fewer, but its
kernels for the gradient clamps take minutes to compile, so it is not used here
(docs/verification.md).
"""

from __future__ import annotations

import math
import time

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.evaluation import interpolate_expression
from fabricsurf.discretise.output import rank0_print
from fabricsurf.discretise.solver import DOMAIN_AWARE, LoadStepError
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.model.materials import PantographBending, bipantographic
from research.studies.bias_convergence import graded_specimen
from research.verification.rates import richardson_summary

RANGE_OPTIONS = dict(DOMAIN_AWARE)
"""Solver options of the whole-range runs (module docstring)."""


class PenaltyFollower:
    """After each converged step: record the largest fibre stretch ρ (and where), and set the
    interior-penalty stretch ρ_p of the model's :class:`PantographBending` to
    ρ_p = max(ρ_0, min(ρ + ``margin``, (ρ + 1/cos γ)/2)), ρ_0 the term's own
    ``penalty_stretch``: above the stretch, and at most halfway from it to the limit
    ρ cos γ = 1, so ρ_p stays inside the domain and never falls below the stretch of the
    solution (a fixed ceiling did: the penalty stopped following and Newton stalled, module
    docstring). By default ρ is the largest stretch anywhere and ρ_p uniform; with ``local``
    ρ is the largest stretch in each cell and ρ_p a DG0 field, raised only where the stretch
    concentrates: more accurate on coarse meshes, less robust next to the limit (measured in
    docs/bipantographic.md). Use as (part of) the ``on_step`` callback of
    :meth:`BiasExtension.run`; collective."""

    def __init__(self, test: BiasExtension, margin: float = 0.03, local: bool = False):
        self.test, self.margin, self.local = test, margin, local
        p = test.problem
        self.terms = [t for t in test.model if isinstance(t, PantographBending)]
        self.V = fem.VectorFunctionSpace(p.msh, ("DG", 2), dim=2)
        self.expr = ufl.as_vector([p.energy.kin.lam, p.energy.kin.mu])
        self.X = self.V.tabulate_dof_coordinates()[:, :2]
        self.cell_nodes = self.V.dofmap.list.array.reshape(-1, self.V.dofmap.dof_layout.num_dofs)
        self.history: list[dict] = []

    def _stretch_at_nodes(self) -> np.ndarray:
        return interpolate_expression(self.expr, self.V).x.array.reshape(-1, 2).max(axis=1)

    def max_stretch(self, a: np.ndarray) -> tuple[float, list[float]]:
        """Largest of the fibre stretches ``a`` at the DG2 nodes and its reference position
        (all ranks)."""
        i = int(np.argmax(a)) if len(a) else 0
        local = (float(a[i]), list(map(float, self.X[i]))) if len(a) else (-1.0, [0.0, 0.0])
        comm = self.test.problem.msh.comm
        return max(comm.allgather(local), key=lambda v: v[0])

    def __call__(self, k: int, ubar: float) -> None:
        a = self._stretch_at_nodes()
        rho, where = self.max_stretch(a)
        msh = self.test.problem.msh
        cells = a[self.cell_nodes].max(axis=1) if self.local else \
            np.full(len(self.cell_nodes), rho)
        for t in self.terms:
            t.set_penalty_stretch(msh, np.maximum(t.penalty_stretch,
                                                  penalty_stretch(cells, self.margin, t.gamma)))
        c = math.cos(self.terms[0].gamma) if self.terms else math.cos(math.pi / 6)
        self.history.append({"ubar": ubar, "max_stretch": rho, "rho_cos_gamma": rho * c,
                             "at": where})


def run_range(clamp: str, level: int, ubar: float = 50.0, steps: int = 20,
              limit_stretch: float | None = None, grading: float = 0.6,
              comm: MPI.Comm = MPI.COMM_WORLD, verbose: bool = False,
              moduli: dict | None = None, local_penalty: bool = False) -> dict:
    """Eq. (2) (Table 3 moduli, or ``moduli``: K_S, K_E, K_F) on the graded mesh of ``level``
    to ``ubar`` in ``steps`` steps; returns the curves, the largest stretch per step, Newton
    iterations, times, and the failure (step, load, reason) if the path could not be
    followed. ``local_penalty``: see :class:`PenaltyFollower`. JSON-ready; scalars reduced."""
    model = bipantographic(limit_stretch=limit_stretch, **(moduli or {}))
    t0 = time.perf_counter()
    test = BiasExtension(model, clamp=clamp, specimen=graded_specimen(level, grading, comm=comm),
                         snes_options=RANGE_OPTIONS, comm=comm)
    setup = time.perf_counter() - t0
    follow = PenaltyFollower(test, local=local_penalty)
    step_times, last = [], [time.perf_counter()]

    def on_step(k: int, ub: float) -> None:
        now = time.perf_counter()
        step_times.append(now - last[0])
        follow(k, ub)
        last[0] = time.perf_counter()

    failure = None
    try:
        res = test.run(ubar, steps, verbose=verbose, on_step=on_step)
    except LoadStepError as e:
        failure = e.as_dict()
        res = e.partial if e.partial is not None and e.partial.ubar else None
    V = test.problem.V
    out = {"clamp": clamp, "level": level, "limit_stretch": limit_stretch,
           "local_penalty": local_penalty,
           "moduli": {t.name: t.values() for t in model},
           "dofs": V.dofmap.index_map.size_global * V.dofmap.index_map_bs,
           "setup_seconds": setup, "step_seconds": step_times,
           "stretch": follow.history, "failure": failure,
           "domain_errors": test.solver.domain_errors}
    if res is not None:
        out |= {"ubar": res.ubar, "force": res.force, "angle_A_deg": res.angle_A_deg,
                "angle_B_deg": res.angle_B_deg, "newton": res.newton, "seconds": res.seconds}
    rank0_print(comm, f"[range] {clamp} level {level}: "
                      + (f"failed: {failure['message']}" if failure else
                         f"ū = {ubar} mm reached, force {res.force[-1]:.4f} N, "
                         f"{sum(res.newton)} Newton iterations, {res.seconds:.1f} s"))
    return out


def values_at(run: dict, loads: list[float]) -> list[dict]:
    """Force and shear angles at A and B at the given loads (must be step loads)."""
    rows = []
    for u in loads:
        k = int(np.argmin(np.abs(np.array(run["ubar"]) - u)))
        if abs(run["ubar"][k] - u) > 1e-9:
            raise ValueError(f"ū = {u} is not a step load of the run")
        rows.append({"ubar": u, "force": run["force"][k], "angle_A_deg": run["angle_A_deg"][k],
                     "angle_B_deg": run["angle_B_deg"][k]})
    return rows


def convergence(runs: list[dict], loads: list[float]) -> dict:
    """Observed rates of the grip force at each load over the nested levels of ``runs``."""
    levels = [r["level"] for r in runs]
    out = {}
    for u in loads:
        forces = [values_at(r, [u])[0]["force"] for r in runs]
        out[f"{u:g}"] = {"force": forces, **richardson_summary(levels, forces)}
    return out


def penalty_stretch(rho, margin: float, gamma: float):
    """min(ρ + margin, (ρ + 1/cos γ)/2) (:class:`PenaltyFollower`), for a float or an array."""
    return np.minimum(rho + margin, 0.5 * (rho + 1.0 / math.cos(gamma)))


def follow_penalty(margin: float = 0.03):
    """An ``on_step(test, k, ū)`` callback for
    :func:`research.studies.bias_comparison.compare` that keeps one
    :class:`PenaltyFollower` per continuum test (built at its first step)."""
    followers: dict[int, PenaltyFollower] = {}

    def on_step(test: BiasExtension, k: int, ubar: float) -> None:
        f = followers.setdefault(id(test), PenaltyFollower(test, margin))
        f(k, ubar)

    on_step.followers = followers
    return on_step
