"""The fishnet drape over any surface (fabricsurf/verification/drapes/surface_drape.py), over
analytic surfaces and over triangulations of them (fabricsurf/experiments/forming/surfaces).

Checks that can fail independently of each other:
* on the analytic sphere it is today's fishnet (fishnet.drape, which closes each cell by a
  mirror image in the sphere and lays great circles), node for node, to round-off, for
  orthogonal, ±45° and non-orthogonal fibres;
* on the analytic cylinder (developable) it is, to round-off, a flat net of parallelograms
  rolled onto it, whatever the fibre angles: no shear between any two cells. The rolled net's
  generators are the helices whose first chord's tangential part points along the fibre
  directions, so the angle between them in the development differs from the nominal one by a
  constant O(a²) (the discretisation of the fibre direction at the seed), which falls at rate 2;
* on the cone (developable, not homogeneous) the cells' shear vanishes at rate 2 in a;
* on triangulations of the sphere, the cylinder and the cone, with triangles of size h, the
  net converges to the net over the smooth surface at rate 2 in h (positions and shear);
* a gmsh OpenCASCADE sphere (an unstructured mesh) gives a net converging to the fishnet;
* a seed point off the surface is refused, naming the surface and the distance, and a net
  that runs off the edge of an open surface stops with a message naming where.

All of it is numpy: the 2-rank session skips it.
"""

import functools
import math

import numpy as np
import pytest

from fabricsurf.errors import InputError
from fabricsurf.experiments.forming.surfaces import meshes
from fabricsurf.experiments.forming.surfaces.analytic import Cone, Cylinder, Sphere
from fabricsurf.experiments.forming.surfaces.meshes import cone_mesh, cylinder_mesh, icosphere
from fabricsurf.experiments.forming.surfaces.triangulated import TriangulatedSurface
from fabricsurf.verification.drapes import fishnet, surface_drape

pytestmark = pytest.mark.serial("numpy only: nothing here depends on the ranks")
ANGLES = [(0.0, 90.0), (30.0, 120.0), (45.0, -45.0), (30.0, -40.0)]
RHO = 30.0
CONE = math.radians(30.0), 80.0
"""Cone half-angle and the seed's slant distance from the apex (mm)."""


def rate(coarse: float, fine: float, ratio: float = 2.0) -> float:
    return math.log(coarse / fine) / math.log(ratio)


@pytest.mark.parametrize("angles", ANGLES[1:])
def test_analytic_sphere_is_the_fishnet(angles):
    R = 100.0
    net = surface_drape.drape(Sphere(R), [0.0, 0.0, R], 5.0, 16, angles)
    ref = fishnet.drape(R, 5.0, 16, angles)
    assert np.abs(net.x - ref.x).max() < 1e-11 * R
    assert np.abs(net.shear - ref.shear).max() < 1e-11 and np.abs(ref.shear).max() > 0.3


def test_triangulated_sphere_converges_to_the_fishnet():
    """Measured (±45°, a = 5 mm, 25 × 25 nodes on R = 100 mm, shear up to 18.8°), icospheres of
    edge 8.26, 4.13, 2.07 mm: positions 0.115, 0.0294, 0.00766 mm (rates 1.97, 1.94), shear
    0.161, 0.0519, 0.0148° (1.63, 1.81)."""
    R, angles = 100.0, (45.0, -45.0)
    ref = fishnet.drape(R, 5.0, 12, angles)
    dx, dg = [], []
    for level in (4, 5, 6):
        surface = TriangulatedSurface(*icosphere(R, level), name="icosphere")
        net = surface_drape.drape(surface, [0.0, 0.0, R], 5.0, 12, angles)
        dx.append(np.abs(net.x - ref.x).max())
        dg.append(np.degrees(np.abs(net.shear - ref.shear).max()))
    assert rate(*dx[:2]) > 1.9 and rate(*dx[1:]) > 1.9, dx
    assert rate(*dg[:2]) > 1.5 and rate(*dg[1:]) > 1.7 and dg[-1] < 0.02, dg


