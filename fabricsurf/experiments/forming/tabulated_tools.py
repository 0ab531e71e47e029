"""A punch or a die of any shape in the forming problem: its signed distance and normal
tabulated at the quadrature points from the current placement, for the penalty contact of
experiments/forming/tools.py (docs/tool_surfaces.md).

The analytic punch enters the energy as a UFL expression of the placement r. A punch given as a
surface (experiments/forming/surfaces: a triangle mesh from an STL or OBJ file, or an analytic
shape) is known only through numpy functions of points, so its distance is linearised about a
tabulated state: at each quadrature point the closest point c on the punch (at the stroke s_q of
the tabulation) and the outward normal n there (the distance's gradient) are stored, and

    d(r, s) = n · (r − c − (s − s_q) e_z),

the distance to the tangent plane at c moved with the stroke. The table is refreshed from the
current placement before every residual and Jacobian evaluation (ContactSolver), so that the
residual is the exact variation −k_c ⟨−d⟩ n of the penalty ½ k_c ⟨−d⟩² at the current state.
For an analytic shape the table also holds the placement r_q it was taken at and the
distance's Hessian K = ∇n there (surfaces/curvature.py), and d gains ½ (r − r_q)·K (r − r_q):
zero with its gradient at the tabulated state, it gives the Jacobian the tool's curvature
term −k_c ⟨−d⟩ K beside k_c n ⊗ n H(−d): the exact tangent (the closest-point projection's,
Wriggers 2006). Newton leaves K zero (:attr:`TabulatedTool.curved` False: the frozen normal,
whose Jacobian stays semi-definite where an iterate dips deep into the tool); the
sensitivities at a converged state take it (ContactSolver.exact_tangent). A triangle mesh's
K vanishes on its faces and is left out. The punch force k_c ⟨−d⟩ n_z is that of the analytic
punch.

Before any computing the punch is checked against the blank (checks.py): a size far from the
blank's (its units) and a punch that holds nodes of the flat blank at stroke 0 are refused; and
against the die (:func:`die_check`): a punch wider than the die's opening, which a stroke would
drive into the die, is refused at that stroke.
A triangle mesh's table is exact within its cutoff of the tool (:data:`CUTOFF` times the
tool's size, or :data:`SOFT_CUTOFF` contact softenings if more), where the penalty acts (the
softened one is below e^(−40) ε beyond). Farther out a point carries a lower bound of its
distance (triangulated.Tracked): the distance at its last projection less how far it moved
since, while that stays beyond the cutoff, else it is projected again; points more than
:data:`BOUND` times the size from every triangle are not projected (TriangulatedSurface.near).
The table is refreshed at every evaluation, so nothing needs more of them, and the sheet far
from the tool, or moving little over a Newton iteration, costs little.
The friction of the punch and of the die's lip (experiments/forming/friction.py) needs the
tool's pressure and normal at the last converged state r_n, fixed over a step: a second table
of the tool (:meth:`TabulatedTool.twin`), tabulated from r_n at the stroke s_n once per step,
where d(r_n, s_n) = n · (r_n − c) is the exact distance (c the closest point of r_n itself).

A die and a holder given as surfaces are tabulated the same way, fixed: d(r) = n · (r − c)
(their placing and checks: experiments/forming/fixed_tools.py).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from fabricsurf.discretise.quadrature import quadrature_points, quadrature_table
from fabricsurf.errors import InputError
from fabricsurf.experiments.forming.surfaces import ToolSurface, checks
from fabricsurf.experiments.forming.surfaces.curvature import distance_hessian, has_curvature
from fabricsurf.experiments.forming.surfaces.triangulated import Tracked

START_TOLERANCE = 1e-6
"""Depth of a blank node inside the punch at stroke 0 taken as touching, in punch sizes."""
CUTOFF = 1e-3
"""Distance from a triangulated tool within which its table is exact, in tool sizes."""
BOUND = 0.05
"""Distance beyond which a point is not projected onto a triangulated tool, in tool sizes: a
point deeper inside it than that would go unseen."""
SOFT_CUTOFF = 40.0
"""The same in the punch's contact softenings ε, where more: the softplus ε ln(1 + e^(−d/ε))
is below e^(−40) ε beyond it."""


class TabulatedTool:
    """The tool ``surface`` (at stroke 0, placed at ``offset``; moving along +z with the stroke
    if ``moving``, the punch, else fixed, the die) tabulated at the quadrature points of
    ``msh`` (module docstring). :meth:`attach` gives it the placement's expression;
    :meth:`refresh` re-tabulates."""

    def __init__(
        self,
        msh,
        surface: ToolSurface,
        moving: bool = True,
        offset=(0.0, 0.0, 0.0),
        softening: float = 0.0,
    ):
        self.surface, self.msh, self.moving = surface, msh, moving
        self.offset, self.softening = np.asarray(offset, float), float(softening)
        cutoff = max(CUTOFF * surface.size, SOFT_CUTOFF * self.softening)
        near = getattr(surface, "near", None) is not None
        self._near = Tracked(surface, cutoff, BOUND * surface.size) if near else None
        Q, self.cells, dofs = quadrature_table(msh, 3)
        self.foot = fem.Function(Q, name="tool_foot")
        self.n = fem.Function(Q, name="tool_normal")
        self.s_q = fem.Constant(msh, 0.0)
        self._index = (3 * dofs[:, None] + np.arange(3)).ravel()
        self.K = self.r_q = None
        self.curved = False  # K left zero: the frozen normal's Jacobian, for Newton
        if has_curvature(surface):  # K = ∇n and the placement it was taken at
            scalar = Q.ufl_element().sub_elements()[0]
            Q9 = fem.FunctionSpace(msh, ufl.VectorElement(scalar, dim=9))
            self.K, self.r_q = fem.Function(Q9, name="tool_curvature"), fem.Function(Q)
            self._index9 = (9 * dofs[:, None] + np.arange(9)).ravel()
        self._r = None
        self._stroke = None

    def attach(self, r, stroke: fem.Constant) -> None:
        """Tabulate from the placement r (a UFL expression of u) at the stroke ``stroke``."""
        points = quadrature_points(self.msh)
        self._r, self._stroke = fem.Expression(r, points), stroke
        self.refresh()

    def refresh(self) -> None:
        """Closest points and normals at the current placement and stroke (module docstring)."""
        s = float(self._stroke.value) if self.moving else 0.0
        self.s_q.value = s
        if len(self.cells) == 0:
            return
        shift = self.offset + s * checks.E_Z
        x = self._r.eval(self.cells).reshape(-1, 3) - shift
        if self._near is not None:
            _, foot, n = self._near(x)
        else:
            d, n = self.surface.signed_distance(x), self.surface.normal(x)
            foot = x - d[:, None] * n
        self.foot.x.array[self._index] = (foot + shift).ravel()
        self.n.x.array[self._index] = n.ravel()
        if self.K is not None and self.curved:  # else K stays zero (Newton's tables)
            self.r_q.x.array[self._index] = (x + shift).ravel()
            self.K.x.array[self._index9] = distance_hessian(self.surface, x).ravel()

    def _parts(self, r, stroke):
        """(r less the foot, r less the tabulated placement or None without K), a moving
        tool's both less its travel since the tabulation."""
        gap, step = r - self.foot, r - self.r_q if self.K is not None else None
        if self.moving:
            lift = (stroke - self.s_q) * ufl.as_vector(checks.E_Z.tolist())
            gap, step = gap - lift, None if step is None else step - lift
        return gap, step

    def _curvature(self):
        return ufl.as_matrix([[self.K[3 * i + j] for j in range(3)] for i in range(3)])

    def distance(self, r, stroke=None):
        """The signed distance at the placement r (a moving tool's at the stroke ``stroke``),
        with the curvature's second-order term where the table holds K (module docstring)."""
        gap, step = self._parts(r, stroke)
        d = ufl.dot(self.n, gap)
        return d if step is None else d + 0.5 * ufl.dot(step, self._curvature() * step)

    def normal(self, r, stroke=None):
        """The outward normal at r, the distance's gradient: n + K (r − r_q) where the table
        holds K, n at the tabulated state with the derivative K there (the punch force's
        sensitivities need it)."""
        _, step = self._parts(r, stroke)
        return self.n if step is None else self.n + self._curvature() * step

    def twin(self) -> TabulatedTool:
        """Another table of the same tool, to be attached elsewhere: the tool's at the last
        converged placement r_n and stroke s_n, for its friction, refreshed once per step
        (module docstring)."""
        twin = TabulatedTool(self.msh, self.surface, self.moving, self.offset, self.softening)
        twin.curved = True  # its r_n is no unknown of Newton's: only ∂/∂u_n sees K
        return twin

    def punch(self, r, stroke) -> tuple:
        """(signed distance, vertical component of the normal) at the stroke ``stroke``."""
        return self.distance(r, stroke), self.normal(r, stroke)[2]

    def punch_normal(self, r, stroke) -> tuple:
        """(signed distance, outward normal)."""
        return self.distance(r, stroke), self.normal(r, stroke)


