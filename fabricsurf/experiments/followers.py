"""Step followers: numerical parameters of a model term that follow the converged solution.

Some terms carry a parameter that is not a modulus but must track the state to keep the
discretisation sound. The bi-pantographic bending term (:class:`PantographBending`) takes its
interior-penalty scale at a stretch ρ_p; its stretch-gradient coefficient grows as
1/(1 − ρ²cos²γ), so a penalty frozen at ρ = 1 stops dominating the consistency term where the
stretch concentrates, the discrete energy loses coercivity and Newton stalls part-way along the
load path (docs/bipantographic.md, "Interior penalty").

A follower (:class:`StepFollower`) is built once per problem from the model terms it serves and
called, collectively, after every converged load step; ``reset()`` returns what it set to the
terms' own values (for a run restarted from the reference state). It changes fem.Constants or
DG0 fields only, so nothing is recompiled. :func:`step_followers` builds the followers a model
needs from :data:`FOLLOWERS` (term class → factory), which a plug-in of terms extends with
:func:`register_follower`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np
import ufl
from dolfinx import fem

from fabricsurf.discretise.problem import FabricProblem
from fabricsurf.model.materials import PantographBending
from fabricsurf.model.terms import Term

PENALTY_MARGIN = 0.03
"""How far above the largest stretch ρ the penalty stretch ρ_p is set (when that is not more
than halfway to the limit ρ cos γ = 1)."""


class StepFollower(Protocol):
    """What :func:`step_followers` returns (module docstring)."""

    def __call__(self) -> None: ...

    def reset(self) -> None: ...


FollowerFactory = Callable[[FabricProblem, list[Term]], StepFollower]


def penalty_stretch(rho, margin: float, gamma: float):
    """min(ρ + margin, (ρ + 1/cos γ)/2): above the stretch ρ and at most halfway from it to the
    limit 1/cos γ, so ρ_p stays inside the energy's domain however close ρ comes to the limit
    (a fixed ceiling falls below the stretch and the penalty stops following). For a float or
    an array."""
    return np.minimum(rho + margin, 0.5 * (rho + 1.0 / math.cos(gamma)))


class PenaltyFollower:
    """After each converged step: the largest fibre stretch ρ (and where), and the penalty
    stretch of the given :class:`PantographBending` terms set to
    ρ_p = max(ρ_0, :func:`penalty_stretch` (ρ)), ρ_0 the term's own ``penalty_stretch``
    before the follower raised it (:meth:`floor`). The terms must be those the problem's
    energy was built from (``test.model``: a test's own copies).

    By default ρ is the largest stretch anywhere and ρ_p uniform; with ``local`` ρ is the largest
    stretch in each cell and ρ_p a DG0 field, raised only where the stretch concentrates (more
    accurate on coarse meshes, less robust next to the limit: docs/bipantographic.md).
    ``history`` holds one record per call (largest ρ, ρ cos γ, its reference position).
    """

    def __init__(
        self,
        problem: FabricProblem,
        terms: list[PantographBending],
        margin: float = PENALTY_MARGIN,
        local: bool = False,
    ) -> None:
        self.problem, self.terms, self.margin, self.local = problem, list(terms), margin, local
        kin = problem.energy.kin
        V = fem.VectorFunctionSpace(problem.msh, ("DG", 2), dim=2)
        self._stretch = fem.Function(V)
        self._expr = fem.Expression(
            ufl.as_vector([kin.lam, kin.mu]), V.element.interpolation_points()
        )
        self._X = V.tabulate_dof_coordinates()[:, :2]
        self._cell_nodes = V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)
        self.history: list[dict] = []
        self._floors = [t.penalty_stretch for t in self.terms]
        self._written = list(self._floors)

    def floor(self, k: int) -> float:
        """ρ_0 of ``terms[k]``: its own ``penalty_stretch`` when the follower was made, or as
        ``set`` changed it since (writing ρ_p changes the term's own value too:
        :meth:`PantographBending.set_penalty_stretch`, so what this follower wrote is not
        taken for a new ρ_0)."""
        t = self.terms[k]
        if t.penalty_stretch != self._written[k]:
            self._floors[k] = t.penalty_stretch
        return self._floors[k]

    def _write(self, k: int, values: np.ndarray) -> None:
        t = self.terms[k]
        t.set_penalty_stretch(self.problem.energy.constants_of(t), values)
        self._written[k] = t.penalty_stretch

    def max_stretch(self, nodal: np.ndarray) -> tuple[float, list[float]]:
        """The largest of the stretches ``nodal`` (one per DG2 node) and its reference position,
        the same on every rank."""
        if len(nodal):
            i = int(np.argmax(nodal))
            local = (float(nodal[i]), [float(x) for x in self._X[i]])
        else:
            local = (-1.0, [0.0, 0.0])
        return max(self.problem.msh.comm.allgather(local), key=lambda v: v[0])

    def __call__(self) -> None:
        self._stretch.interpolate(self._expr)
        nodal = self._stretch.x.array.reshape(-1, 2).max(axis=1)
        rho, where = self.max_stretch(nodal)
        cells = (
            nodal[self._cell_nodes].max(axis=1)
            if self.local
            else np.full(len(self._cell_nodes), rho)
        )
        for k, t in enumerate(self.terms):
            self._write(k, np.maximum(self.floor(k), penalty_stretch(cells, self.margin, t.gamma)))
        gamma = self.terms[0].gamma if self.terms else math.pi / 6
        self.history.append(
            {"max_stretch": rho, "rho_cos_gamma": rho * math.cos(gamma), "at": where}
        )

    def reset(self) -> None:
        """ρ_p back to each term's ρ_0 (uniform; :meth:`floor`), the term's own value too; the
        history is kept."""
        for k in range(len(self.terms)):
            self._write(k, np.full(len(self._cell_nodes), self.floor(k)))


FOLLOWERS: dict[type[Term], FollowerFactory] = {PantographBending: PenaltyFollower}
"""The follower factory of each term class that needs one (subclasses included)."""


def register_follower(term_class: type[Term], factory: FollowerFactory) -> None:
    """Give the terms of ``term_class`` (and its subclasses) a follower: ``factory(problem,
    terms)`` is called once per problem with that model's terms of the class."""
    FOLLOWERS[term_class] = factory


def step_followers(problem: FabricProblem, model: list[Term]) -> list[StepFollower]:
    """One follower per registered term class present in ``model`` (the problem's solver must
    have been built, so that its energy exists)."""
    out = []
    for cls, factory in FOLLOWERS.items():
        terms = [t for t in model if isinstance(t, cls)]
        if terms:
            out.append(factory(problem, terms))
    return out
