"""A punch of any shape in the forming problem: its signed distance and normal tabulated at
the quadrature points from the current placement, for the penalty contact of
experiments/forming/tools.py (docs/tool_surfaces.md).

The analytic punch enters the energy as a UFL expression of the placement r. A punch given as a
surface (experiments/forming/surfaces: a triangle mesh from an STL or OBJ file, or an analytic
shape) is known only through numpy functions of points, so its distance is linearised about a
tabulated state: at each quadrature point the closest point c on the punch (at the stroke s_q of
the tabulation) and the outward normal n there (the distance's gradient) are stored, and

    d(r, s) = n · (r − c − (s − s_q) e_z),

the distance to the tangent plane at c moved with the stroke. The table is refreshed from the
current placement before every residual and Jacobian evaluation (ContactSolver), so that the
residual is the exact variation −k_c ⟨−d⟩ n of the penalty ½ k_c ⟨−d⟩² at the current state and
the Jacobian k_c n ⊗ n H(−d) leaves out only the tool's curvature term k_c ⟨−d⟩ ∂n/∂r (of the
order of the penetration over the tool's radius: Newton converges linearly at that rate where
the punch is curved, quadratically on its flat parts; the classical closest-point-projection
contact of Wriggers 2006, with the normal frozen over an iteration). The punch force
k_c ⟨−d⟩ n_z is that of the analytic punch.

Before any computing the punch is checked against the blank (checks.py): a size far from the
blank's (its units) and a punch that holds nodes of the flat blank at stroke 0 are refused; and
against the die (:func:`die_check`): a punch wider than the die's opening, which a stroke would
drive into the die, is refused at that stroke.
Points farther from a triangle mesh than :data:`CUTOFF` times the punch's size are not
projected (TriangulatedSurface.near): they are out of contact. Friction on a tabulated punch
is not modelled (its potential needs the distance at the last converged state, which the table
holds only to first order).
"""

from __future__ import annotations

import basix
import numpy as np
import ufl
from dolfinx import fem

from fabricsurf.discretise.quadrature import CELL_QUADRATURE_DEGREE
from fabricsurf.errors import InputError
from fabricsurf.experiments.forming import options as forming_options
from fabricsurf.experiments.forming.surfaces import ToolSurface, analytic, checks
from fabricsurf.experiments.forming.surfaces.files import punch_surface

START_TOLERANCE = 1e-6
"""Depth of a blank node inside the punch at stroke 0 taken as touching, in punch sizes."""
CUTOFF = 0.05
"""Distance beyond which a point is not projected onto a triangulated punch, in punch sizes."""
E_Z = np.array([0.0, 0.0, 1.0])
DIE_SPACING = 0.25
"""Spacing of the points sampled near an analytic punch for the die check, in die lip radii."""
GRID_POINTS = 2_000_000
"""Most grid points sampled near an analytic punch for the die check (the spacing grows)."""


class TabulatedPunch:
    """The punch ``surface`` (at stroke 0, moving along +z with the stroke) tabulated at the
    quadrature points of ``msh`` (module docstring); ``friction`` must be 0. :meth:`attach`
    gives it the placement's expression; :meth:`refresh` re-tabulates."""

    def __init__(self, msh, surface: ToolSurface, friction: float = 0.0) -> None:
        if friction:
            raise InputError(
                f"{surface.name}: friction on a punch given as a surface is not modelled "
                "(punch_friction = 0)"
            )
        self.surface, self.msh = surface, msh
        check_against_blank(surface, msh)
        element = ufl.VectorElement(
            "Quadrature", msh.ufl_cell(), CELL_QUADRATURE_DEGREE, quad_scheme="default", dim=3
        )
        Q = fem.FunctionSpace(msh, element)
        self.foot = fem.Function(Q, name="punch_foot")
        self.n = fem.Function(Q, name="punch_normal")
        self.s_q = fem.Constant(msh, 0.0)
        imap = msh.topology.index_map(msh.topology.dim)
        self.cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        dofs = Q.dofmap.list.array.reshape(-1, len(quadrature_points(msh)))[self.cells].ravel()
        self._index = (3 * dofs[:, None] + np.arange(3)).ravel()
        self._r = None
        self._stroke = None

    def attach(self, r, stroke: fem.Constant) -> None:
        """Tabulate from the placement r (a UFL expression of u) at the stroke ``stroke``."""
        points = quadrature_points(self.msh)
        self._r, self._stroke = fem.Expression(r, points), stroke
        self.refresh()

    def refresh(self) -> None:
        """Closest points and normals at the current placement and stroke (module docstring)."""
        s = float(self._stroke.value)
        self.s_q.value = s
        if len(self.cells) == 0:
            return
        x = self._r.eval(self.cells).reshape(-1, 3) - s * E_Z
        near = getattr(self.surface, "near", None)
        if near is not None:
            _, foot, n = near(x, CUTOFF * self.surface.size)
        else:
            d, n = self.surface.signed_distance(x), self.surface.normal(x)
            foot = x - d[:, None] * n
        self.foot.x.array[self._index] = (foot + s * E_Z).ravel()
        self.n.x.array[self._index] = n.ravel()

    def punch(self, r, stroke) -> tuple:
        """(signed distance, vertical component of the normal) at the stroke ``stroke``."""
        d = ufl.dot(self.n, r - self.foot - (stroke - self.s_q) * ufl.as_vector(E_Z.tolist()))
        return d, self.n[2]

    def punch_normal(self, r, stroke) -> tuple:
        """(signed distance, outward normal)."""
        return self.punch(r, stroke)[0], self.n


