"""Hencky-type fabric lattice on a rectangular specimen (its micro-macro identification, the
continuum moduli of its springs: :mod:`fabricsurf.network.hencky_moduli`).

Lattice
-------
Nodes sit at the fibre crossings ``X = origin + eps (a L + b M)`` (integers a, b) that lie
in the specimen ``[0, length] x [0, width]`` (mm); for L, M at +-45 degrees this is a
rotated square grid clipped to the rectangle, for other pairs (braids at +-30, bias cuts at
+-40 degrees) a skew grid. Springs (engine conventions, [B (10), (16)]):

* extensional, along both fibre families between fibre neighbours: ``k_e`` (N/mm), l0 = eps;
* bending, on every consecutive triple of a fibre, turning angle phi0 = 0: ``k_b`` (N mm);
* shear, at each crossing: the four angles between consecutive fibre arms (quadrants
  (+L,+M), (+M,-L), (-L,-M), (-M,+L); rest angles theta0, pi - theta0, theta0, pi - theta0),
  each a nonlinear rotational spring ``1/2 k d^2 + 1/4 k4 d^4 + 1/6 k6 d^6`` with
  ``(k, k4, k6) = (k_sh, k_sh4, k_sh6) / 4`` (N mm), so that ``k_sh`` (and ``k_sh4``,
  ``k_sh6``) are the shear stiffnesses per crossing. Quadrants whose arm is missing (nodes
  on the boundary) are dropped: each quadrant spring stands for a quarter of a lattice cell.
  Optional couplings on the same quadrant triples (:mod:`fabricsurf.network.couplings`): a
  shear-tension coupling that makes the quadrant's shear stiffness (k_sh/4)(1 + c_st (e1 + e2))
  with e1, e2 its arms' strains, and a crimp interchange (k_xc/4) e1 e2 per quadrant;
* compression-soft fibre springs (``s_comp``): tension ``(1 - s_comp) k_e (l - l0)`` for l < l0.

Clamps [B Table 1, (7)]
-----------------------
``u = 0`` and zero normal derivative are imposed by holding two node layers: the clamp set
is every node with ``x <= x_min + w`` and the grip set every node with ``x >= x_max - w``,
``w = eps max(|L_x|, |M_x|)`` the x-distance between fibre neighbours (for +-45 degrees the
columns x = 0 and x = eps/sqrt(2); for 0/90 degrees the columns x = 0 and x = eps).
The outer layers sit on the specimen ends only when ``length`` is a whole number of column
steps w (:func:`spanning_spacing` gives the nearest such eps). Otherwise the grip layer lies
up to w inside the specimen: a grip mismatch that a continuum model of the specimen's length
reads as stiffer fibres (measured in docs/diagnosis.md, "The generator's grip layer").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabricsurf.defaults import FRICTION_ANGLE
from fabricsurf.network.couplings import CrossingCouplings
from fabricsurf.network.engine import SpringNetwork
from fabricsurf.network.equilibrium import Dirichlet


@dataclass
class Lattice:
    """A lattice on the specimen.

    Attributes
    ----------
    net : SpringNetwork
    grid : (na, nb) int array
        Node id of fibre crossing (a, b) (a along L, b along M), -1 where absent; the
        input of :mod:`fabricsurf.network.micromacro` (eqs. [B (3)-(6)]).
    L, M : (2,) unit fibre directions; spacing : eps (mm)
    clamp, grip : node ids of the two held layers at x = 0 and at x = length
    spring_sets : dict of index arrays into ``net.ext`` / ``net.rot`` per spring kind
    """

    net: SpringNetwork
    grid: np.ndarray
    L: np.ndarray
    M: np.ndarray
    spacing: float
    clamp: np.ndarray
    grip: np.ndarray
    spring_sets: dict

    def bias_bcs(self, u_bar: float) -> list[Dirichlet]:
        """Table 1 of [B]: clamp layers fixed, grip layers moved by ``u_bar`` e_x (mm)."""
        return [Dirichlet(self.clamp), Dirichlet(self.grip, np.array([u_bar, 0.0]))]


def fibre_directions(angles_deg: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors L, M at the given angles (degrees) from the x axis (need not be orthogonal;
    parallel families are rejected)."""
    return fibre_frame(angles_deg)[1:]