def helix_residual(z: np.ndarray, theta: float, a: float) -> np.ndarray:
    """The chord of arc s of the helix at angle t (z = (t, s)) minus a, and the cross product of
    its tangential part at the start with the fibre direction θ (both vanish at the node)."""
    t, s = z
    c = math.cos(t)
    return np.array(
        [
            (2 * RHO * math.sin(s * c / (2 * RHO))) ** 2 + (s * math.sin(t)) ** 2 - a * a,
            RHO * math.sin(s * c / RHO) * math.sin(theta) - s * math.sin(t) * math.cos(theta),
        ]
    )


def helix(theta: float, a: float) -> tuple[float, float]:
    """(angle θ' in the development, arc length s) of the generator on the cylinder along the
    fibre angle θ: the helix whose chord of arc s is a and whose first chord's tangential part
    points at θ (Newton, finite-difference Jacobian)."""
    z = np.array([theta, a])
    for _ in range(30):
        f = helix_residual(z, theta, a)
        if np.abs(f).max() < 1e-15 * a * a:
            break
        J = np.column_stack(
            [(helix_residual(z + 1e-7 * e, theta, a) - f) / 1e-7 for e in np.eye(2)]
        )
        z = z - np.linalg.solve(J, f)
    return float(z[0]), float(z[1])


def rolled_net(a: float, n: int, angles) -> tuple[np.ndarray, float]:
    """(nodes of the parallelogram net along the two helices rolled onto the cylinder, the
    development's angle between its generators minus the nominal one)."""
    (tL, sL), (tM, sM) = (helix(math.radians(t), a) for t in angles)
    k = np.arange(-n, n + 1)
    X = k[:, None, None] * sL * np.array([math.cos(tL), math.sin(tL)])
    X = X + k[None, :, None] * sM * np.array([math.cos(tM), math.sin(tM)])
    x = np.stack([RHO * np.sin(X[..., 0] / RHO), X[..., 1], RHO * np.cos(X[..., 0] / RHO)], -1)
    return x, (tM - tL) - math.radians(angles[1] - angles[0])


CYLINDER = Cylinder(RHO, axis=(0.0, 1.0, 0.0))


@functools.cache
def mesh(shape: str, around: int) -> TriangulatedSurface:
    """The open tube of radius RHO, 60 mm long, or the cone between 50 and 110 mm from its
    apex, ``around`` sides, 30 rings of quadrilaterals along."""
    if shape == "tube":
        return TriangulatedSurface(*cylinder_mesh(RHO, 60.0, around, 30), "tube", closed=False)
    return TriangulatedSurface(*cone_mesh(CONE[0], 50.0, 110.0, around, 30), "cone", False)


@pytest.mark.parametrize("angles", ANGLES)
def test_analytic_cylinder_is_a_rolled_net(angles):
    """Measured: positions within 3e-11 mm of the rolled net; the development's angle defect
    3.2e-4, 8.0e-5 rad at a = 2, 1 mm (30/120; ratio 4.00), 0 for 0/90."""
    offsets = []
    for a in (2.0, 1.0):
        n = round(16.0 / a)
        net = surface_drape.drape(CYLINDER, [0.0, 0.0, RHO], a, n, angles)
        exact, offset = rolled_net(a, n, angles)
        assert np.abs(net.x - exact).max() < 1e-9 * RHO, angles
        offsets.append(abs(offset))
    if angles[0] % 90.0:
        assert 1.95 < rate(*offsets) < 2.05, offsets
    else:
        assert max(offsets) < 1e-14


@pytest.mark.parametrize("angles", [(30.0, -40.0), (45.0, -45.0)])
def test_triangulated_cylinder_converges(angles):
    """The prism of 64, 128, 256 sides (circumferential edges 2.95, 1.47, 0.74 mm; 2 mm along),
    a = 2 mm over 17 × 17 nodes: positions 0.0408, 0.0107, 0.00278 mm from the net on the
    cylinder (rates 1.93, 1.94), shear up to 2.0e-3, 6.3e-4, 1.7e-4 rad (30/−40)."""
    ref = surface_drape.drape(CYLINDER, [0.0, 0.0, RHO], 2.0, 8, angles)
    dx, dg = [], []
    for around in (64, 128, 256):
        net = surface_drape.drape(mesh("tube", around), [0.0, 0.0, RHO], 2.0, 8, angles)
        dx.append(np.abs(net.x - ref.x).max())
        dg.append(np.abs(net.shear).max())
    assert rate(*dx[:2]) > 1.85 and rate(*dx[1:]) > 1.85, dx
    assert rate(dg[0], dg[2], 4.0) > 1.6 and dg[-1] < 3e-4, dg