def check_against_blank(surface: ToolSurface, msh) -> None:
    """Refuse a punch whose size is far from the blank's (units, checks.check_scale) or that
    holds a node of the flat blank at stroke 0 (checks.check_outside); the same verdict on
    every rank."""
    X = msh.geometry.x
    lo = np.min(msh.comm.allgather(X[:, :2].min(axis=0) if len(X) else np.full(2, np.inf)), 0)
    hi = np.max(msh.comm.allgather(X[:, :2].max(axis=0) if len(X) else np.full(2, -np.inf)), 0)
    error = None
    try:
        checks.check_scale(surface, float((hi - lo).max()))
        flat = np.column_stack([X[:, 0], X[:, 1], np.zeros(len(X))])
        checks.check_outside(surface, flat, START_TOLERANCE * surface.size)
    except InputError as e:
        error = str(e)
    errors = [m for m in msh.comm.allgather(error) if m]
    if errors:
        raise InputError(errors[0])


def quadrature_points(msh) -> np.ndarray:
    """The reference points of the cell quadrature (degree CELL_QUADRATURE_DEGREE), in the
    order of the quadrature space's degrees of freedom on a cell."""
    cell = basix.cell.string_to_type(msh.topology.cell_name())
    return basix.make_quadrature(cell, CELL_QUADRATURE_DEGREE)[0]


def die_surface(o: dict) -> analytic.DiePlate:
    """The plug-in's die (Tools: its opening, lip, face at −p_h/k_c) as a surface."""
    face = -o["holder_pressure"] / o["contact_stiffness"]
    return analytic.DiePlate(forming_options.opening(o), o["die_lip"], face)


def checked_punch(o: dict) -> ToolSurface | None:
    """The punch to check against the die (:func:`die_check`): the one given as a surface, the
    analytic hemisphere in an opening that is not the circle about it, else None (that circle
    is wider than the punch by the clearance)."""
    surface = punch_surface(o)
    if surface is None and forming_options.opening(o).kind != "circle":
        return analytic.HemispherePunch(o["punch_radius"])
    return surface


def die_check(surface: ToolSurface, o: dict, reach: float):
    """A function of the stroke that refuses one driving the punch ``surface`` into the die
    (checks.check_stroke against :func:`die_surface`), for strokes up to ``reach``.

    The punch's points are sampled once (checks.surface_points), :data:`DIE_SPACING` lip radii
    apart: on a triangle mesh's triangles, or near an analytic punch on a grid (coarser if the
    box would hold more than :data:`GRID_POINTS`), in the layer of the punch that a stroke up
    to ``reach`` brings to the die (from its face less ``reach`` to the top of its lip). The
    first contact between samples is missed by at most about spacing² over the lip radius."""
    die = die_surface(o)
    bounds = getattr(surface, "bounds", lambda: None)()
    lo, hi = (-surface.size, surface.size) if bounds is None else (bounds[0], bounds[1])
    if getattr(surface, "vertices", None) is not None:
        lo, hi = -np.inf, np.inf  # every vertex in the layer, wherever the mesh lies
    lower = np.array([*np.broadcast_to(lo, 3)[:2], die.face - reach])
    upper = np.array([*np.broadcast_to(hi, 3)[:2], die.face + 2.0 * die.lip])
    spacing = DIE_SPACING * die.lip
    if np.isfinite(lower).all() and np.isfinite(upper).all():
        spacing = max(spacing, (np.prod(upper - lower) / GRID_POINTS) ** (1 / 3))
    points = checks.surface_points(surface, lower, upper, spacing)

    def check(stroke: float) -> None:
        checks.check_stroke(surface, die, points, E_Z, stroke)

    return check