def fibre_frame(angles_deg) -> tuple[float, np.ndarray, np.ndarray]:
    """(sin θ0, L, M): the sine of the angle between the fibre families and their unit
    directions at ``angles_deg`` from the x axis (parallel families are rejected)."""
    t = np.radians(np.asarray(angles_deg, float))
    s0 = abs(np.sin(t[0] - t[1]))
    if not np.all(np.isfinite(t)) or s0 < 1e-6:
        raise ValueError(
            f"fibre angles {tuple(angles_deg)} deg: the two families must be finite "
            "and not parallel"
        )
    return s0, np.array([np.cos(t[0]), np.sin(t[0])]), np.array([np.cos(t[1]), np.sin(t[1])])


def spanning_spacing(
    length: float, spacing: float, angles_deg: tuple[float, float] = (45.0, -45.0)
) -> float:
    """The spacing nearest to ``spacing`` for which ``length`` is a whole number of column
    steps ``w = eps max(|L_x|, |M_x|)``, so that the held layers of :func:`hencky_lattice` sit
    on both specimen ends (exact for fibres at ±θ and at 0/90 degrees)."""
    if not (np.isfinite(spacing) and spacing > 0.0 and np.isfinite(length) and length > 0.0):
        raise ValueError(
            f"spanning_spacing: length {length!r} and spacing {spacing!r} must be positive (mm)"
        )
    _, L, M = fibre_frame(angles_deg)
    c = max(abs(L[0]), abs(M[0]))
    return float(length / (max(1, round(length / (spacing * c))) * c))


def _crossings(length, width, eps, L, M, origin):
    B = eps * np.column_stack([L, M])
    corners = np.array([[0, 0], [length, 0], [0, width], [length, width]]) - origin
    ab = np.linalg.solve(B, corners.T).T
    lo, hi = np.floor(ab.min(0)).astype(int) - 1, np.ceil(ab.max(0)).astype(int) + 1
    A, Bb = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1), indexing="ij")
    X = origin + eps * (A[..., None] * L + Bb[..., None] * M)
    tol = 1e-9 * max(length, width)
    inside = (
        (X[..., 0] >= -tol)
        & (X[..., 0] <= length + tol)
        & (X[..., 1] >= -tol)
        & (X[..., 1] <= width + tol)
    )
    ia, ib = np.nonzero(inside.any(1))[0], np.nonzero(inside.any(0))[0]
    inside = inside[ia[0] : ia[-1] + 1, ib[0] : ib[-1] + 1]
    X = X[ia[0] : ia[-1] + 1, ib[0] : ib[-1] + 1]
    grid = -np.ones(inside.shape, np.int64)
    grid[inside] = np.arange(inside.sum())
    return grid, X[inside]


def _pairs(grid, da, db):
    """Node pairs (g[a,b], g[a+da,b+db]) present in the grid."""
    na, nb = grid.shape
    p = grid[: na - da, : nb - db]
    q = grid[da:, db:]
    ok = (p >= 0) & (q >= 0)
    return np.stack([p[ok], q[ok]], 1)


def _triples(grid, d1, d2):
    """Triples (g[X+d1], g[X], g[X+d2]) present in the grid (d = (da, db) in {-1,0,1})."""
    pad = np.pad(grid, 1, constant_values=-1)
    na, nb = grid.shape
    c = pad[1 : na + 1, 1 : nb + 1]
    n1 = pad[1 + d1[0] : na + 1 + d1[0], 1 + d1[1] : nb + 1 + d1[1]]
    n2 = pad[1 + d2[0] : na + 1 + d2[0], 1 + d2[1] : nb + 1 + d2[1]]
    ok = (c >= 0) & (n1 >= 0) & (n2 >= 0)
    return np.stack([n1[ok], c[ok], n2[ok]], 1)