def cone_net(surface, a: float, n: int, angles):
    al, s0 = CONE
    e1 = np.array([math.sin(al), 0.0, math.cos(al)])
    return surface_drape.drape(surface, s0 * e1, a, n, angles, e1)


@pytest.mark.parametrize("angles", [(0.0, 90.0), (30.0, -40.0), (45.0, -45.0)])
def test_cone(angles):
    """Analytic: largest cell shear 4.8e-5, 1.3e-5, 3.2e-6 rad at a = 2, 1, 0.5 mm (30/−40,
    over 32 mm of fibre either way). Triangulated (128, 256, 512 sides, 2 mm along): positions
    0.0118, 0.00299, 0.00077 mm from the net on the cone; shear differences 3.7e-4, 1.2e-4,
    2.9e-5 rad."""
    g = [np.abs(cone_net(Cone(CONE[0]), a, round(16 / a), angles).shear).max() for a in (2, 1)]
    assert rate(*g) > 1.85 and g[1] < 2e-5, g
    ref = cone_net(Cone(CONE[0]), 2.0, 8, angles)
    dx, dg = [], []
    for around in (128, 256, 512):
        net = cone_net(mesh("cone", around), 2.0, 8, angles)
        dx.append(np.abs(net.x - ref.x).max())
        dg.append(np.abs(net.shear - ref.shear).max())
    assert rate(*dx[:2]) > 1.9 and rate(*dx[1:]) > 1.9, dx
    assert rate(dg[0], dg[2], 4.0) > 1.6 and dg[-1] < 5e-5, dg


def test_net_off_the_edge():
    """A net larger than an open surface stops with a message, not a net continued off it."""
    with pytest.raises(ArithmeticError, match=r"could not be placed on tube near .*runs off"):
        surface_drape.drape(mesh("tube", 64), [0.0, 0.0, RHO], 2.0, 20, (30.0, -40.0))


def test_gmsh_sphere_converges_to_the_fishnet():
    """An OpenCASCADE sphere (R = 50 mm) meshed by gmsh at 4, 2 mm (unstructured), ±45°,
    a = 4 mm, 17 × 17 nodes: measured positions 0.0814, 0.0247 mm from the fishnet (rate
    1.7), shear 0.180, 0.083° (0.021° at 1 mm)."""
    gmsh = pytest.importorskip("gmsh")
    R = 50.0
    ref = fishnet.drape(R, 4.0, 8, (45.0, -45.0))
    dx, dg = [], []
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        for h in (4.0, 2.0):
            gmsh.model.add(f"sphere{h}")
            gmsh.model.occ.addSphere(0.0, 0.0, 0.0, R)
            gmsh.model.occ.synchronize()
            gmsh.option.setNumber("Mesh.MeshSizeMax", h)
            gmsh.option.setNumber("Mesh.MeshSizeMin", h)
            gmsh.model.mesh.generate(2)
            surface = meshes.from_gmsh(units="mm", name="gmsh sphere")
            gmsh.model.remove()
            net = surface_drape.drape(surface, [0.0, 0.0, R], 4.0, 8, (45.0, -45.0))
            dx.append(np.abs(net.x - ref.x).max())
            dg.append(np.degrees(np.abs(net.shear - ref.shear).max()))
    finally:
        gmsh.finalize()
    assert rate(*dx) > 1.5 and dx[1] < 0.03, dx
    assert dg[1] < 0.6 * dg[0] and dg[1] < 0.1, dg


def test_seed_off_the_surface():
    surface = TriangulatedSurface(*icosphere(50.0, 2), name="punch.stl")
    with pytest.raises(InputError, match=r"seed point \[0.0, 0.0, 60.0\] is 10.* off punch.stl"):
        surface_drape.drape(surface, [0.0, 0.0, 60.0], 2.0, 4)
    net = surface_drape.drape(Sphere(50.0), [0.0, 0.0, 50.001], 2.0, 4)  # within 1% of a
    assert abs(np.linalg.norm(net.seed) - 50.0) < 1e-12
