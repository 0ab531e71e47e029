"""Triangulations of simple shapes (for checks of the triangulated tools and drapes against
their analytic counterparts) and the triangles of a gmsh model (a tool built with gmsh's
OpenCASCADE kernel, or read by gmsh from a STEP/IGES file).

The sphere is the icosahedron subdivided ``level`` times, each new vertex pushed onto the
sphere (triangles of side ≈ 1.05 R / 2^level, nearly equilateral); the cylinder and the cone
are structured: ``around`` × ``along`` quadrilaterals between the rulings, each split into two
triangles, so that every triangle's corners lie on the smooth surface and both triangles of a
quadrilateral are coplanar (the triangulated cylinder is a prism, itself developable).
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np

from fabricsurf.experiments.forming.surfaces import topology
from fabricsurf.experiments.forming.surfaces.files import unit_scale
from fabricsurf.experiments.forming.surfaces.triangulated import TriangulatedSurface


def icosphere(R: float, level: int, centre=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the subdivided icosahedron on the sphere (module docstring)."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t]]
    v += [[0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4]]
    f += [[11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8]]
    f += [[3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    verts = np.array(v, float)
    faces = np.array(f)
    for _ in range(level):
        sides = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1), axis=-1)
        unique, inverse = np.unique(sides.reshape(-1, 2), axis=0, return_inverse=True)
        mid = len(verts) + inverse.reshape(-1, 3)
        verts = np.vstack([verts, 0.5 * (verts[unique[:, 0]] + verts[unique[:, 1]])])
        a, b, c = faces.T
        ab, bc, ca = mid.T
        faces = np.vstack(
            [np.column_stack(s) for s in ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])]
        )
    verts = R * verts / np.linalg.norm(verts, axis=1, keepdims=True)
    return verts + np.asarray(centre, float), faces


def ruled(ring, around: int, along: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the closed tube through the rings ``ring(s)`` (callable of the
    axial parameter s in [0, 1] giving ``around`` points, counter-clockwise about the axis),
    ``along`` quadrilaterals long, open at both ends; faces facing away from the axis."""
    verts = np.vstack([ring(k / along) for k in range(along + 1)])
    i, k = np.meshgrid(np.arange(around), np.arange(along), indexing="ij")
    p = k * around + i
    q = k * around + (i + 1) % around
    faces = np.vstack(
        [
            np.column_stack([p.ravel(), q.ravel(), q.ravel() + around]),
            np.column_stack([p.ravel(), q.ravel() + around, p.ravel() + around]),
        ]
    )
    return verts, faces


def cylinder_mesh(
    R: float, length: float, around: int, along: int
) -> tuple[np.ndarray, np.ndarray]:
    """The tube of radius R about the y axis, y from −length/2 to length/2, as the drapes
    of fabricsurf/verification/drapes use it (its top line x = 0, z = R); open ends."""
    phi = 2.0 * math.pi * np.arange(around) / around

    def ring(s):
        y = np.full(around, (s - 0.5) * length)
        return np.column_stack([R * np.sin(phi), y, R * np.cos(phi)])

    return ruled(ring, around, along)


def cone_mesh(
    alpha: float, s0: float, s1: float, around: int, along: int
) -> tuple[np.ndarray, np.ndarray]:
    """The cone of half-angle α about the z axis, apex at the origin, between the slant
    distances s0 and s1 from the apex; open ends."""
    phi = 2.0 * math.pi * np.arange(around) / around

    def ring(t):
        s = s0 + t * (s1 - s0)
        r = s * math.sin(alpha)
        return np.column_stack(
            [r * np.cos(phi), r * np.sin(phi), np.full(around, s * math.cos(alpha))]
        )

    return ruled(ring, around, along)


