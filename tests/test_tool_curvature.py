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


def _expansion_errors(surface, x0: np.ndarray, steps) -> list[float]:
    """Largest |d(x0 + s) − (d + n·s + ½ s·∇n s)| over the points x0 and random s of each
    length in ``steps``: the tabulated distance of a table taken at x0 (tabulated_tools.py)."""
    d0, n0, K = surface.signed_distance(x0), surface.normal(x0), distance_hessian(surface, x0)
    u = _directions(len(x0))
    out = []
    for length in steps:
        s = length * u
        model = d0 + np.einsum("ij,ij->i", n0, s) + 0.5 * np.einsum("ij,ijk,ik->i", s, K, s)
        out.append(float(np.abs(surface.signed_distance(x0 + s) - model).max()))
    return out


def test_the_tables_expansion_is_second_order_on_other_shapes():
    """On shapes the forming runs do not check it on — a cone's side, a cylinder's end fillet,
    a rounded box's corner — the table's expanded distance d + n·s + ½ s·∇n s errs at third
    order in the step (halving the step divides the error by about 8); the frozen normal's
    d + n·s errs at second order (by about 4), which the assertion catches (measured: the
    cone's errors 1.7e-4, 2.2e-5, 2.8e-6 mm at steps of 0.4, 0.2, 0.1 mm, rates 7.9; the
    fillet's and the corner's rates 8.0–8.1; with ∇n left out the cone's rates are 4.0)."""
    m = 200
    t, delta = RNG.uniform(10.0, 30.0, m), RNG.uniform(-0.5, 0.5, m)
    alpha = np.radians(35.0)
    phi = RNG.uniform(0.0, 2.0 * np.pi, m)
    e = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(m)])
    a = np.array([0.0, 0.0, 1.0])
    side = t[:, None] * (np.sin(alpha) * e + np.cos(alpha) * a)
    normal = np.cos(alpha) * e - np.sin(alpha) * a
    cone = (analytic.Cone(alpha), side + delta[:, None] * normal)
    psi = RNG.uniform(0.2, 1.37, m)  # within the fillet's quarter of the meridian
    q = (5.0 + delta)[:, None] * np.column_stack([np.cos(psi), np.sin(psi)])
    fillet = (
        analytic.Cylinder(20.0, length=40.0, fillet=5.0),
        (15.0 + q[:, :1]) * e + (15.0 + q[:, 1:]) * a,
    )
    octant = np.abs(_directions(m)) + 0.3  # every component away from the edges' seams
    octant /= np.linalg.norm(octant, axis=1)[:, None]
    corner = 12.0 + (4.0 + delta)[:, None] * octant
    box = (analytic.RoundedBox((16.0, 16.0, 16.0), fillet=4.0), corner)
    for surface, x0 in (cone, fillet, box):
        errors = _expansion_errors(surface, x0, (0.4, 0.2, 0.1))
        rates = [errors[i] / errors[i + 1] for i in range(2)]
        assert all(6.0 < r < 10.0 for r in rates), (surface.name, errors, rates)
