"""The mesh of a bias specimen: along the fibres where a lattice fits, else with the fibre lines
through the corners as edges, and which one was built recorded (docs/theory.md, "Locking")."""

from __future__ import annotations

from mpi4py import MPI

from .aligned import (
    ANGLE_TOLERANCE_DEG,
    EXACT_DEG,
    canonical_angles,
    fibre_aligned_rectangle,
    lattice_angle_deg,
    lattice_divisions,
    symmetric_angle,
)
from .lattice_pair import pair_divisions, paired_lattice_rectangle
from .specimen import Specimen, rectangle
from .zone_mesh import zone_rectangle

MESH_KINDS = ("auto", "aligned", "lattice_pair", "zones", "unstructured")
"""``aligned``: :func:`~.aligned.fibre_aligned_rectangle` (one lattice corner to
corner); ``lattice_pair``: :func:`~.lattice_pair.paired_lattice_rectangle` (a lattice
from each grip and a band between); ``zones``: :func:`~.zone_mesh.zone_rectangle`
(gmsh with the corner fibre lines as edges); ``unstructured``: gmsh's frontal Delaunay;
``auto``: aligned where a corner-to-corner lattice fits (its angle within the caller's
``max_mismatch_deg`` of the fibres'), else the lattice pair where its band lies in the centre
zone (fibres at ±θ, a specimen longer than about 2W/tan θ), else zones."""


def bias_mesh(
    length: float,
    width: float,
    h: float,
    fibre_angles: tuple[float, float],
    comm: MPI.Comm = MPI.COMM_WORLD,
    kind: str = "auto",
    extra_points: dict | None = None,
    max_mismatch_deg: float = ANGLE_TOLERANCE_DEG,
) -> Specimen:
    """The mesh of a rectangular specimen of the given ``kind`` (:data:`MESH_KINDS`); the
    specimen's ``kind`` says which was built and its ``note`` how. ``max_mismatch_deg`` bounds
    the angle between an ``auto`` corner-to-corner lattice and the fibres (stiff fibres lock a
    lattice that is off their angle: experiments/bias_mesh.py); a lattice further off is
    skipped, and the note says so."""
    if kind not in MESH_KINDS:
        raise ValueError(f"geometry: mesh = {kind!r} must be one of {', '.join(MESH_KINDS)}")
    theta = symmetric_angle(fibre_angles)
    if kind in ("aligned", "lattice_pair") and theta is None:
        raise ValueError(
            f"geometry: a fibre-aligned mesh needs fibres at ±θ to x, not at {tuple(fibre_angles)}°"
        )
    if kind == "unstructured":
        specimen = rectangle(length, width, h, comm, extra_points=extra_points)
        specimen.note = "mesh = 'unstructured' requested"
        return specimen
    if kind == "aligned":
        return fibre_aligned_rectangle(length, width, h, theta, comm, extra_points)
    tol = max(min(max_mismatch_deg, ANGLE_TOLERANCE_DEG), EXACT_DEG)
    if (
        kind == "auto"
        and theta is not None
        and _fits(lattice_divisions, length, width, h, theta, tol)
    ):
        return fibre_aligned_rectangle(length, width, h, theta, comm, extra_points, tol)
    if kind == "lattice_pair" or (
        kind == "auto" and theta is not None and _centre_band(length, width, h, theta)
    ):
        specimen = paired_lattice_rectangle(length, width, h, theta, comm, extra_points)
    else:
        specimen = zone_rectangle(
            length, width, h, canonical_angles(fibre_angles), comm, extra_points
        )
    if kind == "auto" and theta is not None and _fits(lattice_divisions, length, width, h, theta):
        specimen.note += _skipped(length, width, h, theta, tol)
    return specimen


def _skipped(length: float, width: float, h: float, theta: float, tol: float) -> str:
    """Why the corner-to-corner lattice that fits within the builder's tolerance was not
    taken: its angle is more than ``tol`` off the fibres'."""
    P, Q = lattice_divisions(length, width, h, theta)
    off = abs(lattice_angle_deg(length, width, P, Q) - theta)
    allowed = (
        "inextensible fibres allow none"
        if tol <= EXACT_DEG
        else f"these fibres allow {tol:.2g} deg"
    )
    return (
        f"; the corner-to-corner lattice at this h is {off:.3g} deg off the fibres "
        f"({allowed}): skipped, it would lock"
    )


def _fits(divisions, *args) -> bool:
    try:
        divisions(*args)
    except ValueError:
        return False
    return True


def _centre_band(length: float, width: float, h: float, theta: float) -> bool:
    """Whether the lattice pair exists and its band lies in the centre zone (P ≥ Q)."""
    if not _fits(pair_divisions, length, width, h, theta):
        return False
    P, Q, _ = pair_divisions(length, width, h, theta)
    return P >= Q
