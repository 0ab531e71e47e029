"""gmsh builders for rectangular specimens (bias-extension test, Barchiesi et al. 2020 Fig. 4) and
squares.

gmsh runs on rank 0 only; the mesh is distributed from there with shared-facet ghosts
(:func:`distributed_mesh`).
Physical groups are named: edges ``clamp`` (x = 0), ``grip`` (x = length), ``bottom`` (y = 0),
``top`` (y = width); points ``corner_00``, ``corner_10``, ``corner_11``, ``corner_01`` and, for
the specimen, ``A`` (centre of the square on the clamped short side) and ``B`` (centre of the
specimen), which are embedded as mesh vertices.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gmsh
import numpy as np
import ufl
from dolfinx import mesh as dmesh
from dolfinx.io import gmshio
from mpi4py import MPI

EDGE_TAGS = {"clamp": 1, "grip": 2, "bottom": 3, "top": 4}
GMSH_TRIANGLE = 2  # gmsh's element type of the 3-node triangle
BIAS_LENGTH, BIAS_WIDTH = 187.0, 119.0
"""The bias-extension specimen of Barchiesi et al. 2020 (Fig. 4), length × width in mm: the
default of the bias-test plug-in and of the studies that compare with that paper."""


@dataclass
class Specimen:
    """A meshed rectangle [0, length] × [0, width] with named edge tags and points.

    ``kind`` names the mesh ("unstructured": gmsh's; "structured": the crossed grid;
    "aligned": edges along the fibres, geometry/aligned.py) and ``h`` the size its builder
    actually used (mm; for an aligned mesh the length of its fibre edges), so that runs can
    record what they computed on; ``note`` says why a builder of another kind was used;
    ``angle_mismatch_deg`` is how far an aligned lattice's angle is from the fibres' (it fits
    the rectangle within geometry.aligned.ANGLE_TOLERANCE_DEG, not exactly)."""

    mesh: object
    facet_tags: object
    length: float
    width: float
    edge_tags: dict = field(default_factory=lambda: dict(EDGE_TAGS))
    points: dict = field(default_factory=dict)
    kind: str = "unstructured"
    h: float = float("nan")
    note: str = ""
    angle_mismatch_deg: float = 0.0


def check_positive(**kw: float) -> None:
    for k, v in kw.items():
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"geometry: {k} = {v!r} must be a positive finite number")


def corner_points(length: float, width: float) -> dict:
    """The named corner points of [0, length] × [0, width]."""
    return {
        "corner_00": (0.0, 0.0),
        "corner_10": (length, 0.0),
        "corner_11": (length, width),
        "corner_01": (0.0, width),
    }


def bias_points(length: float, width: float) -> dict:
    """Points A and B of Barchiesi et al. 2020 Fig. 4: A the centre of the square whose side is the
    clamped
    short side (x = 0), B the centre of the specimen."""
    return {"A": (0.5 * width, 0.5 * width), "B": (0.5 * length, 0.5 * width)}


def _build_rectangle(
    length: float, width: float, h: float, extra_points: dict, structured: bool
) -> None:
    """The gmsh model (rank 0): rectangle, edge groups, embedded points."""
    gmsh.model.add("rectangle")
    occ = gmsh.model.occ
    s = occ.addRectangle(0.0, 0.0, 0.0, length, width)
    pts = {name: occ.addPoint(x, y, 0.0, h) for name, (x, y) in extra_points.items()}
    occ.synchronize()
    if pts:
        gmsh.model.mesh.embed(0, list(pts.values()), 2, s)
    gmsh.model.addPhysicalGroup(2, [s], 1)
    gmsh.model.setPhysicalName(2, 1, "specimen")
    for c in gmsh.model.getBoundary([(2, s)], oriented=False):
        x, y, _ = occ.getCenterOfMass(1, c[1])
        name = (
            "clamp"
            if np.isclose(x, 0)
            else "grip"
            if np.isclose(x, length)
            else "bottom"
            if np.isclose(y, 0)
            else "top"
        )
        gmsh.model.addPhysicalGroup(1, [c[1]], EDGE_TAGS[name])
        gmsh.model.setPhysicalName(1, EDGE_TAGS[name], name)
    for tag, name in enumerate(extra_points, start=100):
        gmsh.model.addPhysicalGroup(0, [pts[name]], tag)
        gmsh.model.setPhysicalName(0, tag, name)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMax", h)
    gmsh.option.setNumber("Mesh.CharacteristicLengthMin", 0.5 * h if not structured else h)
    gmsh.option.setNumber("Mesh.Algorithm", 6 if not structured else 8)
    gmsh.model.mesh.generate(2)


def _triangulation() -> tuple[np.ndarray, np.ndarray]:
    """Nodes (x, y) and 3-node triangles of the meshed gmsh model (rank 0)."""
    x = gmshio.extract_geometry(gmsh.model)[:, :2]
    topology = gmshio.extract_topology_and_markers(gmsh.model)
    return x, np.asarray(topology[GMSH_TRIANGLE]["topology"], dtype=np.int64)


def distributed_mesh(comm: MPI.Comm, x: np.ndarray, cells: np.ndarray) -> dmesh.Mesh:
    """The P1 triangulation held by rank 0 (``x``, ``cells``; empty arrays elsewhere),
    partitioned over ``comm`` with shared-facet ghosts: the interior-penalty terms are integrals
    over every interior facet, and those on a partition boundary need the cells on both
    sides (dolfinx's biharmonic demo sets the same mode)."""
    return dmesh.create_mesh(
        comm, cells, x, coordinate_domain(), ghost_mode=dmesh.GhostMode.shared_facet
    )


def coordinate_domain() -> ufl.Mesh:
    """The UFL domain of a P1 triangle mesh in the plane, its coordinate element marked
    equispaced (as dolfinx's gmshio marks it).

    FFCx 0.5 marks an unmarked coordinate element in place when it compiles the first form on a
    mesh, and the mark enters every later form's cache key: unmarked, a form's key depended on
    whether an earlier form on the same mesh was compiled or read from the cache, and differed
    between the rank that compiles and the others, so the same kernels were compiled again.
    For P1 the variant changes nothing else."""
    p1 = ufl.FiniteElement("Lagrange", "triangle", 1, variant="equispaced")
    return ufl.Mesh(ufl.VectorElement(p1, dim=2))


def rectangle(
    length: float,
    width: float,
    h: float,
    comm: MPI.Comm = MPI.COMM_WORLD,
    extra_points: dict | None = None,
    structured: bool = False,
) -> Specimen:
    """Mesh the rectangle [0, length] × [0, width] with element size ``h``.

    ``extra_points`` (name → (x, y)) are embedded as vertices and named physical points.
    """
    check_positive(length=length, width=width, h=h)
    extra = dict(extra_points or {})
    error = None
    if comm.rank == 0:
        try:
            gmsh.initialize()
            gmsh.option.setNumber("General.Terminal", 0)
            _build_rectangle(length, width, h, extra, structured)
        except Exception as e:  # reported on every rank below, so no rank waits forever
            error = f"{type(e).__name__}: {e}"
    error = comm.bcast(error, root=0)
    if error is not None:
        if comm.rank == 0:
            gmsh.finalize()
        raise RuntimeError(
            f"geometry: gmsh failed to mesh the {length} × {width} rectangle "
            f"(h = {h}) on rank 0: {error}"
        )
    try:
        x, cells = (
            _triangulation() if comm.rank == 0 else (np.zeros((0, 2)), np.zeros((0, 3), np.int64))
        )
    finally:
        if comm.rank == 0:
            gmsh.finalize()
    msh = distributed_mesh(comm, x, cells)
    ft = tag_rectangle_edges(msh, length, width)
    msh.topology.create_connectivity(1, 2)
    return Specimen(
        msh,
        ft,
        float(length),
        float(width),
        points={**corner_points(length, width), **extra},
        kind="structured" if structured else "unstructured",
        h=float(h),
    )


def square(
    side: float = 1.0, h: float = 0.25, comm: MPI.Comm = MPI.COMM_WORLD, structured: bool = False
) -> Specimen:
    """The square [0, side]²; edges tagged clamp/grip/bottom/top as for the rectangle."""
    return rectangle(side, side, h, comm, structured=structured)


def graded(xi: np.ndarray, grading: float) -> np.ndarray:
    """The map ξ ↦ ξ − g sin(2πξ)/(2π) of [0, 1] onto itself: spacing (1 − g)× the uniform one
    at both ends, (1 + g)× in the middle; smooth, so refining ξ uniformly refines x smoothly."""
    return xi - grading * np.sin(2 * np.pi * xi) / (2 * np.pi)


def structured_rectangle(
    length: float,
    width: float,
    nx: int,
    ny: int,
    comm: MPI.Comm = MPI.COMM_WORLD,
    grading: float = 0.0,
) -> Specimen:
    """A structured triangulation of [0, length] × [0, width] (dolfinx built-in, no gmsh), with
    the same edge tags as :func:`rectangle`; the vertex sets are nested when nx, ny double
    (convergence studies).

    ``grading`` ∈ [0, 1) maps both coordinates by :func:`graded`, refining towards all four
    edges (boundary layers) and most at the corners.
    """
    check_positive(length=length, width=width, nx=nx, ny=ny)
    if not 0.0 <= grading < 1.0:
        raise ValueError(f"geometry: grading = {grading!r} must lie in [0, 1)")
    msh = dmesh.create_rectangle(
        comm,
        [np.zeros(2), np.array([length, width])],
        [nx, ny],
        dmesh.CellType.triangle,
        diagonal=dmesh.DiagonalType.crossed,
        ghost_mode=dmesh.GhostMode.shared_facet,
    )
    if grading > 0.0:
        x = msh.geometry.x
        x[:, 0] = length * graded(x[:, 0] / length, grading)
        x[:, 1] = width * graded(x[:, 1] / width, grading)
    ft = tag_rectangle_edges(msh, length, width)
    msh.topology.create_connectivity(1, 2)
    return Specimen(
        msh,
        ft,
        float(length),
        float(width),
        points=corner_points(length, width),
        kind="structured",
        h=float(max(length / nx, width / ny)),
    )


def tag_rectangle_edges(msh, length: float, width: float):
    """Facet tags ``clamp``, ``grip``, ``bottom``, ``top`` (:data:`EDGE_TAGS`) of the rectangle
    [0, length] × [0, width] meshed by ``msh`` (a corner facet is tagged once)."""
    where = {
        "clamp": lambda x: np.isclose(x[0], 0.0),
        "grip": lambda x: np.isclose(x[0], length),
        "bottom": lambda x: np.isclose(x[1], 0.0),
        "top": lambda x: np.isclose(x[1], width),
    }
    facets, values = [], []
    for name, marker in where.items():
        f = dmesh.locate_entities_boundary(msh, 1, marker)
        facets.append(f)
        values.append(np.full(len(f), EDGE_TAGS[name], dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    facets, first = np.unique(facets, return_index=True)
    return dmesh.meshtags(msh, 1, facets, values[first])


def shift_x(specimen: Specimen, dx: float) -> Specimen:
    """Translate a specimen by dx along x (mesh and named points), e.g. the free part of a
    bias specimen between grips of depth dx; edge tags are unchanged."""
    specimen.mesh.geometry.x[:, 0] += dx
    specimen.points = {k: (x + dx, y) for k, (x, y) in specimen.points.items()}
    return specimen
