"""A gmsh triangulation of a rectangle whose edges include the fibre lines through its corners.

In the bias test of an inextensible net the deformation is affine in each zone, and the zones
are bounded by the fibre lines that leave the four corners (Cao et al. 2008 §5: a point's
zone is fixed by where its two fibres end, on a grip or on a free edge, which changes only
across a fibre line through a corner). A mesh with those lines as edges holds the piecewise
affine net solution whatever its other edges do, so it does not lock for that solution; it
serves where no fibre lattice does (specimens shorter than 2W/tan θ, fibre pairs that are not
±θ). Away from that solution (other loadings, finite fibre stiffness far from the limit) its
cells do not follow the fibres.
"""

from __future__ import annotations

import math

import gmsh
import numpy as np
from mpi4py import MPI

from .specimen import (
    Specimen,
    _triangulation,
    check_positive,
    corner_points,
    distributed_mesh,
    tag_rectangle_edges,
)


def corner_fibre_segments(
    length: float, width: float, angles_deg: tuple[float, float]
) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The segments of the fibre lines (both families) from each corner into the rectangle,
    up to where they leave it (lines along a side are the side itself: left out)."""
    segs = []
    for cx, cy in ((0.0, 0.0), (0.0, width), (length, 0.0), (length, width)):
        for a in angles_deg:
            for s in (1.0, -1.0):
                dx, dy = s * math.cos(math.radians(a)), s * math.sin(math.radians(a))
                if abs(dx) < 1e-12 or abs(dy) < 1e-12:
                    continue
                if (dx > 0) != (cx == 0.0) or (dy > 0) != (cy == 0.0):
                    continue
                t = min(
                    (length - cx) / dx if dx > 0 else -cx / dx,
                    (width - cy) / dy if dy > 0 else -cy / dy,
                )
                segs.append(((cx, cy), (cx + t * dx, cy + t * dy)))
    return segs


def _build(length: float, width: float, h: float, segs: list) -> None:
    """The gmsh model (rank 0): the rectangle fragmented by the segments, meshed at size h."""
    gmsh.model.add("zones")
    occ = gmsh.model.occ
    s = occ.addRectangle(0.0, 0.0, 0.0, length, width)
    lines = [occ.addLine(occ.addPoint(*p, 0.0, h), occ.addPoint(*q, 0.0, h)) for p, q in segs]
    occ.fragment([(2, s)], [(1, c) for c in lines])
    occ.synchronize()
    gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getEntities(2)], 1)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * h)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.model.mesh.generate(2)


def zone_rectangle(
    length: float,
    width: float,
    h: float,
    angles_deg: tuple[float, float],
    comm: MPI.Comm = MPI.COMM_WORLD,
    extra_points: dict | None = None,
) -> Specimen:
    """The rectangle [0, length] × [0, width] meshed by gmsh at size ``h`` with the corner
    fibre lines of :func:`corner_fibre_segments` as edges; ``extra_points`` are recorded in
    ``points`` (they need not be vertices)."""
    check_positive(length=length, width=width, h=h)
    segs = corner_fibre_segments(length, width, angles_deg)
    error, x, cells = None, np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    if comm.rank == 0:
        try:
            gmsh.initialize()
            gmsh.option.setNumber("General.Terminal", 0)
            _build(length, width, h, segs)
            x, cells = _triangulation()
        except Exception as e:  # reported on every rank below, so no rank waits forever
            error = f"{type(e).__name__}: {e}"
        finally:
            gmsh.finalize()
    error = comm.bcast(error, root=0)
    if error is not None:
        raise RuntimeError(
            f"geometry: gmsh failed to mesh the {length} × {width} rectangle "
            f"with its corner fibre lines (h = {h}) on rank 0: {error}"
        )
    msh = distributed_mesh(comm, x, cells)
    ft = tag_rectangle_edges(msh, length, width)
    msh.topology.create_connectivity(1, 2)
    return Specimen(
        msh,
        ft,
        float(length),
        float(width),
        points={**corner_points(length, width), **dict(extra_points or {})},
        kind="zones",
        h=float(h),
        note=f"gmsh with the {len(segs)} fibre lines through the corners as edges",
    )
