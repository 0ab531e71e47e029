"""Warm starts of a forward model's load steps from its earlier runs (docs/dic.md, "Speed").

A fit or diagnosis runs the same experiment along the same load path many times with nearby
moduli p (Levenberg–Marquardt trials, refits, the linearised scores). A cold run starts every
load step's Newton solve from the previous step's converged state; here step k starts instead
from a stored run's converged state at the same step, corrected by sensitivities:

    u_k(p) ≈ u_k(p₀) + Σ_j (du_k/dp_j)(p₀') (p_j − p₀_j),

with p₀ the moduli of the stored run nearest to p (the largest relative change of a modulus,
the measure of :data:`TRUST`) among the last :data:`KEEP` runs that followed the whole path,
and p₀' those of that run if it computed sensitivities, else of the last one that did (moduli
without a stored sensitivity enter at zeroth order). A refit that returns to the optimum of
an earlier fit, or a ranking run at the optimum a refit just found, so starts from that very
state. Runs shared among the ranks (:func:`~.ranks.spread`) hand their stored runs to every
rank (:func:`snapshot`, :func:`export`, :func:`adopt`), so that the ranks go on alike.
Only when no modulus changed by more than :data:`TRUST` (relative) since p₀: a start from
further away (the scan by decades, a candidate's grid, the first steps of a refit that grows a
candidate from zero) took as many Newton iterations as the cold one, or more (measured with the
residual norm choosing among the starts, which picked such starts and lost). If Newton does not
converge from a warm start, the load stepper follows the step from the last converged state as
without one (:mod:`fabricsurf.discretise.stepping`).

The answer is the same to Newton's tolerance: the bias, picture-frame and cantilever models are
elastic, their equilibrium at a load does not depend on the path to it, and a warm-started solve
stops on an absolute residual of 1e-10 or once a Newton correction is below 1e-8 of the state
(``step_rtol``, the test a cold step ends with: ``SNESSolver.solve``, discretise/solver.py).
A residual relative to the start's is no test here: with stiff yarns (K/k_s ~ 10⁷) the
residual's rounding floor lay above 1e-10 of a good start's, and such solves ran to SNES's
iteration limit before the step was followed again from the last converged state. Newton takes
at least one iteration from any start (``SNESSetForceIteration``): the sensitivities are solved
with the factorisation of the last Jacobian, which a start already converged would otherwise
leave at the previous run's moduli.
A solver with another history — exact constraints by multiplier updates, or a subclass (the
forming plug-in's friction) — is never warm-started.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.solver import SNESSolver

TRUST = 0.3
"""The largest relative change of any modulus since the stored run for which its states are
used (module docstring); beyond it every step starts cold."""

KEEP = 8
"""Runs stored per forward model (the nearest one is used; module docstring): the last
accepted iterate of a refit on each of two ranks and the trials after it fit in."""

PINNED = 4
"""Refit optima kept however many runs come after them (:meth:`WarmStart.latest`): the
confirmed candidates of a round, refitted one after the other on a distributed mesh."""

MEMORY = 50_000_000
"""Bytes of stored states per forward model beyond which the oldest runs go (but never the
latest, nor the latest with sensitivities: what a single stored run kept before)."""

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


def snapshot(model) -> tuple[list[dict], int]:
    """(copies of the runs ``model`` has stored, a mark for :func:`export`): what the ranks
    share before they run different things (:func:`~.ranks.independent`)."""
    ws = model.__dict__.get("_warm_start")
    return ([], 0) if ws is None else ([dict(r) for r in ws.runs], ws.serial)


def export(model, mark: int = 0) -> list[dict]:
    """The runs ``model`` stored after ``mark`` (:func:`snapshot`) and still holds (module
    docstring: for the other ranks)."""
    ws = model.__dict__.get("_warm_start")
    return [] if ws is None else [r for r in ws.runs if r["serial"] > mark]


def adopt(model, runs: list[dict]) -> None:
    """Store ``runs`` (another rank's or this one's, from :func:`export`) as ``model``'s
    latest, in order."""
    if not runs:
        return
    ws = of(model)
    for run in runs:
        ws.store(run)


def latest(fm, p: np.ndarray) -> None:
    """:meth:`WarmStart.latest` for every forward model of ``fm`` (a model or a set)."""
    for m in getattr(fm, "models", [fm]):
        of(m).latest(p)


def carry(fm, p: np.ndarray) -> list[dict | None]:
    """Per forward model of ``fm`` (a model or a set), its stored run nearest the moduli ``p``
    (within :data:`TRUST`) with the sensitivities to correct it and the names of its moduli
    (None where no run is that near): what a forward set of another model on the same meshes
    starts from (:func:`seed`)."""
    out: list[dict | None] = []
    for m in getattr(fm, "models", [fm]):
        ws = m.__dict__.get("_warm_start")
        near = None if ws is None else ws._nearest(np.asarray(p, dtype=float))
        out.append(None if near is None else {"names": list(m.names), **near[0], "du": near[1]})
    return out


def seed(fm, carried: list[dict | None]) -> None:
    """Store in each forward model of ``fm`` the run :func:`carry` took from the same
    experiment's model in another forward set on the same mesh, its moduli and sensitivities
    mapped by name (a modulus the carried model lacks at this model's value). Nothing is
    stored for a model whose states differ in size from the carried ones, or where the carried
    model has a modulus this one lacks that is not zero: its answer would not be this one's.
    Collective: the ranks store alike or not at all (they must go on alike)."""
    for m, c in zip(getattr(fm, "models", [fm]), carried, strict=False):
        names = list(m.names)
        ok = (
            c is not None
            and bool(c["u"])
            and len(c["u"][0]) == len(m.test.solver.u.x.array)
            and not any(c["p"][j] for j, n in enumerate(c["names"]) if n not in names)
        )
        if not m.comm.allreduce(ok, op=MPI.LAND):
            continue
        p = np.array(m.values(), dtype=float)
        for j, n in enumerate(c["names"]):
            if n in names:
                p[names.index(n)] = c["p"][j]
        du = {names.index(c["names"][j]): v for j, v in c["du"].items() if c["names"][j] in names}
        adopt(m, [{"p": p, "u": c["u"], "du": du}])


def _bytes(run: dict) -> int:
    return sum(a.nbytes for a in run["u"]) + sum(a.nbytes for v in run["du"].values() for a in v)


class WarmStart:
    """The last :data:`KEEP` runs' converged states (and sensitivities) of one
    :class:`~.forward.ForwardModel`, and the predictor built from the one nearest to the
    moduli of the run (module docstring). ``starts`` counts the steps started "corrected",
    "uncorrected" (no sensitivities stored, or the same moduli) and "cold" (beyond
    :data:`TRUST`)."""

    def __init__(self, model, enabled: bool = True) -> None:
        sol = model.test.solver
        self._model, self.solver = weakref.ref(model), sol
        self.enabled = enabled and type(sol) is SNESSolver and not sol.multipliers
        if self.enabled:  # a start that already converged still factorises its Jacobian
            sol.snes.setForceIteration(True)
        self.runs: list[dict] = []
        self.serial = 0
        """How many runs were stored (each run's ``serial``: its number)."""
        """The stored runs, oldest first: {"p": moduli, "u": states per step, "du": {j:
        sensitivities per step}} (``du`` empty: the run computed none)."""
        self._run: dict | None = None
        self._base: tuple[dict, dict] | None = None
        self.starts = {"corrected": 0, "uncorrected": 0, "cold": 0}

    # -- recording ----------------------------------------------------------------------
    def recording(
        self, converged: Callable[[int, float, int], None], steps: int
    ) -> Callable[[int, float, int], None]:
        """``converged`` followed by recording the step's state; a run that follows all
        ``steps`` is stored (a failed run is not)."""
        self._run, self._base = {"p": self._model().values(), "u": [], "du": {}}, None

        def observe(k: int, t: float, its: int) -> None:
            run = self._run
            converged(k, t, its)
            run["u"].append(self.solver.u.x.array.copy())
            if k == steps - 1 and len(run["u"]) == steps:
                run["du"] = {j: v for j, v in run["du"].items() if len(v) == steps}
                self.store(run)
                self._run = None

        return observe

    def sensitivities(self, which: list[int], out: list) -> list:
        """Record the sensitivities (du/dp_j as Functions, j in ``which``) of the current step
        of the run being recorded; returns ``out`` unchanged."""
        run = self._run
        if run is not None and self.enabled:
            for j, (du, _) in zip(which, out):
                run["du"].setdefault(j, []).append(du.x.array.copy())
        return out

    def store(self, run: dict) -> None:
        """Keep ``run`` as the latest: the oldest go beyond :data:`KEEP` runs (but not the last
        :data:`PINNED` optima, :meth:`latest`) or :data:`MEMORY`, never the latest nor the
        latest with sensitivities."""
        if not self.enabled:
            return
        self.serial += 1
        run["serial"] = self.serial
        runs = [r for r in self.runs if r is not run] + [run]
        for r in [r for r in runs if r.get("pinned")][:-PINNED]:
            r["pinned"] = False

        for too_many, pins in (
            (lambda: len(runs) > KEEP, True),
            (lambda: sum(map(_bytes, runs)) > MEMORY, False),  # pinned runs too
        ):
            while too_many():
                keep = {id(runs[-1]), id(next((r for r in reversed(runs) if r["du"]), runs[-1]))}
                keep |= {id(r) for r in runs if pins and r.get("pinned")}
                old = next((r for r in runs if id(r) not in keep), None)
                if old is None:
                    break
                runs = [r for r in runs if r is not old]  # by identity: arrays inside
        self.runs = runs

    def latest(self, p: np.ndarray) -> None:
        """Make the stored run at exactly the moduli ``p``, if any, the latest and keep it
        (pinned) while later runs come: a refit's optimum, which the next round's ranking
        starts from if its effect is added, after the trials that did not improve on it and
        the other candidates' refits."""
        at = [r for r in self.runs if np.array_equal(r["p"], p)]
        if at:
            at[-1]["pinned"] = True
            self.store(at[-1])

    # -- prediction ---------------------------------------------------------------------
    def predictor(self) -> Callable[[int, float], np.ndarray | None] | None:
        """The load stepper's predictor (None: warm starts are off)."""
        return self._predict if self.enabled else None

    def _nearest(self, p: np.ndarray) -> tuple[dict, dict] | None:
        """(the stored run nearest to ``p``, the sensitivities to correct it with), or None
        beyond :data:`TRUST`; the latest of equally near runs."""
        best, dist = None, TRUST
        for run in self.runs:
            scale = np.maximum(np.abs(p), np.abs(run["p"]))
            d = np.max(np.abs(p - run["p"]) / np.where(scale > 0, scale, 1.0), initial=0.0)
            if d <= dist:
                best, dist = run, d
        if best is None:
            return None
        du = best["du"] or next((r["du"] for r in reversed(self.runs) if r["du"]), {})
        return best, du

    def _predict(self, k: int, t: float) -> np.ndarray | None:
        p = self._model().values()
        if self._base is None or k == 0:  # the run's start: once per run
            self._base = self._nearest(p) or ({"p": p, "u": []}, {})
        base, dus = self._base
        if k >= len(base["u"]):
            self.starts["cold"] += 1
            return None
        dp = p - base["p"]
        start = base["u"][k].copy()
        for j, du in dus.items():
            start += dp[j] * du[k]
        self.starts["corrected" if dus and np.any(dp) else "uncorrected"] += 1
        return start