def tabulated_punch(
    msh, surface: ToolSurface | None, softening: float = 0.0
) -> TabulatedTool | None:
    """The punch given as a surface, checked against the blank; ``softening`` its contact's ε;
    None for none (the analytic punch)."""
    if surface is None:
        return None
    check_against_blank(surface, msh)
    return TabulatedTool(msh, surface, softening=softening)


def check_against_blank(surface: ToolSurface, msh) -> None:
    """Refuse a punch whose size is far from the blank's (units, checks.check_scale) or that
    holds a node of the flat blank at stroke 0 (checks.check_outside); the same verdict on
    every rank."""
    X = msh.geometry.x
    error = None
    try:
        checks.check_scale(surface, blank_size(msh))
        flat = np.column_stack([X[:, 0], X[:, 1], np.zeros(len(X))])
        checks.check_outside(surface, flat, START_TOLERANCE * surface.size)
    except InputError as e:
        error = str(e)
    same_error(msh, error)


def blank_size(msh) -> float:
    """The blank's largest extent in its plane (mm): twice its reach from the punch axis, the
    whole blank's whether the full blank or its quarter is meshed."""
    X = msh.geometry.x
    reach = float(np.abs(X[:, :2]).max()) if len(X) else 0.0
    return 2.0 * msh.comm.allreduce(reach, op=MPI.MAX)


def same_error(msh, error: str | None) -> None:
    """Raise the first rank's error on every rank, if any rank has one."""
    errors = [m for m in msh.comm.allgather(error) if m]
    if errors:
        raise InputError(errors[0])
