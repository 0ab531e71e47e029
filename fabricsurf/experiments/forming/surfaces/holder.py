"""A blank holder given as a surface: where it presses the flange, and that pressure's weight
tabulated at the quadrature points (docs/tool_surfaces.md, "A holder given as a surface").

The analytic holder presses the flange with p_h w, w = S(t) = 3t² − 2t³,
t = clamp(σ/r_d − 2, 0, 1), σ the signed in-plane distance from the die opening's outline
(experiments/forming/tools.py): its face is flat from σ = r_d, so the pressure rises from one
lip radius inside the face to full one lip radius further. A holder given as a surface is
given with its face, where it presses, at z = 0 and facing up (the plug-in places it at −g, g
the holder's gap). Its footprint is the union of its upward triangles at z = 0, e the signed
in-plane distance from the footprint's outline (positive inside), and its pressure's weight
w = S(clamp(e/r_d − 1, 0, 1)). On the analytic holder's own shape e = σ − r_d, and w is the
analytic one; on a holder whose face starts farther out, the pressure does too.

The weight is read at the sheet's current in-plane position. A :class:`HolderPress` tabulates
e and its gradient at the quadrature points from the current placement whenever the contact
tables are refreshed (before every residual and Jacobian), and the forms see e linearised
about that state, e_q + ∇e·(r − r_q): the value there, and its derivative.
"""

from __future__ import annotations

import functools

import numpy as np
import ufl
from dolfinx import fem
from scipy.spatial import cKDTree

from fabricsurf.discretise.quadrature import quadrature_points, quadrature_table
from fabricsurf.errors import InputError

UP = 1.0 - 1e-6
"""A triangle of the face points up: the z component of its unit outward normal above this."""
FACE_TOLERANCE = 1e-6
"""How far a face triangle's corners may leave z = 0, in the holder's sizes."""
CANDIDATES = 8
"""Outline samples whose segments are measured exactly for each point."""
FOOTPRINTS_KEPT = 2
"""Holder footprints :func:`footprint_of` keeps."""


def ramp(t):
    """S(t) = 3t² − 2t³ of t clamped to [0, 1] (UFL)."""
    t = ufl.min_value(ufl.max_value(t, 0.0), 1.0)
    return t**2 * (3.0 - 2.0 * t)


@functools.lru_cache(maxsize=FOOTPRINTS_KEPT)
def footprint_of(surface) -> Footprint:
    """The :class:`Footprint` of a holder surface, built once for its users (the die's face
    check, the unheld-edge warning, the tables): a large mesh's outline takes a while."""
    return Footprint(surface)


