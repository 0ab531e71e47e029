"""One forward run along an experiment's recorded load path (:func:`follow_path`), and what it
predicts at the data (:class:`Prediction`): the displacements at the measured points, the
reaction and the shear angles at every converged step, with their exact sensitivities to the
moduli (:mod:`.tangent`; docs/theory.md, "Sensitivities"). The forward model
(:class:`~.runs.ForwardModel`) owns the plug-in, its observers and the point locators; this
is the run itself.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass

import numpy as np

from fabricsurf.discretise.stepping import LoadStepError, LoadStepper
from fabricsurf.inverse.forward import path, tangent, warm_start


@dataclass
class Prediction:
    """Model values at the data: ``u`` (rows×c, NaN outside the mesh; c compared components),
    ``force`` (steps, or None), ``shear`` (shear rows, deg, or None); sensitivities ``du``
    (rows×c×P), ``dforce`` (steps×P), ``dshear`` (shear rows×P)."""

    u: np.ndarray
    force: np.ndarray | None
    du: np.ndarray | None = None
    dforce: np.ndarray | None = None
    newton: int = 0
    seconds: float = 0.0
    shear: np.ndarray | None = None
    dshear: np.ndarray | None = None


def follow_path(fm, which: list[int]) -> Prediction:
    """One run of the forward model ``fm`` (a :class:`~.runs.ForwardModel`) along its
    experiment's recorded load path from the reference state: at every converged step the
    displacements at the step's field points, the reaction and the shear angles, with their
    sensitivities to the moduli ``which`` (indices into ``fm.params``; tangent solves, started
    from the last run's, warm_start.py). A step that fails raises LoadStepError carrying the
    steps converged before it (``partial``) and the experiment's name."""
    exp, t0, c = fm.exp, time.perf_counter(), fm.components
    P, n, with_force = len(which), len(exp.field_step), exp.has_force
    u = np.full((n, c), np.nan)
    force = np.zeros(len(exp.steps)) if with_force else None
    du = np.zeros((n, c, P)) if which else None
    dF = np.zeros((len(exp.steps), P)) if which and with_force else None
    obs = fm.observers
    shear = np.full(len(exp.shear_step), np.nan) if exp.has_shear else None
    dshear = np.zeros((len(exp.shear_step), P)) if which and exp.has_shear else None
    sol = fm.test.solver
    sol.u.x.array[:] = 0.0
    getattr(sol, "reset", lambda: None)()  # a path history (forming: friction, predictor)
    fm.test.set_load(0.0)
    ws = warm_start.of(fm)  # each step started from the last run's (warm_start.py)
    weight = lambda: fm.test.reaction_weight() if with_force else None  # noqa: E731
    history = path.PathSensitivities(fm, which, weight) if path.along_path(fm, which) else None

    def converged(k: int, t: float, its: int) -> None:
        rows, at = fm.step_points(k)
        if len(rows):
            u[rows] = at(sol.u)[:, :c]
        srows = exp.shear_rows(exp.steps[k]) if shear is not None else []
        if len(srows):
            shear[srows] = obs.shear_values()[srows]
        w = weight()
        if w is not None:
            force[k] = sol.virtual_work(w)
        elif with_force and obs.reaction is not None:
            force[k] = obs.force()
        if history is not None and history.current is not None:
            sens = history.current
        else:  # no path history, or no solve yet (a step at load 0): per step is exact
            sens = tangent.sensitivities(fm, which, w)
        sens = ws.sensitivities(which, sens)
        for j, (duj, dfj) in enumerate(sens):
            if len(rows):
                du[rows, :, j] = at(duj)[:, :c]
            if len(srows):
                dshear[srows, j] = obs.shear_derivative(duj)[srows]
            if dF is not None:
                dF[k, j] = dfj

    stepper = LoadStepper(
        sol,
        fm.test.set_load,
        ws.recording(converged, len(exp.path)),
        predictor=ws.predictor(),
    )
    try:
        with history or contextlib.nullcontext():
            iters = stepper.run(exp.path)
    except LoadStepError as e:
        done = len(stepper.iterations)
        if force is not None:
            force[done:] = np.nan
        for s in exp.steps[done:]:
            u[exp.step_rows(s)] = np.nan
        raise e.carrying(partial=Prediction(u, force, shear=shear), experiment=exp.name) from e
    return Prediction(u, force, du, dF, int(sum(iters)), time.perf_counter() - t0, shear, dshear)
