"""The stability check of fitted moduli (docs/usage.md, "Signed moduli and the stability
check"): after a fit or a comparison of a model with a signed modulus, the tangent of its energy
at the states its predictions pass through (:mod:`fabricsurf.model.stability`).

The states are those of the model's own solution at the last load step of every experiment, one
per cell (λ, μ, γ at the cell's midpoint), and the states on the straight path to them from the
reference (:data:`~fabricsurf.model.stability.PATH_FRACTIONS`): the range the data take the
sheet through, as the fitted model sees it. Each experiment is checked at its own fibre angles;
the report is the worst of them.
"""

from __future__ import annotations

import logging

from fabricsurf.discretise.evaluation import fibre_states
from fabricsurf.discretise.stepping import LoadStepError
from fabricsurf.log import muted, rank0, warn
from fabricsurf.model.stability import TangentCheck, check_tangent, path_states

logger = logging.getLogger(__name__)


def has_signed(model: list) -> bool:
    """Whether a term of ``model`` declares a signed modulus."""
    return any(getattr(t, "signed", ()) for t in model)


def fitted_tangent(fs, run: bool = True) -> TangentCheck | None:
    """:class:`~fabricsurf.model.stability.TangentCheck` of the current moduli of ``fs`` (a
    :class:`~fabricsurf.inverse.forward.runs.ForwardSet` or ``ForwardModel``) over the states
    of its solutions; None when no term has a signed modulus (moduli ≥ 0 of the vocabulary's
    convex forms need no check). ``run``: solve at the current moduli first (the last solve of
    a fit may be a rejected trial's). Logged: a line at PROGRESS, a warning when unstable."""
    models = getattr(fs, "models", [fs])
    if not has_signed(models[0].model):
        return None
    if run:
        fs.run()
    worst = None
    for fm in models:
        problem = fm.test.problem
        states = path_states(fibre_states(problem.u, problem.L, problem.M))
        comm = None if fm.local else fm.comm  # a rank-local mesh is whole on every rank
        res = check_tangent(fm.model, fm.exp.fibre_angles_deg, states, comm=comm)
        if worst is None or res.min_eigenvalue < worst.min_eigenvalue:
            worst = res
    if worst.stable:
        rank0(logger, fs.comm, f"  stability: {worst.text()}")
    else:
        warn(logger, fs.comm, f"stability: {worst.text()}")
    return worst


def explained(fs, err: LoadStepError) -> LoadStepError:
    """``err`` (a forward run of ``fs`` that stopped) with the reason when the model has a
    signed modulus and its energy lost stability at the last converged state: a limit point of
    the material, not of the solver (no step cutting passes it)."""
    if not has_signed(getattr(fs, "models", [fs])[0].model):
        return err
    with muted():
        check = fitted_tangent(fs, run=False)
    if check.stable:
        return err
    return err.carrying(f"{err}; at the last converged load {check.text()}")
