"""Fibre-aligned triangulations of a rectangle for two fibre families at ±θ to its long side.

On a mesh whose edges do not follow the fibres, conforming elements cannot shear without
stretching a fibre somewhere in each element, so the response of nearly inextensible yarns
grows with their stiffness (intra-ply shear locking, Yu et al. 2005; ten Thije & Akkerman
2008). Here every interior edge lies along one of the fibre families or along the rectangle's
axes: the vertices form the rhombic lattice (p·dx, q·dy), p + q even, with dy/dx = tan θ, and
each lattice rhombus (its diagonals are along x and y) is cut along its shorter diagonal. The
rectangle's corners are lattice vertices, so the fibre lines that leave the clamp corners (the
zone boundaries of the bias test, Cao et al. 2008 §5) are mesh lines and the piecewise
homogeneous pin-jointed-net solution is in the discrete space.

The mesh is built in memory on rank 0 and distributed by dolfinx with shared-facet ghosts,
which the interior-penalty facet integrals need. Edges are tagged ``clamp`` (x = 0), ``grip``
(x = length), ``bottom`` (y = 0) and ``top`` (y = width), as for every specimen builder.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from mpi4py import MPI

from .specimen import (
    Specimen,
    check_positive,
    corner_points,
    distributed_mesh,
    tag_rectangle_edges,
)

ANGLE_TOLERANCE_DEG = 0.05
"""Largest difference between the mesh's lattice angle and the requested fibre angle."""

EXACT_DEG = 1e-9
"""A lattice this close to the fibres' angle is exact (rounding only)."""

SIZE_WINDOW = 1.4
"""The lattice's number of rows may differ from the one ``h`` asks for by this factor either
way (about 2× in cell count); beyond it the specimen gets no aligned mesh at this h."""


def lattice_angle_deg(length: float, width: float, P: int, Q: int) -> float:
    """The fibre angle of the lattice of P × Q steps on a length × width rectangle."""
    return math.degrees(math.atan((width / Q) / (length / P)))


def lattice_divisions(
    length: float, width: float, h: float, theta_deg: float, tol_deg: float = ANGLE_TOLERANCE_DEG
) -> tuple[int, int]:
    """Even numbers (P, Q) of lattice steps along x and y with atan((W/Q)/(L/P)) = θ within
    ``tol_deg``, Q within :data:`SIZE_WINDOW` of the count q0 that fibre edges of length ``h``
    give (so the mesh has about the requested size), and Q as close to q0 as such pairs allow.

    Raises ValueError, naming the nearest angle a lattice in that window can have, when none
    fits (a rectangle whose sides are in no simple ratio to the fibre angle at this h).
    """
    check_positive(length=length, width=width, h=h)
    if not 0.0 < theta_deg < 90.0:
        raise ValueError(
            f"geometry: fibre angle ±{theta_deg:g}° must lie strictly between 0° "
            "and 90° for a fibre-aligned mesh"
        )
    t = math.radians(theta_deg)
    q0 = width / (h * math.sin(t))
    lo, hi = max(2, math.ceil(q0 / SIZE_WINDOW)), max(2, math.floor(q0 * SIZE_WINDOW))
    best, nearest = None, None
    for q in range(lo + lo % 2, hi + 1, 2):
        p = max(2, 2 * round(length * math.tan(t) * q / (2 * width)))
        err = abs(lattice_angle_deg(length, width, p, q) - theta_deg)
        if nearest is None or err < nearest[0]:
            nearest = (err, p, q)
        if err <= tol_deg and (best is None or abs(q - q0) < abs(best[1] - q0)):
            best = (p, q)
    if best is None:
        if nearest is None:
            raise ValueError(
                f"geometry: no even number of lattice rows of a {width:g} mm "
                f"width lies within {SIZE_WINDOW:g}× of {q0:.1f} (h = {h:g})"
            )
        _, p, q = nearest
        ang = lattice_angle_deg(length, width, p, q)
        raise ValueError(
            f"geometry: no fibre-aligned lattice of a {length:g} × {width:g} "
            f"rectangle at ±{theta_deg:g}° within {tol_deg:g}° near h = {h:g} "
            f"(nearest: ±{ang:.3f}° with {p} × {q} steps)"
        )
    return best


