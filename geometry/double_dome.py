"""A double-dome punch built with gmsh's OpenCASCADE kernel: two spherical domes of radius
``radius`` whose centres lie ``spacing`` apart on the x axis, each on a vertical cylinder of
the same radius (the punch's walls, ``skirt`` deep below the domes' equators), the concave
creases where the two halves meet rounded to ``fillet``. The domes' tops are at z = 0, the
punch's axis of symmetry is the z axis, and it is its own mirror image about x = 0 and y = 0.

The shape is ours (demos/demo_double_dome.py; docs/tool_surfaces.md, "A double dome"), not
the dimensions of the woven-composites double-dome benchmark. A user with that tool's STL or
STEP file forms over it through ``punch_file`` instead.

gmsh runs on rank 0 only; every rank receives the same triangles (vertices in mm, faces
oriented outwards), ready for ``TriangulatedSurface``.
"""

from __future__ import annotations

import gmsh
import numpy as np
from mpi4py import MPI

CREASE_WIDTH = 0.15
"""The creases lie in the plane x = 0; an edge whose bounding box stays within this share of
the radius of it is one (OpenCASCADE's boxes are loose by a few per cent of the size)."""


def _halves(radius: float, spacing: float, skirt: float) -> list:
    """Each dome fused with its own cylinder first: fusing the four solids at once lost a
    dome in OpenCASCADE's boolean."""
    occ = gmsh.model.occ
    halves = []
    for x in (-spacing / 2.0, spacing / 2.0):
        sphere = occ.addSphere(x, 0.0, -radius, radius)
        wall = occ.addCylinder(x, 0.0, -radius - skirt, 0.0, 0.0, skirt, radius)
        halves.append(occ.fuse([(3, sphere)], [(3, wall)])[0])
    return occ.fuse(halves[0], halves[1])[0]


def _triangles(radius: float, spacing: float, fillet: float, skirt: float, h: float):
    occ = gmsh.model.occ
    gmsh.model.add("double dome")
    solid = _halves(radius, spacing, skirt)
    occ.synchronize()
    box = gmsh.model.getBoundingBox
    crease = [
        t
        for _, t in gmsh.model.getEntities(1)
        if max(abs(box(1, t)[0]), abs(box(1, t)[3])) < CREASE_WIDTH * radius
    ]
    if fillet > 0.0:
        occ.fillet([solid[0][1]], crease, [fillet])
        occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 24)
    gmsh.model.mesh.generate(2)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    points = np.zeros((int(tags.max()) + 1, 3))
    points[tags.astype(int)] = coords.reshape(-1, 3)
    _, nodes = gmsh.model.mesh.getElementsByType(2)
    return points, nodes.astype(np.int64).reshape(-1, 3)


def double_dome_punch(
    *,
    radius: float = 40.0,
    spacing: float = 70.0,
    fillet: float = 12.0,
    skirt: float = 60.0,
    h: float = 3.0,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> tuple[np.ndarray, np.ndarray]:
    """(points, faces) of the punch (module docstring; mm), meshed with triangles of side at
    most ``h`` and 24 per full turn of curvature. Points not used by a face may be present
    (``topology.weld`` drops them)."""
    if not 0.0 < spacing < 2.0 * radius:
        raise ValueError(f"double_dome_punch: spacing {spacing} must lie in (0, 2 radius)")
    error = None
    points = faces = None
    if comm.rank == 0:
        gmsh.initialize()
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            points, faces = _triangles(radius, spacing, fillet, skirt, h)
        except Exception as err:  # gmsh raises bare Exceptions
            error = f"double_dome_punch: gmsh failed: {err}"
        finally:
            gmsh.finalize()
    error = comm.bcast(error, root=0)
    if error:
        raise RuntimeError(error)
    return comm.bcast((points, faces), root=0)
