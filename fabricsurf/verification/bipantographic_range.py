"""The bi-pantographic bias test over its whole range (Barchiesi et al. 2020, Figs. 9–11: ū up
to 25 % of the length), on nested meshes, with both clamp variants.

What makes the homogenised energy (Barchiesi et al. 2020, eq. 2) followable to ū = 50 mm
(measured and explained in docs/bipantographic.md, "Interior penalty"):

* the interior-penalty scale follows the largest fibre stretch of the solution
  (:class:`~fabricsurf.experiments.followers.PenaltyFollower`, which
  :meth:`BiasExtension.run` calls after every converged step by default; no recompilation) —
  with the scale frozen at ρ = 1 the discrete energy loses coercivity near the grip corners
  and Newton stalls, whatever the line search or Jacobian. The scale must keep following up
  to the limit (a fixed ceiling below it stalls the finest position-clamp run once the corner
  stretch passes it): the ceiling is halfway from ρ to the limit;
* the domain-aware solver options (:data:`~fabricsurf.discretise.snes.DOMAIN_AWARE`):
  a backtracking line search that shrinks steps leaving ρ cos γ < 1.

With these, the default Jacobian (no extra form to compile) converges in a few Newton
iterations per step. The exact Jacobian (``jacobian: exact``) needs hardly fewer, but its
kernels for the gradient clamps take minutes to compile, so it is not used here
(docs/verification.md).
"""

from __future__ import annotations

import logging
import time

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.snes import DOMAIN_AWARE
from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.experiments.followers import PenaltyFollower
from fabricsurf.log import detail, rank0
from fabricsurf.model.materials import PantographBending, bipantographic
from fabricsurf.verification.bias_convergence import graded_specimen
from fabricsurf.verification.rates import richardson_summary

logger = logging.getLogger(__name__)

RANGE_OPTIONS = dict(DOMAIN_AWARE)
"""Solver options of the whole-range runs (module docstring)."""


def stretch_history(test: BiasExtension) -> list[dict]:
    """The largest-stretch records of the test's :class:`PenaltyFollower` (empty without one)."""
    return next((f.history for f in test.followers if isinstance(f, PenaltyFollower)), [])


def run_range(
    clamp: str,
    level: int,
    ubar: float = 50.0,
    steps: int = 20,
    limit_stretch: float | None = None,
    grading: float = 0.6,
    comm: MPI.Comm = MPI.COMM_WORLD,
    moduli: dict | None = None,
    local_penalty: bool = False,
    snes_options: dict | None = RANGE_OPTIONS,
) -> dict:
    """Eq. (2) (Table 3 moduli, or ``moduli``: K_S, K_E, K_F) on the graded mesh of ``level``
    to ``ubar`` in ``steps`` steps; returns the curves, the largest stretch per step, Newton
    iterations, times, and the failure (step, load, reason) if the path could not be
    followed. The penalty follows the stretch as in any :class:`BiasExtension` run;
    ``local_penalty``: cell by cell (:class:`PenaltyFollower` ``local``). ``snes_options``
    None: the package's defaults, i.e. the plain public API. JSON-ready; scalars reduced. The
    run is logged at PROGRESS in one line when done, its steps at DEBUG."""
    model = bipantographic(limit_stretch=limit_stretch, **(moduli or {}))
    t0 = time.perf_counter()
    test = BiasExtension(
        model,
        clamp=clamp,
        specimen=graded_specimen(level, grading, comm=comm),
        snes_options=snes_options,
        comm=comm,
    )
    setup = time.perf_counter() - t0
    if local_penalty:
        bending = [t for t in test.model if isinstance(t, PantographBending)]  # its own
        test.followers = [PenaltyFollower(test.problem, bending, local=True)]
    step_times, loads, last = [], [], [time.perf_counter()]

    def on_step(k: int, ub: float) -> None:
        now = time.perf_counter()
        step_times.append(now - last[0])
        loads.append(ub)
        last[0] = now

    failure = None
    try:
        with detail():
            res = test.run(ubar, steps, on_step=on_step)
    except LoadStepError as e:
        failure = e.as_dict()
        res = e.partial if e.partial is not None and e.partial.ubar else None
    V = test.problem.V
    out = {
        "clamp": clamp,
        "level": level,
        "limit_stretch": limit_stretch,
        "local_penalty": local_penalty,
        "moduli": {t.name: t.values() for t in model},
        "dofs": V.dofmap.index_map.size_global * V.dofmap.index_map_bs,
        "setup_seconds": setup,
        "step_seconds": step_times,
        "stretch": [{"ubar": u, **h} for u, h in zip(loads, stretch_history(test))],
        "failure": failure,
        "domain_errors": test.solver.domain_errors,
    }
    if res is not None:
        out |= {
            "ubar": res.ubar,
            "force": res.force,
            "angle_A_deg": res.angle_A_deg,
            "angle_B_deg": res.angle_B_deg,
            "newton": res.newton,
            "seconds": res.seconds,
        }
    rank0(
        logger,
        comm,
        f"[range] {clamp} level {level}: "
        + (
            f"failed: {failure['message']}"
            if failure
            else f"ū = {ubar} mm reached, force {res.force[-1]:.4f} N, "
            f"{sum(res.newton)} Newton iterations, {res.seconds:.1f} s"
        ),
    )
    return out


def values_at(run: dict, loads: list[float]) -> list[dict]:
    """Force and shear angles at A and B at the given loads (must be step loads)."""
    rows = []
    for u in loads:
        k = int(np.argmin(np.abs(np.array(run["ubar"]) - u)))
        if abs(run["ubar"][k] - u) > 1e-9:
            raise ValueError(f"ū = {u} is not a step load of the run")
        rows.append(
            {
                "ubar": u,
                "force": run["force"][k],
                "angle_A_deg": run["angle_A_deg"][k],
                "angle_B_deg": run["angle_B_deg"][k],
            }
        )
    return rows


def convergence(runs: list[dict], loads: list[float]) -> dict:
    """Observed rates of the grip force at each load over the nested levels of ``runs``."""
    levels = [r["level"] for r in runs]
    out = {}
    for u in loads:
        forces = [values_at(r, [u])[0]["force"] for r in runs]
        out[f"{u:g}"] = {"force": forces, **richardson_summary(levels, forces)}
    return out


def follow_penalty():
    """An ``on_step(test, k, ū)`` callback for
    :func:`fabricsurf.verification.bias_comparison.compare` that records, per continuum test,
    the largest stretch its penalty follower saw at each step (``followers``: one record holder
    per test, in the order the tests ran, with ``history`` as in :func:`run_range`).

    A test is told from the previous one by identity, and the callback holds the test of its
    last record: keyed by ``id(test)``, a test built after the previous one was freed could
    take its id and have its records appended to the previous test's."""
    followers: list[_StretchRecord] = []
    current: list[BiasExtension | None] = [None]

    def on_step(test: BiasExtension, k: int, ubar: float) -> None:
        if test is not current[0]:
            current[0] = test
            followers.append(_StretchRecord())
        followers[-1].history.append({"ubar": ubar, **stretch_history(test)[-1]})

    on_step.followers = followers
    return on_step


class _StretchRecord:
    """The largest-stretch records of one test, with the load of each."""

    def __init__(self) -> None:
        self.history: list[dict] = []
