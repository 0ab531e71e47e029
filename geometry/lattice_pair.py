"""A fibre-aligned triangulation of any rectangle for fibres at ±θ to its long side: two fibre
lattices, one anchored at each grip, joined by a band of cells across the middle.

The corner-to-corner lattice of :mod:`geometry.aligned` exists only when the rectangle's sides
are in a suitable ratio at the requested h. Here the lattice's rows fit the width exactly
(Q rows of height dy = W/Q, dx = dy/tan θ, so the fibre angle is exact), the left lattice
covers [0, P·dx] from the clamp and its mirror image [L − P·dx, L] from the grip, and the band
between them (a column of rectangles cut into triangles) takes up what is left of the length.
The fibre lines leaving all four corners, the zone boundaries of the bias test (Cao et al.
2008 §5), are mesh lines. Only the band's cells do not follow the fibres; when the band lies in
the centre zone of the test (P ≥ Q: every fibre through the band ends on the free edges) the
ideal deformation is affine there, which any mesh represents exactly, so the pin-jointed-net
solution is still in the discrete space and nothing locks (docs/theory.md, "Locking").
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from mpi4py import MPI

from .aligned import lattice_triangles
from .specimen import (
    Specimen,
    check_positive,
    corner_points,
    distributed_mesh,
    tag_rectangle_edges,
)


def pair_divisions(length: float, width: float, h: float, theta_deg: float) -> tuple[int, int, int]:
    """(P, Q, B): even lattice steps P along x from each end and Q across the width (fibre
    edges ≈ ``h``), and the number B ≥ 1 of band columns, each between dx and 2·dx wide.
    Raises ValueError when the rectangle is too short for two lattices of two steps."""
    check_positive(length=length, width=width, h=h)
    if not 0.0 < theta_deg < 90.0:
        raise ValueError(
            f"geometry: fibre angle ±{theta_deg:g}° must lie strictly between 0° "
            "and 90° for a fibre-aligned mesh"
        )
    t = math.radians(theta_deg)
    Q = max(2, 2 * round(width / (h * math.sin(t)) / 2))
    dx = width / Q / math.tan(t)
    P = 2 * math.floor((length / dx - 1.0) / 4.0)
    if P < 2:
        raise ValueError(
            f"geometry: a {length:g} × {width:g} rectangle is too short for two "
            f"fibre lattices at ±{theta_deg:g}° near h = {h:g}"
        )
    band = length - 2 * P * dx
    return P, Q, max(1, math.floor(band / dx / 2.0 + 0.5))


def pair_triangles(
    P: int, Q: int, B: int, dx: float, dy: float, length: float
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (x, y) and triangles of the two lattices and the band (module docstring)."""
    verts, tri = lattice_triangles(P, Q, split_horizontal=dx <= dy)
    left = np.column_stack([verts[:, 0] * dx, verts[:, 1] * dy])
    right = np.column_stack([length - verts[:, 0] * dx, verts[:, 1] * dy])
    n = len(left)
    ys = np.arange(0, Q + 1, 2) * dy  # the vertices of column P (P, Q even)
    x0, x1 = P * dx, length - P * dx
    cols = [np.flatnonzero(np.isclose(left[:, 0], x0))]
    cols[0] = cols[0][np.argsort(left[cols[0], 1])]
    inner = [np.column_stack([np.full(len(ys), x0 + (x1 - x0) * k / B), ys]) for k in range(1, B)]
    x = np.vstack([left, right, *inner])
    for k in range(1, B):
        cols.append(2 * n + (k - 1) * len(ys) + np.arange(len(ys)))
    last = n + np.flatnonzero(np.isclose(right[:, 0], x1))
    cols.append(last[np.argsort(right[last - n, 1])])
    band = []
    for a, b in itertools.pairwise(cols):
        for i in range(len(ys) - 1):
            band += [(a[i], b[i], b[i + 1]), (a[i], b[i + 1], a[i + 1])]
    cells = np.vstack([tri, tri + n, np.array(band, dtype=np.int64)])
    return x, cells


def paired_lattice_rectangle(
    length: float,
    width: float,
    h: float,
    fibre_angle_deg: float = 45.0,
    comm: MPI.Comm = MPI.COMM_WORLD,
    extra_points: dict | None = None,
) -> Specimen:
    """The rectangle [0, length] × [0, width] meshed by two fibre lattices at ±θ and a band
    (module docstring), fibre edges ≈ ``h``. ``note`` says whether the band lies in the
    centre zone of the bias test (else the mesh may lock locally)."""
    P, Q, B = pair_divisions(length, width, h, fibre_angle_deg)
    dy = width / Q
    dx = dy / math.tan(math.radians(fibre_angle_deg))
    if comm.rank == 0:
        x, cells = pair_triangles(P, Q, B, dx, dy, length)
    else:
        x, cells = np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    msh = distributed_mesh(comm, x, cells)
    ft = tag_rectangle_edges(msh, length, width)
    msh.topology.create_connectivity(1, 2)
    centre = P >= Q
    note = f"two fibre lattices of {P} × {Q} steps joined by a {length - 2 * P * dx:.3g} mm " + (
        "band in the centre zone"
        if centre
        else "band that reaches into the grip zones (the specimen is shorter than "
        f"{2 * width / math.tan(math.radians(fibre_angle_deg)):.4g} mm): "
        "it may lock there"
    )
    return Specimen(
        msh,
        ft,
        float(length),
        float(width),
        points={**corner_points(length, width), **dict(extra_points or {})},
        kind="lattice_pair" if centre else "lattice_pair_short",
        h=math.hypot(dx, dy),
        note=note,
    )
