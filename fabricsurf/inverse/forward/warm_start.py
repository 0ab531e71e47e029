"""Warm starts of a forward model's load steps from its previous run (docs/dic.md, "Speed").

A fit or diagnosis runs the same experiment along the same load path many times with nearby
moduli p (Levenberg–Marquardt trials, refits, the linearised scores). A cold run starts every
load step's Newton solve from the previous step's converged state; here step k starts instead
from the previous run's converged state at the same step, corrected by its sensitivities:

    u_k(p) ≈ u_k(p₀) + Σ_j (du_k/dp_j)(p₀') (p_j − p₀_j),

with p₀ the moduli of the last run that followed the whole path and p₀' those of the last one
that also computed sensitivities (moduli without a stored sensitivity enter at zeroth order).
Only when no modulus changed by more than :data:`TRUST` (relative) since p₀: a start from
further away (the scan by decades, a candidate's grid, the first steps of a refit that grows a
candidate from zero) took as many Newton iterations as the cold one, or more (measured with the
residual norm choosing among the starts, which picked such starts and lost). If Newton does not
converge from a warm start, the load stepper follows the step from the last converged state as
without one (:mod:`fabricsurf.discretise.stepping`).

The answer is the same to Newton's tolerance: the bias, picture-frame and cantilever models are
elastic, their equilibrium at a load does not depend on the path to it, and SNES stops on an
absolute residual of 1e-10 or on 1e-10 relative to the start's (a start closer to the solution
is held to the tighter of the two). Newton takes at least one iteration from any start
(``SNESSetForceIteration``): the sensitivities are solved with the factorisation of the last
Jacobian, which a start already converged would otherwise leave at the previous run's moduli.
A solver with another history — exact constraints by multiplier updates, or a subclass (the
forming plug-in's friction) — is never warm-started.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable

import numpy as np

from fabricsurf.discretise.solver import SNESSolver

TRUST = 0.3
"""The largest relative change of any modulus since the stored run for which its states are
used (module docstring); beyond it every step starts cold."""

ENABLED = True
"""Whether new forward models warm-start their runs (False: every run cold, as before; for
comparisons, tests/test_warm_start.py)."""


def of(model) -> WarmStart:
    """The warm start of ``model`` (a :class:`~.forward.ForwardModel`), made on first use and
    kept on the model; it holds the model only weakly (no reference cycle: the model still
    goes, and destroys its PETSc objects, by reference counting). The model hands it each
    step's sensitivities (:meth:`WarmStart.sensitivities`)."""
    ws = model.__dict__.get("_warm_start")
    if ws is None:
        ws = model._warm_start = WarmStart(model, ENABLED)
    return ws


def forget(model) -> None:
    """Drop what ``model``'s runs stored: its next run starts every step cold."""
    model.__dict__.pop("_warm_start", None)


class WarmStart:
    """The last run's converged states (and its last sensitivities) of one
    :class:`~.forward.ForwardModel`, and the predictor built from them (module docstring).
    ``starts`` counts the steps started "corrected", "uncorrected" (no sensitivities stored, or
    the same moduli) and "cold" (beyond :data:`TRUST`)."""

    def __init__(self, model, enabled: bool = True) -> None:
        sol = model.test.solver
        self._model, self.solver = weakref.ref(model), sol
        self.enabled = enabled and type(sol) is SNESSolver and not sol.multipliers
        if self.enabled:  # a start that already converged still factorises its Jacobian
            sol.snes.setForceIteration(True)
        self._u: list[np.ndarray] | None = None
        self._p: np.ndarray | None = None
        self._du: dict[int, list[np.ndarray]] = {}
        self._run: dict | None = None
        self.starts = {"corrected": 0, "uncorrected": 0, "cold": 0}

    # -- recording ----------------------------------------------------------------------
    def recording(
        self, converged: Callable[[int, float, int], None], steps: int
    ) -> Callable[[int, float, int], None]:
        """``converged`` followed by recording the step's state; a run that follows all
        ``steps`` replaces the stored one (a failed run leaves it as it was)."""
        self._run = {"p": self._model().values(), "u": [], "du": {}}

        def observe(k: int, t: float, its: int) -> None:
            run = self._run
            converged(k, t, its)
            run["u"].append(self.solver.u.x.array.copy())
            if k == steps - 1 and len(run["u"]) == steps:
                self._commit(run, steps)

        return observe

    def sensitivities(self, which: list[int], out: list) -> list:
        """Record the sensitivities (du/dp_j as Functions, j in ``which``) of the current step
        of the run being recorded; returns ``out`` unchanged."""
        run = self._run
        if run is not None and self.enabled:
            for j, (du, _) in zip(which, out):
                run["du"].setdefault(j, []).append(du.x.array.copy())
        return out

    def _commit(self, run: dict, steps: int) -> None:
        self._u, self._p = run["u"], run["p"]
        full = {j: v for j, v in run["du"].items() if len(v) == steps}
        if full:
            self._du = full
        self._run = None

    # -- prediction ---------------------------------------------------------------------
    def predictor(self) -> Callable[[int, float], np.ndarray | None] | None:
        """The load stepper's predictor (None: warm starts are off)."""
        return self._predict if self.enabled else None

    def _predict(self, k: int, t: float) -> np.ndarray | None:
        if self._u is None or k >= len(self._u):
            return None
        p = self._model().values()
        dp = p - self._p
        scale = np.maximum(np.abs(p), np.abs(self._p))
        if np.max(np.abs(dp) / np.where(scale > 0, scale, 1.0), initial=0.0) > TRUST:
            self.starts["cold"] += 1
            return None
        start = self._u[k].copy()
        for j, du in self._du.items():
            start += dp[j] * du[k]
        self.starts["corrected" if self._du and np.any(dp) else "uncorrected"] += 1
        return start
