"""The curvature of a tool given as a surface (fabricsurf/experiments/forming/surfaces/
curvature.py): ∇∇d = ∇n by central differences of the normal, for the Jacobian of the
tabulated contact. Checked against shapes whose Hessian is known in closed form; a kink of the
normal field within the difference step gives zero (the frozen normal's Jacobian), not the
step's inverse. The sensitivities it makes exact are tests/test_forming_loop.py's."""

import numpy as np

from fabricsurf.experiments.forming.surfaces import analytic
from fabricsurf.experiments.forming.surfaces.curvature import distance_hessian, has_curvature
from fabricsurf.experiments.forming.surfaces.meshes import hemisphere_punch_mesh
from fabricsurf.experiments.forming.surfaces.triangulated import TriangulatedSurface

RNG = np.random.default_rng(3)


def _directions(m: int, upper: bool = False) -> np.ndarray:
    v = RNG.normal(size=(m, 3))
    if upper:
        v[:, 2] = np.abs(v[:, 2]) + 0.05
    return v / np.linalg.norm(v, axis=1)[:, None]


def test_sphere_and_cylinder_in_closed_form():
    """(I − n ⊗ n)/ρ for a sphere, (I − a ⊗ a − n ⊗ n)/ρ for a cylinder of axis a, ρ the
    distance to the centre or the axis; inside and outside, to the differences' rounding
    (≈ 10⁻¹¹ of the curvature)."""
    R, centre = 20.0, np.array([1.0, -2.0, 3.0])
    n = _directions(500)
    rho = R + RNG.uniform(-0.5, 0.5, 500)
    exact = (np.eye(3) - n[:, :, None] * n[:, None, :]) / rho[:, None, None]
    H = distance_hessian(analytic.Sphere(R, centre), centre + rho[:, None] * n)
    assert np.abs(H - exact).max() < 1e-8 / R
    cyl = analytic.Cylinder(R, length=80.0)
    t = RNG.uniform(0, 2 * np.pi, 500)
    n = np.column_stack([np.cos(t), np.sin(t), np.zeros(500)])
    x = rho[:, None] * n + np.column_stack([np.zeros((500, 2)), RNG.uniform(-20, 20, 500)])
    a = np.array([0.0, 0.0, 1.0])
    exact = (np.eye(3) - np.outer(a, a) - n[:, :, None] * n[:, None, :]) / rho[:, None, None]
    assert np.abs(distance_hessian(cyl, x) - exact).max() < 1e-8 / R


def test_flat_and_kinked():
    """On a die plate's flat face ∇n = 0; at points within the step of the seam where the
    hemisphere's cap meets its wall (the curvature jumps there: the one-sided differences
    disagree) ∇n is set to zero, while just off the seam it is the cap's or the wall's."""
    plate = analytic.DiePlate(22.0, 2.0)
    x = np.column_stack([RNG.uniform(30, 40, 50), RNG.uniform(-5, 5, 50), -RNG.uniform(0, 1, 50)])
    assert np.abs(distance_hessian(plate, x)).max() < 1e-9
    punch = analytic.HemispherePunch(20.0)
    seam = np.array([[20.1, 0.0, -20.0], [20.1, 0.0, -20.0 + 1e-6]])
    assert np.abs(distance_hessian(punch, seam)).max() == 0.0
    off = distance_hessian(punch, np.array([[20.1, 0.0, -19.0]]))[0]
    assert 0.9 / 20.1 < np.trace(off) < 1.1 * 2 / 20.1


def test_which_surfaces_carry_it():
    """Analytic shapes (also moved) carry ∇n; a triangle mesh, flat on each face, does not."""
    assert has_curvature(analytic.HemispherePunch(20.0))
    assert has_curvature(analytic.Moved(analytic.Sphere(5.0), (0.0, 0.0, 1.0)))
    assert not has_curvature(TriangulatedSurface(*hemisphere_punch_mesh(20.0, 2.0), "punch"))