def hencky_lattice(
    length: float,
    width: float,
    spacing: float,
    angles_deg: tuple[float, float] = (45.0, -45.0),
    k_e: float = 1.0,
    k_sh: float = 1.0,
    k_b: float = 1.0,
    origin: tuple[float, float] = (0.0, 0.0),
    k_sh4: float = 0.0,
    k_sh6: float = 0.0,
    m_shf: float = 0.0,
    gamma_f: float = FRICTION_ANGLE,
    f_slip: float = 0.0,
    eps_slip: float = 1.0,
    c_st: float = 0.0,
    k_xc: float = 0.0,
    s_comp: float = 0.0,
) -> Lattice:
    """Build the Hencky-type fabric lattice of the module docstring.

    Parameters
    ----------
    length, width : specimen size (mm), x = loading direction, origin at the lower left.
    spacing : eps, node spacing along the fibres (mm).
    angles_deg : fibre directions L, M from the x axis (degrees).
    k_e : extensional stiffness per spring (N/mm).
    k_sh : shear stiffness per crossing (N mm/rad^2), split over four quadrant springs.
    k_b : bending stiffness per fibre triple (N mm/rad^2).
    origin : one node position (mm), default the lower-left corner.
    k_sh4, k_sh6 : quartic and sextic shear (locking) stiffnesses per crossing (N mm/rad^4,
        N mm/rad^6), split like ``k_sh``.
    m_shf, gamma_f : saturated friction moment per crossing (N mm) and its shape angle (rad):
        the shear springs' moment ``m_shf tanh(d / gamma_f)``, split like ``k_sh``.
    f_slip, eps_slip : slip tension per fibre spring (N) and its slip strain: the fibre
        springs' tension ``k_e (l - l0) + f_slip tanh((l - l0) / (l0 eps_slip))``.
    c_st : shear-tension coupling (dimensionless): the shear stiffness per crossing becomes
        ``k_sh (1 + c_st (e_L + e_M))``, e_L, e_M the strains of the quadrant's arms.
    k_xc : crimp interchange per crossing (N mm): energy ``k_xc e_L e_M``, split over the four
        quadrants like ``k_sh``.
    s_comp : compression softness of the fibre springs (0 <= s_comp < 1): their stiffness in
        compression is ``(1 - s_comp) k_e`` (:class:`~.engine.SpringNetwork`).
    All three default to 0: the network is then the one without them, bit for bit.
    """
    if not 0.0 <= s_comp < 1.0:
        raise ValueError(f"hencky_lattice: s_comp = {s_comp!r} must be in [0, 1)")
    L, M = fibre_directions(angles_deg)
    grid, X = _crossings(length, width, spacing, L, M, np.asarray(origin, float))
    ext_l, ext_m = _pairs(grid, 1, 0), _pairs(grid, 0, 1)
    bend = [_triples(grid, (-1, 0), (1, 0)), _triples(grid, (0, -1), (0, 1))]
    quads = [((1, 0), (0, 1)), ((0, 1), (-1, 0)), ((-1, 0), (0, -1)), ((0, -1), (1, 0))]
    shear = np.concatenate([_triples(grid, d1, d2) for d1, d2 in quads])
    ext = np.concatenate([ext_l, ext_m])
    rot = np.concatenate(bend + [shear])
    nb = len(bend[0]) + len(bend[1])
    k_rot = np.concatenate([np.full(nb, float(k_b)), np.full(len(shear), k_sh / 4.0)])
    k_rot4, k_rot6, m_fric = (
        np.concatenate([np.zeros(nb), np.full(len(shear), k / 4.0)]) for k in (k_sh4, k_sh6, m_shf)
    )
    phi0 = np.concatenate([np.zeros(nb), np.full(len(shear), np.nan)])
    net = SpringNetwork(
        X,
        ext,
        k_e,
        l0=spacing,
        rot=rot,
        k_rot=k_rot,
        phi0=phi0,
        k_rot4=k_rot4,
        k_rot6=k_rot6,
        m_fric=m_fric,
        phi_f=gamma_f,
        f_slip=f_slip,
        eps_slip=eps_slip,
        s_comp=s_comp,
    )
    ref = net.turning_angles(X)
    net.phi0[nb:] = ref[nb:]
    if c_st != 0.0 or k_xc != 0.0:
        net.couplings = CrossingCouplings(
            nb + np.arange(len(shear)),
            shear,
            spacing,
            net.phi0[nb:],
            k_st=c_st * k_sh / 4.0,
            k_x=k_xc / 4.0,
        )
    w = spacing * max(abs(L[0]), abs(M[0]))
    tol = 1e-6 * spacing
    clamp = np.nonzero(X[:, 0] <= X[:, 0].min() + w + tol)[0]
    grip = np.nonzero(X[:, 0] >= X[:, 0].max() - w - tol)[0]
    sets = {
        "stretch_l": np.arange(len(ext_l)),
        "stretch_m": len(ext_l) + np.arange(len(ext_m)),
        "bending": np.arange(nb),
        "shear": nb + np.arange(len(shear)),
    }
    return Lattice(net, grid, L, M, float(spacing), clamp, grip, sets)
