"""A tool file at the size a CAD export has (issue 55 item 1, "Test at the sizes users have"):
a binary STL of 327 680 triangles (a sphere of radius 40 mm, the icosahedron subdivided seven
times, edges of about 0.4 mm) read, checked and queried under an address-space limit.

Memory is O(triangles + points): the surface keeps about 0.3 kB per triangle and its build
peaks near 1.3 kB per triangle (420 MB here, tracemalloc); a query adds arrays of
triangulated.PAIRS point–candidate pairs whatever the number of points. Before the queries
were cut into such pieces, 2·10⁴ points at 3 mm from a finer sphere's surface took the whole
k = 512 stage at once, 12.7 kB per triangle at 8·10⁴ triangles, which the limit below refuses.

The distances are checked against an exact bracket: the triangulated sphere bounds a convex
solid that holds the ball of radius r_in (the least distance from the centre to a triangle's
plane) and lies within the ball of radius R, and the signed distance decreases as the solid
grows, so |x| − R ≤ d ≤ |x| − r_in at every point; and against brute force over all the
triangles at a few points.
"""

import numpy as np
import pytest
from address_space import address_space_limit

from fabricsurf.experiments.forming.surfaces import files, meshes
from fabricsurf.experiments.forming.surfaces.closest import closest_on_triangles

pytestmark = pytest.mark.serial("numpy only: nothing here depends on the ranks")

R, LEVEL = 40.0, 7
BUDGET = 800 << 20
"""Bytes of address space the test may add: about twice the build's measured peak."""


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    """(the surface read from a binary STL under BUDGET, the sphere's inner radius)."""
    v, f = meshes.icosphere(R, LEVEL)
    path = tmp_path_factory.mktemp("large") / "sphere.stl"
    files.write_stl(path, v, f)
    with address_space_limit(BUDGET):
        surface = files.read_surface(path, "mm")
    assert len(surface.faces) == len(f) == 327_680
    return surface, inner_radius(v, f)


def points_about(n: int, spread: float, seed: int) -> np.ndarray:
    """n random points whose distance from the centre is R ± spread."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    return x * (R + rng.uniform(-spread, spread, n))[:, None] / np.linalg.norm(x, axis=1)[:, None]


def inner_radius(v: np.ndarray, f: np.ndarray) -> float:
    """Least distance from the centre to a triangle's plane."""
    a, b, c = (v[f[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    return float((np.einsum("ij,ij->i", a, n) / np.linalg.norm(n, axis=1)).min())


def test_a_large_stl_is_read_and_queried_in_linear_memory(sphere):
    """Read and checked (closed, oriented outwards: the fixture) and queried under BUDGET:
    10⁵ points within 1 mm through ``near`` (the contact table's query) and 2·10⁴ at up to
    3 mm through ``closest`` (the drape's); every distance in the exact bracket of the module
    docstring, or, beyond ``near``'s cutoff outside, a lower bound."""
    surface, r_in = sphere
    assert R - r_in < 1e-3  # the bracket is tight: edges of about 0.4 mm
    x = points_about(100_000, 1.0, seed=55)
    far = points_about(20_000, 3.0, seed=56)
    with address_space_limit(BUDGET):
        d, _, _ = surface.near(x, 0.5)
        d_far = surface.signed_distance(far)
    r = np.linalg.norm(x, axis=1)
    exact = np.abs(r - R) < 0.5 - (R - r_in)  # near() is exact within its cutoff
    outside = r - R > 0.5
    assert exact.sum() > 40_000 and outside.sum() > 20_000
    tol = 1e-9 * R
    assert np.all(d[exact] >= r[exact] - R - tol) and np.all(d[exact] <= r[exact] - r_in + tol)
    assert np.all(d[outside] <= r[outside] - r_in + tol)
    r_far = np.linalg.norm(far, axis=1)
    assert np.all(d_far >= r_far - R - tol) and np.all(d_far <= r_far - r_in + tol)


def test_a_large_stl_matches_brute_force(sphere):
    """At 20 points, the distance equals the least over all 327 680 triangles to round-off."""
    surface, _ = sphere
    x = points_about(20, 3.0, seed=57)
    d = surface.signed_distance(x)
    a, b, c = (surface.vertices[surface.faces[:, k]] for k in range(3))
    for p, dp in zip(x, d):
        _, d2, _, _ = closest_on_triangles(p[None], a, b, c)
        assert abs(abs(dp) - np.sqrt(d2.min())) < 1e-12 * R
        assert np.sign(dp) == np.sign(np.linalg.norm(p) - R)