def lattice_sizes(
    length: float, width: float, h: float, theta_deg: float, tol_deg: float = ANGLE_TOLERANCE_DEG
) -> tuple[float | None, float | None]:
    """The fibre-edge lengths (the h an aligned mesh reports) of the corner-to-corner lattices
    of the rectangle whose angle is within ``tol_deg`` of θ nearest to ``h``: (the largest not
    above h, the smallest not below h), None where there is none with 2 to 4·q0 rows (q0 of
    :func:`lattice_divisions`)."""
    t = math.radians(theta_deg)
    q0 = width / (h * math.sin(t))
    finer, coarser = None, None
    for q in range(2, max(4, math.ceil(4 * q0)) + 1, 2):
        p = max(2, 2 * round(length * math.tan(t) * q / (2 * width)))
        if abs(lattice_angle_deg(length, width, p, q) - theta_deg) > tol_deg:
            continue
        size = math.hypot(length / p, width / q)
        if size <= h and (finer is None or size > finer):
            finer = size
        if size >= h and (coarser is None or size < coarser):
            coarser = size
    return finer, coarser


def lattice_triangles(
    P: int, Q: int, split_horizontal: bool | Callable[[int, int], bool]
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (p, q) (p + q even, 0 ≤ p ≤ P, 0 ≤ q ≤ Q) and the triangles of the rhombi
    centred at (p, q) with p + q odd, cut along one diagonal: along x where
    ``split_horizontal`` (a bool, or a function of the rhombus centre (p, q)), else along y;
    half rhombi on the boundary are single triangles."""
    horizontal = split_horizontal if callable(split_horizontal) else (lambda p, q: split_horizontal)
    index = {}
    for q in range(Q + 1):
        for p in range(q % 2, P + 1, 2):
            index[(p, q)] = len(index)
    cells = []
    for q in range(Q + 1):
        for p in range((q + 1) % 2, P + 1, 2):
            left, right, down, up = (p - 1, q), (p + 1, q), (p, q - 1), (p, q + 1)
            have = [v in index for v in (left, right, down, up)]
            if all(have):
                if horizontal(p, q):
                    cells += [(left, right, up), (left, right, down)]
                else:
                    cells += [(down, up, left), (down, up, right)]
            elif sum(have) == 3:
                cells.append(tuple(v for v, ok in zip((left, right, down, up), have) if ok))
    verts = np.array(list(index), dtype=float)
    tri = np.array([[index[v] for v in c] for c in cells], dtype=np.int64)
    return verts, tri


def fibre_aligned_rectangle(
    length: float,
    width: float,
    h: float,
    fibre_angle_deg: float = 45.0,
    comm: MPI.Comm = MPI.COMM_WORLD,
    extra_points: dict | None = None,
    tol_deg: float = ANGLE_TOLERANCE_DEG,
) -> Specimen:
    """The rectangle [0, length] × [0, width] meshed along fibres at ±``fibre_angle_deg`` to x,
    with fibre edges of length ≈ ``h`` and the lattice's angle within ``tol_deg`` of the
    fibres' (see :func:`lattice_divisions`).

    ``extra_points`` (name → (x, y)) are recorded in ``points`` for evaluation; they need not
    be vertices.
    """
    P, Q = lattice_divisions(length, width, h, fibre_angle_deg, tol_deg)
    dx, dy = length / P, width / Q
    if comm.rank == 0:
        verts, cells = lattice_triangles(P, Q, split_horizontal=dx <= dy)
        x = np.column_stack([verts[:, 0] * dx, verts[:, 1] * dy])
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    msh = distributed_mesh(comm, x, cells)
    ft = tag_rectangle_edges(msh, length, width)
    msh.topology.create_connectivity(1, 2)
    angle = lattice_angle_deg(length, width, P, Q)
    mismatch = abs(angle - fibre_angle_deg)
    return Specimen(
        msh,
        ft,
        float(length),
        float(width),
        points={**corner_points(length, width), **dict(extra_points or {})},
        kind="aligned",
        h=math.hypot(dx, dy),
        angle_mismatch_deg=mismatch,
        note=f"lattice at ±{angle:.4f} deg for fibres at ±{fibre_angle_deg:g} deg"
        if mismatch > EXACT_DEG
        else "",
    )


def fibre_line_angle(angle_deg: float) -> float:
    """The angle of a fibre direction as a line, in (−90°, 90°]: a fibre is a line, not an
    arrow, so angles that differ by a multiple of 180° (45°, −135°, 225°, 405°) are one fibre."""
    a = math.fmod(float(angle_deg), 180.0)
    a = a - 180.0 if a > 90.0 else a + 180.0 if a <= -90.0 else a
    return 0.0 if a == 0.0 else a  # no −0.0


def canonical_angles(fibre_angles: tuple[float, float]) -> tuple[float, float]:
    """Both fibre angles as lines (:func:`fibre_line_angle`): [45, 135] and [405, −45] are the
    pair (45, −45)."""
    return tuple(fibre_line_angle(a) for a in fibre_angles)


def symmetric_angle(fibre_angles: tuple[float, float]) -> float | None:
    """θ when the two families are, as lines, at +θ and −θ to x (either order, 0 < θ < 90°;
    any spelling mod 180°, :func:`canonical_angles`), else None."""
    a, b = canonical_angles(fibre_angles)
    theta = abs(a)
    if math.isclose(a, -b, abs_tol=1e-9) and 0.0 < theta < 90.0:
        return theta
    return None


SIDES = {(0.0, 90.0), (90.0, 0.0), (0.0, -90.0), (-90.0, 0.0)}
"""Fibre angles of a blank with its fibres along its sides."""


def blank_angle(fibre_angles: tuple[float, float]) -> float | None:
    """θ of fibres at ±θ to a square blank's sides, 0 for fibres along them (both cases are
    mirror-symmetric about the blank's mid-lines, :func:`quarter_blank`), else None."""
    if tuple(float(a) for a in fibre_angles) in SIDES:
        return 0.0
    return symmetric_angle(fibre_angles)


def square_divisions(side: float, h: float) -> int:
    """Cells along a side of the square grid of :func:`quarter_blank` (cell ≈ h, at least 2)."""
    check_positive(side=side, h=h)
    return max(2, round(side / h))


def square_triangles(n: int, m: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (i, j), 0 ≤ i ≤ n, 0 ≤ j ≤ m (default n), and the triangles of the n × m unit
    squares, each cut along its diagonal parallel to x = y (so the n × n grid is its own mirror
    image in that line)."""
    m = n if m is None else m
    i, j = np.meshgrid(np.arange(n + 1), np.arange(m + 1), indexing="xy")
    verts = np.column_stack([i.ravel(), j.ravel()]).astype(float)
    a = (np.arange(n)[None, :] + (n + 1) * np.arange(m)[:, None]).ravel()
    tri = np.concatenate(
        [np.column_stack([a, a + 1, a + n + 2]), np.column_stack([a, a + n + 2, a + n + 1])]
    )
    return verts, tri.astype(np.int64)


def quarter_divisions(half_x: float, half_y: float, h: float, theta_deg: float) -> tuple[int, int]:
    """(P, Q): the divisions of the quarter [0, half_x] × [0, half_y] along x and y at size h
    (:func:`quarter_blank`); ValueError (from :func:`lattice_divisions`) when no lattice at ±θ
    fits the rectangle."""
    if theta_deg == 0.0:
        return square_divisions(half_x, h), square_divisions(half_y, h)
    return lattice_divisions(half_x, half_y, h, theta_deg)


def quarter_triangles(P: int, Q: int, theta_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """The quarter's lattice (integer vertex coordinates, triangles) with the cut of
    :func:`quarter_blank`."""
    if theta_deg == 0.0:
        return square_triangles(P, Q)
    return lattice_triangles(P, Q, lambda p, q: p > q)


def quarter_blank(
    half_x: float, half_y: float, h: float, theta_deg: float, comm: MPI.Comm = MPI.COMM_WORLD
) -> Specimen:
    """The quarter [0, half_x] × [0, half_y] of a rectangular blank meshed along its fibres.

    Fibres at ±θ (0 < θ < 90°): the rhombic lattice above, each rhombus centred at (p, q) cut
    along x where p > q and along y where p < q; at θ = 45° the mesh is then its own mirror
    image in the diagonal, so a set-up symmetric about the diagonal has a discrete solution that
    is symmetric to round-off. θ = 0, fibres along the sides (0°/90°): a grid of cells ≈ h cut
    along the diagonals parallel to x = y, its own mirror image in that diagonal on a square.
    A rectangle at ±θ takes the lattice whose cells' diagonals are within
    ANGLE_TOLERANCE_DEG of the fibres (ValueError when none is near h).
    """
    P, Q = quarter_divisions(half_x, half_y, h, theta_deg)
    if comm.rank == 0:
        verts, tri = quarter_triangles(P, Q, theta_deg)
        x = np.column_stack([verts[:, 0] * half_x / P, verts[:, 1] * half_y / Q])
    else:
        x, tri = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    msh = distributed_mesh(comm, x, tri)
    ft = tag_rectangle_edges(msh, half_x, half_y)
    msh.topology.create_connectivity(1, 2)
    return Specimen(
        msh,
        ft,
        float(half_x),
        float(half_y),
        points=corner_points(half_x, half_y),
        kind="aligned",
        h=math.hypot(half_x / P, half_y / Q) if theta_deg else max(half_x / P, half_y / Q),
    )
