"""What a forward model observes besides displacements at points: a test's own reaction
functional F(u) (``reaction_form``: the hemisphere's punch force) and measured shear angles at
points (``shear.csv``), each with the pieces of its exact sensitivity (forward.py).

The shear angle observed at a point is the test's γ (``shear_angle``) interpolated into DG2
(the ``shear_deg`` output; at a point on element boundaries the mean over the cells there,
evaluation.PointLocator), and its derivative along a displacement sensitivity du/dp is the
interpolant of (∂γ/∂u)·du/dp: interpolation is linear, so that is the exact derivative of the
observed value. The measured points, anywhere on the specimen, are mapped onto the solved
domain by the plug-in (``shear_points``: the hemisphere's quarter by its mirrors, with the
sign a mirror gives γ).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc
from ufl.algorithms import expand_derivatives

from fabricsurf.discretise.evaluation import PointLocator
from fabricsurf.discretise.resources import Owner, release_vectors


class Observers(Owner):
    """The reaction functional and the shear observation of one plug-in ``test`` for the data
    of ``exp`` (module docstring); each is None when the data or the test do not have it."""

    def __init__(self, test, exp) -> None:
        self.comm = test.comm
        u, V = test.problem.u, test.problem.V
        form = test.reaction_form() if exp.has_force else None
        self.reaction = None if form is None else fem.form(form)
        self._dreaction = None if form is None else fem.form(ufl.derivative(form, u))
        u_n = getattr(test.problem, "u_n", None)  # a path history (forming: friction)
        self._reaction_n = None if form is None or u_n is None else (form, u_n)
        self._dreaction_n = None  # compiled when first needed (force_history_gradient)
        self.shear = None
        if exp.has_shear:
            gamma = test.shear_angle()
            if gamma is None:
                raise ValueError(
                    f"experiment '{exp.name}': the '{exp.test}' test gives no "
                    "shear angle to compare with its shear data"
                )
            S = fem.FunctionSpace(test.problem.msh, ("DG", 2))
            self._w = fem.Function(V)
            pts = S.element.interpolation_points()
            self._g, self._dg = fem.Function(S), fem.Function(S)
            self._expr = fem.Expression(gamma, pts)
            self._dexpr = fem.Expression(ufl.derivative(gamma, u, self._w), pts)
            mapped, self._sign = test.shear_points(exp.shear_X)
            self.shear = PointLocator(test.problem.msh, mapped)

    def _release(self) -> None:
        if self.shear is not None:
            release_vectors(self._w, self._g, self._dg)

    def force(self) -> float:
        """F(u) at the current state, reduced over ranks."""
        return float(self.comm.allreduce(fem.assemble_scalar(self.reaction), op=MPI.SUM))

    def force_gradient(self) -> PETSc.Vec:
        """∂F/∂u at the current state (owned entries complete; the caller destroys it)."""
        b = fem_petsc.assemble_vector(self._dreaction)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def force_history_gradient(self) -> PETSc.Vec | None:
        """∂F/∂u_n at the current state, u_n the last converged state of a solver with a path
        history (the punch's friction traction in the hemisphere's force), or None where F
        does not depend on it (the caller destroys it)."""
        if self._reaction_n is not None:
            history = _derivative(*self._reaction_n)
            self._dreaction_n = None if history is None else fem.form(history)
            self._reaction_n = None
        if self._dreaction_n is None:
            return None
        b = fem_petsc.assemble_vector(self._dreaction_n)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def shear_values(self) -> np.ndarray:
        """γ (deg) at every measured shear point (all steps' rows), the same on every rank."""
        self._g.interpolate(self._expr)
        return self.shear(self._g)[:, 0] * self._sign

    def shear_derivative(self, du: fem.Function) -> np.ndarray:
        """(∂γ/∂u)·du (deg) at every measured shear point."""
        self._w.x.array[:] = du.x.array
        self._dg.interpolate(self._dexpr)
        return self.shear(self._dg)[:, 0] * self._sign


def _derivative(form, f):
    """The derivative of ``form`` with respect to the Function ``f``, or None if it vanishes."""
    d = expand_derivatives(ufl.derivative(form, f))
    return None if d.empty() else d