class Footprint:
    """The outline of a triangulated holder's face (module docstring) and the signed in-plane
    distance e from it. The outline's segments keep their triangles' direction, the face on
    their left (seen from above); e's sign at a point comes from the segment nearest to it, or
    where that nearest point is a corner, from the sum of its two segments' outward normals."""

    def __init__(self, surface) -> None:
        V, F = getattr(surface, "vertices", None), getattr(surface, "faces", None)
        name = getattr(surface, "name", "holder")
        if V is None or F is None:
            raise InputError(
                f"{name}: a holder must be a triangle mesh (an STL or OBJ file, or a gmsh "
                "surface): the outline of its face is read from its triangles"
            )
        flat = np.all(np.abs(V[F][:, :, 2]) <= FACE_TOLERANCE * surface.size, axis=1)
        top = F[flat & (surface.face_normal[:, 2] > UP)]
        if len(top) == 0:
            low, high = V[:, 2].min(), V[:, 2].max()
            raise InputError(
                f"{name}: no face of the holder lies at z = 0 facing up (it spans z = "
                f"{low:.4g} to {high:.4g} mm): a holder is given with its face, where it "
                "presses the flange against the die, at the blank's plane z = 0"
            )
        edges = np.concatenate([top[:, [0, 1]], top[:, [1, 2]], top[:, [2, 0]]])
        _, inverse, count = np.unique(
            np.sort(edges, axis=1), axis=0, return_inverse=True, return_counts=True
        )
        outline = edges[count[inverse.ravel()] == 1]
        self.a, self.b = V[outline[:, 0], :2], V[outline[:, 1], :2]
        d = self.b - self.a
        length = np.linalg.norm(d, axis=1)
        self.out = np.column_stack([d[:, 1], -d[:, 0]]) / length[:, None]
        corner = np.zeros((len(V), 2))
        np.add.at(corner, outline[:, 0], self.out)
        np.add.at(corner, outline[:, 1], self.out)
        self.corner_a, self.corner_b = corner[outline[:, 0]], corner[outline[:, 1]]
        spacing = 0.5 * float(length.min())
        per = np.maximum(2, np.ceil(length / spacing).astype(int) + 1)
        self.owner = np.repeat(np.arange(len(length)), per)
        t = np.concatenate([np.linspace(0.0, 1.0, n) for n in per])
        self.tree = cKDTree(self.a[self.owner] + t[:, None] * d[self.owner])
        self.name = name

    def __call__(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(e, ∇e) at the in-plane points ``xy`` (n, 2)."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        if len(xy) == 0:
            return np.zeros(0), np.zeros((0, 2))
        k = min(CANDIDATES, len(self.owner))
        seg = self.owner[self.tree.query(xy, k=k)[1].reshape(len(xy), k)]
        a, ab = self.a[seg], self.b[seg] - self.a[seg]
        t = np.einsum("nkj,nkj->nk", xy[:, None, :] - a, ab) / np.einsum("nkj,nkj->nk", ab, ab)
        t = np.clip(t, 0.0, 1.0)
        gap = xy[:, None, :] - (a + t[..., None] * ab)
        dist = np.linalg.norm(gap, axis=2)
        j = np.argmin(dist, axis=1)
        rows = np.arange(len(xy))
        s, tj, g = seg[rows, j], t[rows, j], gap[rows, j]
        at_a, at_b = (tj <= 0.0)[:, None], (tj >= 1.0)[:, None]
        normal = np.where(at_a, self.corner_a[s], np.where(at_b, self.corner_b[s], self.out[s]))
        sign = np.where(np.einsum("nj,nj->n", g, normal) > 0.0, -1.0, 1.0)  # + inside
        r = dist[rows, j]
        away = np.where(r > 0.0, r, 1.0)[:, None]  # on the outline: ∇e = −the outward normal
        inward = -normal / np.linalg.norm(normal, axis=1)[:, None]
        unit = np.where((r > 0.0)[:, None], g / away, inward)
        return sign * r, sign[:, None] * unit


def unheld_by(
    footprint: Footprint, lip: float, half_x: float, half_y: float, round_blank: bool
) -> str | None:
    """Why the middle of a blank's sides (``half_x``, ``half_y`` from the axis; a disc of
    radius ``half_x`` if ``round_blank``) is not under the holder's full pressure (e ≥ 2 r_d),
    or None: the flange there is held by the holder's gap alone, free to buckle
    (forming/options.unheld_edge)."""
    half_y = half_x if round_blank else half_y
    sides = np.array([[half_x, 0.0], [0.0, half_y], [-half_x, 0.0], [0.0, -half_y]])
    e = footprint(sides)[0]
    if e.min() >= 2.0 * lip:
        return None
    k = int(np.argmin(e))
    return (
        f"hemisphere: the blank's edge at {sides[k].tolist()} mm is {e[k]:.3g} mm inside the "
        f"outline of the face of {footprint.name} (negative: outside), where its pressure is "
        f"full from {2.0 * lip:g} mm (twice the die's lip) inside: the flange there is held by "
        "the holder's gap alone and may buckle (wrinkles, cut steps)"
    )


class HolderPress:
    """The weight w of a holder given as a surface, tabulated at the quadrature points of
    ``msh`` from a placement (module docstring): :meth:`attach` gives it the placement's
    expression, :meth:`refresh` re-tabulates e and ∇e there, :meth:`weight` is w in UFL."""

    K = None  # no curvature term (ContactSolver.exact_tangent asks every table)

    def __init__(self, msh, footprint: Footprint, lip: fem.Constant) -> None:
        self.msh, self.footprint, self.lip = msh, footprint, lip
        Q, self.cells, dofs = quadrature_table(msh, 3)
        self.table = fem.Function(Q, name="holder_edge")  # (e − ∇e·r_q, ∂e/∂x, ∂e/∂y)
        self._index = (3 * dofs[:, None] + np.arange(3)).ravel()
        self._r = self._xy = self._e = None  # the positions last tabulated, and e there

    def attach(self, r, stroke=None) -> None:
        """Tabulate from the placement r (a UFL expression of u); the stroke plays no part."""
        self._r = fem.Expression(r, quadrature_points(self.msh))
        self.refresh()

    def refresh(self) -> None:
        """e and ∇e at the current in-plane positions of the points that need them: those in
        the ramp's band r_d < e < 2 r_d, or that may have reached it, having moved farther
        since their last tabulation than they were from it (e changes by at most the motion).
        Elsewhere w is 0 or 1 with a zero derivative, and the old linearisation gives the
        same: it too moves by at most the motion."""
        if len(self.cells) == 0:
            return
        xy = self._r.eval(self.cells).reshape(-1, 3)[:, :2]
        lip = float(self.lip.value)
        if self._xy is None:
            self._xy, self._e = np.full(xy.shape, np.nan), np.zeros(len(xy))
        away = np.maximum(lip - self._e, self._e - 2.0 * lip)
        need = ~(np.linalg.norm(xy - self._xy, axis=1) < away)  # NaN: never tabulated
        if not need.any():
            return
        e, grad = self.footprint(xy[need])
        self._xy[need], self._e[need] = xy[need], e
        values = self.table.x.array.reshape(-1, 3)
        rows = self._index.reshape(-1, 3)[need, 0] // 3
        values[rows] = np.column_stack([e - np.einsum("nj,nj->n", grad, xy[need]), grad])

    def edge_distance(self, r):
        """e at the placement r, linear about the tabulated state."""
        return self.table[0] + self.table[1] * r[0] + self.table[2] * r[1]

    def weight(self, r):
        """w = S(e/r_d − 1) (module docstring)."""
        return ramp(self.edge_distance(r) / self.lip - 1.0)

    def twin(self) -> HolderPress:
        """Another table of the same holder, to be attached at the last converged placement
        (the holder's friction: experiments/forming/friction.py)."""
        return HolderPress(self.msh, self.footprint, self.lip)
