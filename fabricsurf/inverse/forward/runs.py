"""The forward model of one or several experiments, with exact sensitivities to the moduli.

:class:`ForwardModel` runs one experiment's plug-in (:mod:`fabricsurf.experiments`) along the
recorded load path from the reference state (:mod:`.load_path`) and observes, at every converged
step, the displacements at the measured points, the measured reaction and shear angles; with
``sens`` also their exact derivatives with respect to the moduli from the converged Jacobian's
factorisation (:mod:`.tangent`, :class:`Observers`; the derivation, and why it is exact because
Π_h is linear (affine with contact) in the moduli: docs/theory.md, "Sensitivities").
:class:`ForwardSet` runs several experiments with one set of moduli: one material, several
tests. Each plug-in builds its forms from its own copies of the terms (``Term.copy``), which
``set_values`` sets without recompiling. On several ranks a small mesh is solved whole on every
rank (:mod:`.ranks`). Both own their plug-ins and every PETSc object: ``close()`` (or ``with``)
destroys them.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fabricsurf.discretise.evaluation import PointLocator
from fabricsurf.discretise.resources import Owner
from fabricsurf.experiments import get_test
from fabricsurf.inverse.contract.experiment import Experiment
from fabricsurf.inverse.forward import misfit as mf
from fabricsurf.inverse.forward import profile, ranks
from fabricsurf.inverse.forward.load_path import Prediction, follow_path
from fabricsurf.inverse.forward.observe import Observers
from fabricsurf.model.terms import EFFECTS, Term


class ForwardModel(Owner):
    """One experiment with a given model (list of vocabulary terms); see the module docstring.

    ``params`` lists every modulus of every term in model order; ``names`` "term.param".
    :attr:`model` is the plug-in's own copy of ``model`` (module docstring).
    :meth:`close` closes its plug-in and its coarse scout.
    """

    def __init__(
        self,
        exp: Experiment,
        model: list[Term],
        h: float | None = None,
        comm: MPI.Comm = MPI.COMM_WORLD,
        local: bool | None = None,
    ) -> None:
        foreign = [t.name for t in model if t.name not in EFFECTS]
        if foreign:
            raise ValueError(
                f"compare/fit: terms {foreign} are not in the vocabulary "
                f"({', '.join(EFFECTS)}); the exact sensitivities assume an "
                "energy linear in each modulus"
            )
        plugin = get_test(exp.test)
        self.exp, self.model, self.comm = exp, model, comm
        self.h = float(h or plugin.default_h(exp.setup))
        self._local_request = local
        cells = ranks.estimated_cells(exp.setup.length, exp.setup.width, self.h)
        self.solve_comm = ranks.solve_comm(comm, cells, local)
        self.local = self.solve_comm is not comm
        """Whether this model solves its mesh whole on every rank (local.py)."""

        def build():  # the plug-in and its observers: every form compiled here
            test = plugin(exp.setup, model, self.h, self.solve_comm)
            try:
                return test, Observers(test, exp)
            except Exception:
                test.close()
                raise

        with ranks.one_voice(comm, self.local):
            self.test, self.observers = ranks.rank0_first(comm, self.local, build)
        self.model = self.test.model  # the plug-in's own terms: set_values sets these
        energy = getattr(self.test.problem, "energy", None)
        if energy is not None and {id(t) for t in self.model} - {id(t) for t, _ in energy.bound}:
            raise ValueError(
                f"experiment plug-in '{exp.test}' builds its forms from other terms "
                "than its own self.model, so a fit would not reach them; build "
                "them from self.model (experiments/base.py)"
            )
        self.components = min(exp.u.shape[1], plugin.d)
        self.ignored = (
            ["uz (the planar test cannot predict it)"]
            if exp.u.shape[1] > plugin.d and exp.has_field
            else []
        )
        self.params = [(t, p) for t in self.model for p in t.parameters()]
        self.names = [f"{t.name}.{p}" for t, p in self.params]
        self.bc_dofs = np.concatenate([bc.dof_indices()[0] for bc in self.test.problem.bcs]).astype(
            np.int32
        )
        self.affine = self.test.problem.extra_energy() is not None
        """A residual part no modulus multiplies (the tools' contact): ∂R/∂p = R(e_k) − R(0)."""
        self.forward_runs = 0
        self._coarse: ForwardModel | None = None
        self._locators: dict[int, tuple[np.ndarray, np.ndarray, PointLocator]] = {}

    def _release(self) -> None:
        self._locators.clear()
        for owner in (self.observers, self.test, self._coarse):
            if owner is not None:
                owner.close()

    def coarse(self, factor: float = 2.0) -> ForwardModel:
        """The same experiment and moduli (copies of this model's terms, which
        :meth:`set_values` keeps at this model's values) on a mesh ``factor`` times coarser,
        built once: a cheap scout for starting values (same forms, so nothing is compiled)."""
        if self._coarse is None:
            ranks.not_alone("a scout mesh")
            self._coarse = ForwardModel(
                self.exp, self.model, self.h * factor, self.comm, local=self._local_request
            )
        return self._coarse

    def mesh(self) -> dict:
        """The mesh this model solves on: h, cells and displacement unknowns (all ranks) and,
        where the plug-in keeps a discretisation record, the mesh kind and the h it used."""
        msh, V = self.test.problem.msh, self.test.problem.V
        rec = getattr(self.test, "discretisation", None) or {}
        return {
            "experiment": self.exp.name,
            "h": self.h,
            "cells": int(msh.topology.index_map(msh.topology.dim).size_global),
            "dofs": int(V.dofmap.index_map.size_global * V.dofmap.index_map_bs),
            "mesh_kind": rec.get("mesh_kind"),
            "h_used": rec.get("h_used", self.h),
        }

    # -- parameters ----------------------------------------------------------------------
    def values(self) -> np.ndarray:
        return np.array([getattr(t, p) for t, p in self.params])

    def set_values(self, vals) -> None:
        """Set the moduli of this model's own terms (and its scout's, if built)."""
        for (t, p), v in zip(self.params, vals):
            t.set(**{p: float(v)})
        if self._coarse is not None:
            self._coarse.set_values(vals)

    @property
    def experiments(self) -> list[Experiment]:
        return [self.exp]

    @property
    def noise_known(self) -> bool:
        return mf.noise_known(self.exp)

    # -- solves --------------------------------------------------------------------------
    def step_points(self, k: int) -> tuple[np.ndarray, PointLocator]:
        """(field rows, their locator) of load step ``k``, found once per model (the mesh does
        not change between runs; the points are compared, so data edited in place are found
        again)."""
        rows = self.exp.step_rows(self.exp.steps[k])
        pts = self.exp.X[rows]
        old = self._locators.get(k)
        if old is None or not (np.array_equal(old[0], rows) and np.array_equal(old[1], pts)):
            self._locators[k] = (rows, pts, PointLocator(self.test.problem.msh, pts))
        return rows, self._locators[k][2]

    def run(self, sens: bool | list[int] = False) -> Prediction:
        """Follow the recorded load path; sensitivities for ``sens`` (True: all moduli). On a
        rank-local model every rank runs it and all return rank 0's outcome (local.py)."""
        with ranks.one_voice(self.comm, self.local):
            return ranks.agree(self.comm, self.local, lambda: self._run(sens))

    def _run(self, sens: bool | list[int]) -> Prediction:
        which = list(range(len(self.params))) if sens is True else list(sens or [])
        pred = follow_path(self, which)
        self.forward_runs += 1
        prof = profile.current()
        if prof is not None:
            prof.add_run(pred.newton)
        return pred

    def residuals(self, pred: Prediction) -> tuple[np.ndarray, np.ndarray | None]:
        return mf.residuals(self.exp, pred)

    def misfit(self, pred: Prediction) -> dict:
        return mf.misfit(self.exp, pred) | ({"ignored": self.ignored} if self.ignored else {})


class ForwardSet(Owner):
    """Several experiments, one set of moduli: runs, stacked residuals, joint misfit;
    :meth:`close` closes every model and the coarse scouts."""

    def __init__(
        self,
        exps: list[Experiment],
        model: list[Term],
        h: float | list[float] | None = None,
        comm: MPI.Comm = MPI.COMM_WORLD,
        local: bool | None = None,
    ) -> None:
        if not exps:
            raise ValueError("no experiments given")
        hs = list(h) if isinstance(h, (list, tuple)) else [h] * len(exps)
        self.models = [ForwardModel(e, model, hk, comm, local=local) for e, hk in zip(exps, hs)]
        first = self.models[0]
        self.comm, self.params, self.names = comm, first.params, first.names
        self._local_request = local
        self._coarse: ForwardSet | None = None

    def _release(self) -> None:
        for owner in [*self.models, self._coarse]:
            if owner is not None:
                owner.close()

    def coarse(self, factor: float = 2.0) -> ForwardSet:
        """Every experiment on a mesh ``factor`` times coarser (:meth:`ForwardModel.coarse`)."""
        if self._coarse is None:
            ranks.not_alone("a scout mesh")
            self._coarse = ForwardSet(
                self.experiments,
                self.model,
                [m.h * factor for m in self.models],
                self.comm,
                local=self._local_request,
            )
        return self._coarse

    @property
    def model(self) -> list[Term]:
        """The first experiment's own terms (at the moduli last set)."""
        return self.models[0].model

    def meshes(self) -> list[dict]:
        """:meth:`ForwardModel.mesh` of every experiment."""
        return [m.mesh() for m in self.models]

    def values(self) -> np.ndarray:
        return self.models[0].values()

    def set_values(self, vals) -> None:
        """Set the moduli in every experiment's own terms (and the scouts', if built)."""
        for m in self.models:
            m.set_values(vals)
        if self._coarse is not None:
            self._coarse.set_values(vals)

    @property
    def experiments(self) -> list[Experiment]:
        return [m.exp for m in self.models]

    @property
    def forward_runs(self) -> int:
        return sum(m.forward_runs for m in self.models)

    @property
    def noise_known(self) -> bool:
        return all(m.noise_known for m in self.models)

    def run(self, sens: bool | list[int] = False) -> list[Prediction]:
        return [m.run(sens) for m in self.models]

    def residuals(self, preds: list[Prediction]) -> tuple[np.ndarray, np.ndarray | None]:
        parts = [m.residuals(p) for m, p in zip(self.models, preds)]
        r = np.concatenate([a for a, _ in parts])
        if any(J is None for _, J in parts):
            return r, None
        return r, np.vstack([J for _, J in parts])

    def misfit(self, preds: list[Prediction]) -> dict:
        """Overall misfit and one entry per experiment (its own misfit dict and name)."""
        per = [{"experiment": m.exp.name} | m.misfit(p) for m, p in zip(self.models, preds)]
        r, _ = self.residuals(preds)
        return {
            "combined": float(np.sqrt(np.mean(r**2))),
            "chi2": float(r @ r),
            "n": int(r.size),
            "experiments": per,
        }
