"""Model vs measurements: forward model at the recorded grip displacements, misfits, figures.

Misfit (documented weights). Each datum gets a normalised residual
    field: r = (u_model − u_meas)/s_u  for every field row and in-plane component,
    force: r = (F_model − F_meas)/s_F  for every step,
with s_u = ``noise_std`` and s_F = ``force_noise_std`` when the data give them, otherwise
s_u = 1 % of the largest measured displacement magnitude and s_F = 1 % of the largest |force|.
The combined misfit is sqrt(mean r²) over all data (so it is ≈ 1 at the noise level when the
noise is given), χ² = Σ r². Field RMS (mm) and force RMS (N) are reported unweighted.
Rows whose point lies outside the mesh are reported and left out.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from fabricsurf.discretise.evaluation import eval_points
from fabricsurf.discretise.solver import LoadStepper
from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.inverse.data import Experiment
from fabricsurf.model.terms import EFFECTS, Term


@dataclass
class Prediction:
    """Model values at the data: ``u`` (rows×2, NaN outside the mesh), ``force`` (steps);
    with sensitivities ``du`` (rows×2×P) and ``dforce`` (steps×P) w.r.t. the moduli."""

    u: np.ndarray
    force: np.ndarray
    du: np.ndarray | None = None
    dforce: np.ndarray | None = None
    newton: int = 0
    seconds: float = 0.0


def default_h(exp: Experiment) -> float:
    """Element size: a tenth of the specimen width (mm)."""
    return min(exp.length, exp.width) / 10.0


class ForwardModel:
    """The continuum tensile test of an Experiment with a given model (list of terms).

    Parameters are every modulus of every term, in model order (:attr:`params`). :meth:`run`
    follows the recorded grip displacements from the reference state; with ``sens`` it also
    returns du/dp = −J⁻¹ ∂R/∂p at each converged step, using the converged Jacobian's
    factorisation. Π_h (cell energy, C0-IP consistency and penalty terms) is linear in the
    vector of moduli, so ∂R/∂p is the assembled residual with that modulus 1 and all others 0.
    """

    def __init__(self, exp: Experiment, model: list[Term], h: float | None = None,
                 comm: MPI.Comm = MPI.COMM_WORLD, verbose: bool = False) -> None:
        foreign = [t.name for t in model if t.name not in EFFECTS]
        if foreign:
            raise ValueError(f"compare/fit: terms {foreign} are not in the vocabulary "
                             f"({', '.join(EFFECTS)}); the exact sensitivities assume an "
                             "energy linear in each modulus")
        self.exp, self.model, self.verbose = exp, model, verbose
        self.h = float(h or default_h(exp))
        self.bias = BiasExtension(model, exp.length, exp.width, self.h, exp.clamp,
                                  tuple(exp.fibre_angles_deg), comm=comm)
        self.comm = comm
        self.params = [(t, p) for t in model for p in t.parameters()]
        self.names = [f"{t.name}.{p}" for t, p in self.params]
        V = self.bias.problem.V
        self._grip = fem.Function(V)
        self._grip.x.array[self.bias.problem.component_dofs("grip", 0)] = 1.0
        self._bc_dofs = np.concatenate([bc.dof_indices()[0] for bc in self.bias.problem.bcs])
        self._w = fem.Function(V)
        self.forward_runs = 0

    # -- parameters ----------------------------------------------------------------------
    def values(self) -> np.ndarray:
        return np.array([getattr(t, p) for t, p in self.params])

    def set_values(self, vals) -> None:
        for (t, p), v in zip(self.params, vals):
            t.set(**{p: float(v)})

    def param_dict(self) -> dict:
        return {t.name: t.values() for t in self.model}

    # -- solves --------------------------------------------------------------------------
    def _dR_dp(self, k: int) -> PETSc.Vec:
        """∂R/∂p_k at the current u (no boundary conditions)."""
        vals = self.values()
        self.set_values(np.eye(len(vals))[k])
        try:
            b = self.bias.solver.internal_force()
        finally:
            self.set_values(vals)
        return b

    def _sensitivities(self, which: list[int]) -> list[tuple[fem.Function, float]]:
        """(du/dp_k, dF/dp_k) for k in ``which`` at the converged state."""
        s = self.bias.solver
        ksp = s.snes.getKSP()
        A_full = fem_petsc.assemble_matrix(s.a)
        A_full.assemble()
        out, x, Jdu = [], s.x.duplicate(), s.x.duplicate()
        for k in which:
            b = self._dR_dp(k)
            dF = b.dot(self._grip.vector)
            b.scale(-1.0)
            with b.localForm() as loc:
                loc.array[self._bc_dofs] = 0.0
            ksp.solve(b, x)
            A_full.mult(x, Jdu)
            dF += Jdu.dot(self._grip.vector)
            w = fem.Function(self.bias.problem.V)
            x.copy(w.vector)
            w.x.scatter_forward()
            out.append((w, dF))
        A_full.destroy()
        return out

    def run(self, sens: bool | list[int] = False) -> Prediction:
        """Follow the recorded grip displacements; sensitivities for ``sens`` (True: all)."""
        exp, t0 = self.exp, time.perf_counter()
        which = list(range(len(self.params))) if sens is True else list(sens or [])
        P, n = len(which), len(exp.field_step)
        u = np.full((n, 2), np.nan)
        force = np.zeros(len(exp.steps))
        du = np.zeros((n, 2, P)) if which else None
        dF = np.zeros((len(exp.steps), P)) if which else None
        sol = self.bias.solver
        sol.u.x.array[:] = 0.0
        self.bias.set_load(0.0)

        def converged(k: int, ubar: float, its: int) -> None:
            rows = exp.step_rows(exp.steps[k])
            pts = exp.X[rows]
            u[rows] = eval_points(sol.u, pts)[:, :2]
            force[k] = self.bias.problem.reaction("grip", 0)
            for j, (w, dfj) in enumerate(self._sensitivities(which)):
                du[rows, :, j] = eval_points(w, pts)[:, :2]
                dF[k, j] = dfj

        stepper = LoadStepper(sol, self.bias.set_load, converged)
        iters = stepper.run(exp.displacement)
        self.forward_runs += 1
        return Prediction(u, force, du, dF, int(sum(iters)), time.perf_counter() - t0)


# -- misfit ------------------------------------------------------------------------------
def scales(exp: Experiment) -> tuple[float, float]:
    """(s_u, s_F): the noise levels, or 1 % of the largest measured value (module docstring)."""
    s_u = exp.noise_std or 0.01 * float(np.max(np.linalg.norm(exp.u[:, :2], axis=1)))
    s_F = exp.force_noise_std or 0.01 * float(np.max(np.abs(exp.force)))
    return max(s_u, 1e-300), max(s_F, 1e-300)


def residuals(exp: Experiment, pred: Prediction) -> tuple[np.ndarray, np.ndarray | None]:
    """Normalised residual vector r (field rows inside the mesh, then forces) and dr/dp."""
    s_u, s_F = scales(exp)
    inside = np.isfinite(pred.u).all(axis=1)
    r = np.concatenate([((pred.u - exp.u[:, :2])[inside] / s_u).ravel(),
                        (pred.force - exp.force) / s_F])
    if pred.du is None:
        return r, None
    P = pred.du.shape[2]
    Jr = np.vstack([(pred.du[inside] / s_u).reshape(-1, P), pred.dforce / s_F])
    return r, Jr


def misfit(exp: Experiment, pred: Prediction) -> dict:
    """Overall and per-step misfits (see the module docstring) and per-row errors (mm)."""
    s_u, s_F = scales(exp)
    inside = np.isfinite(pred.u).all(axis=1)
    err = np.linalg.norm(pred.u - exp.u[:, :2], axis=1)
    dF = pred.force - exp.force
    r, _ = residuals(exp, pred)
    per_step = []
    for k, s in enumerate(exp.steps):
        rows = exp.step_rows(s)
        rows = rows[inside[rows]]
        e2 = np.sum((pred.u[rows] - exp.u[rows, :2]) ** 2)
        n = 2 * len(rows) + 1
        per_step.append({
            "step": int(s), "displacement": float(exp.displacement[k]),
            "field_rms": float(np.sqrt(e2 / max(2 * len(rows), 1))),
            "force_model": float(pred.force[k]), "force_meas": float(exp.force[k]),
            "force_error": float(dF[k]),
            "combined": float(np.sqrt((e2 / s_u**2 + (dF[k] / s_F) ** 2) / n))})
    return {
        "field_rms": float(np.sqrt(np.mean(err[inside] ** 2) / 2)),
        "force_rms": float(np.sqrt(np.mean(dF**2))),
        "combined": float(np.sqrt(np.mean(r**2))), "chi2": float(np.sum(r**2)), "n": int(r.size),
        "s_u": s_u, "s_F": s_F, "points_outside": int(np.count_nonzero(~inside)),
        "per_step": per_step, "row_error": err}
