"""The mesh of a bias specimen: fibre-aligned wherever the fibres are at ±θ to the load, else
gmsh's, with the reason recorded (docs/theory.md, "Locking")."""

from __future__ import annotations

from mpi4py import MPI

from geometry.aligned import canonical_angles, fibre_aligned_rectangle, symmetric_angle
from geometry.lattice_pair import paired_lattice_rectangle
from geometry.specimen import Specimen, rectangle

MESH_KINDS = ("auto", "aligned", "lattice_pair", "unstructured")
"""``aligned``: :func:`~geometry.aligned.fibre_aligned_rectangle` (one lattice corner to
corner); ``lattice_pair``: :func:`~geometry.lattice_pair.paired_lattice_rectangle` (a lattice
from each grip and a band between); ``unstructured``: gmsh's frontal Delaunay; ``auto``: the
first of these that exists for the rectangle, fibres and h."""


def bias_mesh(length: float, width: float, h: float, fibre_angles: tuple[float, float],
              comm: MPI.Comm = MPI.COMM_WORLD, kind: str = "auto",
              extra_points: dict | None = None) -> Specimen:
    """The mesh of a rectangular specimen of the given ``kind`` (:data:`MESH_KINDS`); the
    specimen's ``kind`` says which was built and its ``note`` why (for a fallback)."""
    if kind not in MESH_KINDS:
        raise ValueError(f"geometry: mesh = {kind!r} must be one of {', '.join(MESH_KINDS)}")
    theta = symmetric_angle(fibre_angles)
    if kind in ("aligned", "lattice_pair") and theta is None:
        raise ValueError(f"geometry: a fibre-aligned mesh needs fibres at ±θ to x, not at "
                         f"{tuple(fibre_angles)}°")
    if kind == "unstructured":
        note = "mesh = 'unstructured' requested"
    elif theta is None:
        note = (f"fibres at {list(canonical_angles(fibre_angles))} deg are not at +-theta to "
                "the load")
    else:
        if kind in ("auto", "aligned"):
            try:
                return fibre_aligned_rectangle(length, width, h, theta, comm, extra_points)
            except ValueError:
                if kind == "aligned":
                    raise
        try:
            return paired_lattice_rectangle(length, width, h, theta, comm, extra_points)
        except ValueError as e:
            if kind == "lattice_pair":
                raise
            note = str(e).removeprefix("geometry: ")
    specimen = rectangle(length, width, h, comm, extra_points=extra_points)
    specimen.note = note
    return specimen