def revolved(profile: np.ndarray, around: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the closed surface swept by the meridian ``profile`` (rows (ρ, z)
    from a point on the z axis to another, ρ > 0 between) about the z axis, ``around``
    segments; faces outwards."""
    inner = np.asarray(profile, float)[1:-1]
    phi = 2.0 * math.pi * np.arange(around) / around
    rings = [
        np.column_stack([rho * np.cos(phi), rho * np.sin(phi), np.full(around, z)])
        for rho, z in inner
    ]
    top, bottom = np.array([[0.0, 0.0, profile[0][1]]]), np.array([[0.0, 0.0, profile[-1][1]]])
    verts = np.vstack([top, *rings, bottom])
    i = np.arange(around)
    j = (i + 1) % around
    faces = [np.column_stack([np.zeros(around, int), 1 + i, 1 + j])]
    for k in range(len(inner) - 1):
        a, b = 1 + k * around, 1 + (k + 1) * around
        faces += [np.column_stack([a + i, b + i, b + j]), np.column_stack([a + i, b + j, a + j])]
    last, end = 1 + (len(inner) - 1) * around, len(verts) - 1
    faces.append(np.column_stack([last + i, np.full(around, end), last + j]))
    faces = np.vstack(faces)
    if topology.enclosed_volume(verts, faces) < 0:
        faces = faces[:, ::-1]
    return verts, faces


def revolved_loop(loop: np.ndarray, around: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the closed ring-shaped surface swept by the closed meridian
    ``loop`` (rows (ρ, z), ρ > 0, the last row joined to the first) about the z axis: a die
    plate about its opening, say; ``around`` segments, faces outwards."""
    loop = np.asarray(loop, float)
    m = len(loop)
    phi = 2.0 * math.pi * np.arange(around) / around
    verts = np.vstack(
        [
            np.column_stack([rho * np.cos(phi), rho * np.sin(phi), np.full(around, z)])
            for rho, z in loop
        ]
    )
    i, k = np.meshgrid(np.arange(around), np.arange(m), indexing="ij")
    p, q = k * around + i, k * around + (i + 1) % around
    p2, q2 = (p + around) % (m * around), (q + around) % (m * around)
    faces = np.vstack(
        [
            np.column_stack([p.ravel(), q.ravel(), q2.ravel()]),
            np.column_stack([p.ravel(), q2.ravel(), p2.ravel()]),
        ]
    )
    if topology.enclosed_volume(verts, faces) < 0:
        faces = faces[:, ::-1]
    return verts, faces


def die_plate_mesh(
    opening: float, lip: float, outer: float, thickness: float, h: float, around: int
) -> tuple[np.ndarray, np.ndarray]:
    """The forming plug-in's die plate (analytic.DiePlate about a circular opening of radius
    ``opening``, its face at z = 0) as a closed annular plate of radius ``outer`` and
    ``thickness``: the lip a quarter circle of radius ``lip`` in meridian edges about h long,
    ``around`` segments, the straight parts of the meridian cut as long as a segment at the
    opening (no long slivers)."""
    m = max(2, math.ceil(0.5 * math.pi * lip / h))
    t = 0.5 * math.pi * np.arange(m + 1) / m
    arc = np.column_stack([opening + lip - lip * np.sin(t), lip - lip * np.cos(t)])
    corners = [(opening, thickness), (outer, thickness), (outer, 0.0)]
    step = 2.0 * math.pi * opening / around  # a segment's length at the opening
    return revolved_loop(np.vstack([arc[:-1], cut_loop([arc[-1], *corners, arc[0]], step)]), around)


def holder_plate_mesh(
    opening: float, lip: float, outer: float, thickness: float, h: float, around: int
) -> tuple[np.ndarray, np.ndarray]:
    """The analytic holder's plate (below the blank, its face at z = 0 facing up) about a
    circular opening of radius ``opening``: :func:`die_plate_mesh` mirrored in z = 0."""
    vertices, faces = die_plate_mesh(opening, lip, outer, thickness, h, around)
    return vertices * np.array([1.0, 1.0, -1.0]), faces[:, ::-1].copy()


def cut_loop(corners, step: float) -> np.ndarray:
    """The polyline through ``corners`` (rows (ρ, z)) cut into pieces at most ``step`` long,
    its last corner left out (a closed meridian for :func:`revolved_loop`)."""
    out = []
    for a, b in pairwise(np.asarray(corners, float)):
        n = max(1, math.ceil(math.dist(a, b) / step))
        out.append(a + np.outer(np.arange(n) / n, b - a))
    return np.vstack(out)


def hemisphere_punch_mesh(
    R: float, h: float, shank: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The forming plug-in's punch (analytic.HemispherePunch with its pole at z = 0) closed:
    the hemisphere on a cylinder ``shank`` long (default 2 R) with a flat bottom, meridian
    edges about h long, ``around`` = 2πR/h segments."""
    shank = 2.0 * R if shank is None else shank
    m = max(2, math.ceil(0.5 * math.pi * R / h))
    t = 0.5 * math.pi * np.arange(m + 1) / m
    cap = np.column_stack([R * np.sin(t), -R + R * np.cos(t)])
    z = -R - shank * np.arange(1, max(1, math.ceil(shank / h)) + 1) / max(1, math.ceil(shank / h))
    side = np.column_stack([np.full(len(z), R), z])
    rho = R * np.arange(max(1, math.ceil(R / h)) - 1, -1, -1) / max(1, math.ceil(R / h))
    base = np.column_stack([rho, np.full(len(rho), z[-1])])
    return revolved(np.vstack([cap, side, base]), max(8, math.ceil(2.0 * math.pi * R / h)))


def from_gmsh(*, units: str, name: str = "gmsh model", closed: bool = True) -> TriangulatedSurface:
    """The triangles of the current gmsh model's 2D mesh (call gmsh.model.mesh.generate(2)
    first), welded and oriented consistently, each closed piece outwards (topology.orient:
    gmsh orients each surface of a solid on its own); the model's coordinates in ``units``
    (files.UNITS), converted to mm."""
    import gmsh

    tags, coords, _ = gmsh.model.mesh.getNodes()
    points = np.zeros((int(tags.max()) + 1, 3))
    points[tags.astype(int)] = coords.reshape(-1, 3)
    _, nodes = gmsh.model.mesh.getElementsByType(2)
    return welded(unit_scale(units, name) * points, nodes.astype(int).reshape(-1, 3), name, closed)


def welded(
    points: np.ndarray, faces: np.ndarray, name: str, closed: bool = True
) -> TriangulatedSurface:
    """The surface of the triangles ``faces`` (rows of indices into ``points``, mm): points no
    face uses dropped, coincident ones welded, the faces oriented consistently, each closed
    piece outwards (topology.orient)."""
    used, faces = np.unique(faces, return_inverse=True)
    vertices, faces = topology.weld(points[used], faces.reshape(-1, 3))
    return TriangulatedSurface(vertices, topology.orient(faces, vertices), name, closed)
