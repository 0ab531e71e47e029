"""Exact pointwise constraints g(u) = 0 by an augmented Lagrangian (docs/theory.md).

A constraint holds at every cell quadrature point of the energy. Its multiplier T lives in a
quadrature space of the same degree, and the constraint adds

    ∫ ( T g(u) + ½ r g(u)² ) dx

to Π_h, with r > 0 the augmentation stiffness. Each Newton solve is done at fixed T; then T is
updated to T + r g(u) at the quadrature points (Uzawa's iteration on the augmented Lagrangian,
Fortin & Glowinski 1983) until max |g| is below the tolerance. The multiplier converges to the
reaction of the constraint: for inextensible fibres g = λ − 1, and T is the fibre tension per
unit reference width (N/mm). T is part of the state: the load stepper saves and restores it
with u when it cuts a step.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.evaluation import quadrature_expression

CONSTRAINT_TOLERANCE = 1e-9
"""Largest |g| accepted at a quadrature point (for stretches: a relative elongation)."""

MAX_MULTIPLIER_UPDATES = 60
"""Uzawa updates per Newton solve before the step counts as failed."""


class Multiplier:
    """The multiplier field T of one constraint g = 0 and its update (module docstring).

    ``g`` is a UFL expression of u, ``r`` the augmentation stiffness (a fem.Constant or float),
    ``degree`` the quadrature degree of the cell integrals that carry it.
    """

    def __init__(self, name: str, g, r, msh, degree: int) -> None:
        element = ufl.FiniteElement("Quadrature", msh.ufl_cell(), degree, quad_scheme="default")
        self.name, self.g, self.r, self.degree = name, g, r, degree
        self.space = fem.FunctionSpace(msh, element)
        self.T = fem.Function(self.space, name=name)
        self._g = quadrature_expression(g, msh, degree)
        self._tension = quadrature_expression(self.tension(), msh, degree)
        tdim = msh.topology.dim
        imap = msh.topology.index_map(tdim)
        self._cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        self._dofs = self.space.dofmap.list.array.reshape(len(self._cells), -1)
        self.comm = msh.comm

    def energy_density(self):
        """T g + ½ r g² (per unit reference area)."""
        return self.T * self.g + 0.5 * self.r * self.g**2

    def tension(self):
        """The constraint force T + r g (UFL), → T as g → 0."""
        return self.T + self.r * self.g

    def violation(self) -> float:
        """max |g| over all quadrature points of all ranks."""
        local = np.abs(self._g.eval(self._cells)).max() if len(self._cells) else 0.0
        return float(self.comm.allreduce(float(local), op=MPI.MAX))

    def update(self) -> None:
        """T ← T + r g at every quadrature point (ghost cells included, so no scatter)."""
        self.T.x.array[self._dofs] = self._tension.eval(self._cells)

    def state(self) -> np.ndarray:
        return self.T.x.array.copy()

    def restore(self, state: np.ndarray) -> None:
        self.T.x.array[:] = state
