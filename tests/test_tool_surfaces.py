"""Tool surfaces (fabricsurf/experiments/forming/surfaces): analytic shapes, triangle meshes
from STL, OBJ and gmsh, and the checks of bad input.

Checks that can fail independently of each other:
* each analytic shape's normal is the gradient of its signed distance (central differences),
  and the distance is right at points where it is known by hand (faces, fillets, corners);
* a triangle mesh's distance is the exact distance to its triangles (against all triangles,
  by brute force) with the sign of the inside;
* the icosphere's signed distance converges to the sphere's at rate 2 in the edge length, its
  gradient (a face normal) at rate 1, the interpolated vertex normals on the surface at rate 2;
* STL (ASCII and binary) and OBJ files written and read back give the same surface, scaled by
  the stated units; a gmsh OpenCASCADE box with fillets, meshed, converges to the analytic
  rounded box at rate 2;
* each bad input is refused with a message naming the file or tool and the fault: a surface
  not closed, flipped normals, inconsistently oriented triangles, a degenerate triangle, units
  that make the tool a thousand times too large, a tool that starts inside the blank, a stroke
  that passes through the die (with the stroke at which the die stops the punch).
"""

import math

import numpy as np
import pytest

from fabricsurf.errors import InputError
from fabricsurf.experiments.forming.surfaces import analytic, checks, files, meshes
from fabricsurf.experiments.forming.surfaces.closest import closest_on_triangles
from fabricsurf.experiments.forming.surfaces.opening import Opening
from fabricsurf.experiments.forming.surfaces.triangulated import Tracked, TriangulatedSurface

pytestmark = pytest.mark.serial("numpy only: nothing here depends on the ranks")
RNG = np.random.default_rng(7)


def rate(coarse: float, fine: float) -> float:
    return math.log2(coarse / fine)


SHAPES = [
    analytic.Sphere(20.0, (1.0, 2.0, 3.0)),
    analytic.HemispherePunch(20.0, pole=5.0),
    analytic.RoundedBox((10.0, 20.0, 30.0), 4.0),
    analytic.Cylinder(15.0, (0.0, 0.0, 1.0), (1.0, 1.0, 0.0), length=40.0, fillet=5.0),
    analytic.Cylinder(15.0),
    analytic.Cone(math.radians(30.0), axis=(0.0, 1.0, 1.0)),
    analytic.DiePlate(22.0, 2.0, face=-0.5),
    analytic.DiePlate(Opening("rectangle", 30.0, 18.0, 6.0), 2.0, face=-0.5),
]


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.name)
def test_normal_is_the_distance_gradient(shape):
    x = RNG.uniform(-40.0, 40.0, (400, 3))
    h = 1e-6
    grad = np.column_stack(
        [
            (shape.signed_distance(x + h * e) - shape.signed_distance(x - h * e)) / (2 * h)
            for e in np.eye(3)
        ]
    )
    n = shape.normal(x)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    ok = np.abs(grad - n).max(axis=1) < 1e-6
    assert ok.mean() > 0.98, ok.mean()  # the rest sit on a crease of the inside distance


def test_distances_by_hand():
    box = analytic.RoundedBox((10.0, 20.0, 30.0), 4.0)
    corner = np.array([6.0, 16.0, 26.0])
    p = corner + 7.0 * np.ones(3) / math.sqrt(3.0)
    assert np.allclose(box.signed_distance([[13.0, 0, 0], [0, 0, -27.0], p]), [3.0, -3.0, 3.0])
    cyl = analytic.Cylinder(15.0, length=40.0, fillet=5.0)
    pts = [[0, 0, 25.0], [17.0, 0, 0], [10 + 8 / math.sqrt(2), 0, 15 + 8 / math.sqrt(2)]]
    assert np.allclose(cyl.signed_distance(pts), [5.0, 2.0, 3.0])
    punch = analytic.HemispherePunch(20.0, pole=5.0)
    assert np.allclose(punch.signed_distance([[0, 0, 7.0], [25.0, 0, -40.0]]), [2.0, 5.0])
    die = analytic.DiePlate(22.0, 2.0, face=-0.5)  # lip circle ρ = 24 at z = 1.5
    pts = [[30.0, 0, -3.5], [0, 10.0, 1.5], [24.0 - 5.0 * 0.6, 0, 1.5 - 5.0 * 0.8]]
    assert np.allclose(die.signed_distance(pts), [3.0, 12.0, 3.0])
    slot = analytic.DiePlate(Opening("rectangle", 30.0, 18.0, 6.0), 2.0, face=-0.5)
    # the lip's tube about the straight side y = 20 and about the corner arc (centre (24, 12),
    # radius 8) at z = 1.5; the face beyond
    c = np.array([24.0, 12.0]) + 8.0 * np.ones(2) / math.sqrt(2.0)
    pts = [[0, 20.0 - 5.0 * 0.6, 1.5 - 5.0 * 0.8], [*c, 1.5 + 4.0], [40.0, 0, -3.5]]
    assert np.allclose(slot.signed_distance(pts), [3.0, 2.0, 3.0])


def test_closest_triangle_is_exact():
    surface = TriangulatedSurface(*meshes.icosphere(10.0, 2), name="ico")
    x = np.vstack([RNG.normal(size=(300, 3)) * 8.0, RNG.normal(size=(50, 3)) * 60.0, [[0, 0, 0]]])
    tri = surface.vertices[surface.faces]
    _, d2, _, _ = closest_on_triangles(x[:, None, :], tri[:, 0], tri[:, 1], tri[:, 2])
    brute = np.sqrt(d2.min(axis=1))
    d = surface.signed_distance(x)
    assert np.abs(np.abs(d) - brute).max() < 1e-12 * 60.0
    exact = analytic.Sphere(10.0).signed_distance(x)
    sure = np.abs(exact) > 0.2  # beyond the sagitta of the coarse mesh
    assert np.all(np.sign(d[sure]) == np.sign(exact[sure]))


def near_points(surface, inner: float = 9.0):
    """Points from ``inner`` (inside the 10 mm sphere) to 30 mm beyond it, half of them within
    1 mm of the sphere, and some of the surface's vertices."""
    u = RNG.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    radii = np.concatenate([RNG.uniform(inner, 11.0, 1500), RNG.uniform(11.0, 40.0, 1500)])
    return np.vstack([u * radii[:, None], surface.vertices[:50]])


def assert_near(surface, x, d, foot, n, cutoff):
    """``near``'s contract: within ``cutoff`` of the mesh, inside or out, the exact signed
    distance, foot and normal; farther outside a lower bound of the distance, positive, the
    foot that far below the point along the normal."""
    exact, c, normal = surface.frame(x)
    within, outside = np.abs(exact) <= cutoff, exact > cutoff
    assert within.sum() > 100 and outside.sum() > 1000
    assert np.abs(d[within] - exact[within]).max() < 1e-12
    assert np.abs(foot[within] - c[within]).max() < 1e-12
    assert np.abs(n[within] - normal[within]).max() < 1e-12
    assert np.all(d[outside] <= exact[outside] + 1e-12) and np.all(d[outside] > 0.0)
    assert np.abs(np.einsum("ij,ij->i", n, x - foot) - d).max() < 1e-12


@pytest.mark.parametrize("cutoff", [0.05, 1.0])
def test_near_is_exact_within_its_cutoff(cutoff):
    """What a contact table reads (TriangulatedSurface.near), from points inside the sphere to
    far beyond it."""
    surface = TriangulatedSurface(*meshes.icosphere(10.0, 3), name="ico")
    x = near_points(surface)
    assert_near(surface, x, *surface.near(x, cutoff), cutoff)


def test_tracked_points_keep_nears_contract():
    """Points that move between calls (triangulated.Tracked: a point is projected again only
    where its distance at its last projection, less how far it moved since, is within the
    cutoff): at every call ``near``'s contract at the cutoff, the points within it exact.
    Twelve steps of 0.3 mm in random directions, a drift towards the sphere among them; after
    the first call most points are not projected again (the call's cost)."""
    surface = TriangulatedSurface(*meshes.icosphere(10.0, 3), name="ico")
    x = near_points(surface, inner=9.8)
    tracked = Tracked(surface, exact=0.1, bound=2.0)
    projected = []
    for step in range(12):
        before = np.array(tracked._x, copy=True) if step else None
        assert_near(surface, x, *tracked(x), 0.1)
        if step:
            projected.append(np.mean(np.any(tracked._x != before, axis=1)))
        move = RNG.normal(size=x.shape)
        x = x + 0.3 * move / np.linalg.norm(move, axis=1, keepdims=True) - 0.05 * x / 40.0
    print(f"share projected again per call: {np.round(projected, 2)}")
    assert max(projected) < 0.5


def test_icosphere_converges_to_the_sphere():
    """Measured (R = 100 mm, 2000 points within ±20 mm of the sphere; edges 16.5, 8.26, 4.13 mm):
    distance 0.447, 0.112, 0.0281 mm; normal (gradient) 0.087, 0.044, 0.022 rad; interpolated
    vertex normals at the closest points 4.5e-3, 1.21e-3, 3.03e-4 rad."""
    R = 100.0
    sphere = analytic.Sphere(R)
    u = RNG.normal(size=(2000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    x = u * R * (1 + RNG.uniform(-0.2, 0.2, (2000, 1)))
    dd, dn, ds = [], [], []
    for level in (3, 4, 5):
        surface = TriangulatedSurface(*meshes.icosphere(R, level), name="ico")
        dd.append(np.abs(surface.signed_distance(x) - sphere.signed_distance(x)).max())
        dn.append(np.arccos(np.clip(np.sum(surface.normal(x) * u, 1), -1, 1)).max())
        on = x - surface.signed_distance(x)[:, None] * surface.normal(x)
        ds.append(
            np.arccos(
                np.clip(np.sum(surface.smooth_normal(on) * sphere.normal(on), 1), -1, 1)
            ).max()
        )
    assert rate(*dd[:2]) > 1.95 and rate(*dd[1:]) > 1.95, dd
    assert 0.9 < rate(*dn[:2]) < 1.1 and 0.9 < rate(*dn[1:]) < 1.1, dn
    assert rate(*ds[:2]) > 1.8 and rate(*ds[1:]) > 1.8, ds


def sphere_mesh(level: int = 2, R: float = 50.0):
    return meshes.icosphere(R, level)


@pytest.mark.parametrize(
    "fmt", ["binary.stl", "ascii.stl", "mesh.obj"], ids=["stl-binary", "stl-ascii", "obj"]
)
def test_files_round_trip_with_units(tmp_path, fmt):
    v, f = sphere_mesh()
    path = tmp_path / fmt
    write = {
        "binary.stl": lambda: files.write_stl(path, v / 1000.0, f, binary=True),
        "ascii.stl": lambda: files.write_stl(path, v / 1000.0, f, binary=False),
        "mesh.obj": lambda: files.write_obj(path, v / 1000.0, f),
    }
    write[fmt]()
    surface = files.read_surface(path, units="m")
    assert surface.name == str(path) and len(surface.faces) == len(f)
    assert len(surface.vertices) == len(v)  # the STL's repeated corners welded
    x = RNG.normal(size=(200, 3)) * 40.0
    exact = TriangulatedSurface(v, f).signed_distance(x)
    tol = 1e-5 if fmt == "binary.stl" else 1e-10  # float32 corners
    assert np.abs(surface.signed_distance(x) - exact).max() < tol * 50.0


def test_gmsh_rounded_box_converges():
    """A gmsh OpenCASCADE box 40 × 30 × 20 mm with 4 mm fillets on all edges, meshed at 4, 2,
    1 mm (longest edges 4.9, 2.7, 1.4 mm): measured distance errors against the analytic rounded
    box at points within 3 mm of it 0.451, 0.142, 0.0374 mm (the fillets' sagitta; rates 1.67,
    1.93)."""
    gmsh = pytest.importorskip("gmsh")
    box = analytic.RoundedBox((20.0, 15.0, 10.0), 4.0)
    x = RNG.uniform(-26.0, 26.0, (4000, 3))
    x = x[np.abs(box.signed_distance(x)) < 3.0]
    errors = []
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        for h in (4.0, 2.0, 1.0):
            gmsh.model.add(f"box{h}")
            tag = gmsh.model.occ.addBox(-20, -15, -10, 40, 30, 20)
            gmsh.model.occ.synchronize()
            edges = [e for _, e in gmsh.model.getEntities(1)]
            gmsh.model.occ.fillet([tag], edges, [4.0])
            gmsh.model.occ.synchronize()
            gmsh.option.setNumber("Mesh.MeshSizeMax", h)
            gmsh.option.setNumber("Mesh.MeshSizeMin", h)
            gmsh.model.mesh.generate(2)
            surface = meshes.from_gmsh(units="mm", name=f"box at h = {h}")
            errors.append(np.abs(surface.signed_distance(x) - box.signed_distance(x)).max())
            gmsh.model.remove()
    finally:
        gmsh.finalize()
    assert rate(*errors[:2]) > 1.5 and rate(*errors[1:]) > 1.5, errors
    assert rate(errors[0], errors[2]) / 2 > 1.7 and errors[2] < 0.05, errors


def bad_file(tmp_path, name: str, v, f) -> str:
    path = tmp_path / name
    files.write_stl(path, v, f, binary=False)
    return str(path)


def test_not_closed(tmp_path):
    v, f = sphere_mesh()
    path = bad_file(tmp_path, "open.stl", v, f[1:])
    with pytest.raises(InputError, match=r"open.stl: the surface is not closed: 3 boundary edge"):
        files.read_surface(path, units="mm")
    assert len(files.read_surface(path, units="mm", closed=False).faces) == len(f) - 1


def test_flipped_normals(tmp_path):
    v, f = sphere_mesh()
    path = bad_file(tmp_path, "inside_out.stl", v, f[:, ::-1])
    with pytest.raises(InputError, match=r"inside_out.stl: flipped normals.*volume -"):
        files.read_surface(path, units="mm")


def test_inconsistent_normals(tmp_path):
    v, f = sphere_mesh()
    f = f.copy()
    f[10] = f[10, ::-1]
    path = bad_file(tmp_path, "one_flipped.stl", v, f)
    with pytest.raises(InputError, match=r"one_flipped.stl: inconsistent normals: 3 edge"):
        files.read_surface(path, units="mm")


def test_degenerate_triangle(tmp_path):
    v, f = sphere_mesh()
    a, b = f[0, 0], f[0, 1]
    v = np.vstack([v, 0.5 * (v[a] + v[b])])  # a corner on an edge: zero area
    f = np.vstack([f, [a, b, len(v) - 1]])
    path = bad_file(tmp_path, "sliver.stl", v, f)
    with pytest.raises(InputError, match=r"sliver.stl: 1 degenerate triangle\(s\) of zero area"):
        files.read_surface(path, units="mm")


def test_units_and_formats(tmp_path):
    v, f = sphere_mesh()  # a punch of radius 50 mm written in mm
    path = tmp_path / "punch.obj"
    files.write_obj(path, v, f)
    punch = files.read_surface(path, units="m")  # read as metres: 1000 times too large
    with pytest.raises(
        InputError, match=r"punch.obj: the tool is 400 times larger than the blank.*units"
    ):
        checks.check_scale(punch, blank_size=250.0)
    checks.check_scale(files.read_surface(path, units="mm"), blank_size=250.0)
    with pytest.raises(InputError, match=r"units = 'mile' is not one of"):
        files.read_surface(path, units="mile")
    (tmp_path / "punch.step").write_text("")
    with pytest.raises(InputError, match=r"from .stl or .obj, not '.step'"):
        files.read_surface(tmp_path / "punch.step", units="mm")


def test_tool_inside_the_blank():
    X, Y = np.meshgrid(np.linspace(-100, 100, 41), np.linspace(-100, 100, 41))
    blank = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    checks.check_outside(analytic.HemispherePunch(50.0, pole=0.0), blank)  # touches: fine
    with pytest.raises(InputError, match=r"starts inside the blank: \d+ of 1681 points.*5 mm deep"):
        checks.check_outside(analytic.HemispherePunch(50.0, pole=5.0), blank)


def test_stroke_through_the_die():
    """A hemispherical punch (R = 50 mm, pole at 0) pushed up into a die whose lower face is
    at z = 20 mm: the die stops it at a stroke of 20 mm."""
    punch = analytic.HemispherePunch(50.0)
    die = analytic.RoundedBox((100.0, 100.0, 20.0), 2.0, centre=(0.0, 0.0, 40.0))
    pts = checks.surface_points(punch, (-60, -60, -60), (60, 60, 1), 2.0)
    assert np.abs(punch.signed_distance(pts)).max() < 1e-9 and len(pts) > 1000
    checks.check_stroke(punch, die, pts, (0, 0, 1), 19.0)
    with pytest.raises(
        InputError,
        match=r"stroke of 30 mm passes through the die.*10 mm inside.*stops it at a stroke of 20",
    ):
        checks.check_stroke(punch, die, pts, (0, 0, 1), 30.0)


def test_mirror_asymmetry():
    """Shapes that are their own mirror images in x = 0 and y = 0 pass, triangulated or not
    (the revolved punch's triangulation is not mirror-symmetric at every edge size, its
    vertices' images land on the other side's facets within their sagitta); the same shapes
    moved off the axis by a fifth or a fiftieth of a millimetre are named, with the plane."""
    symmetric = [
        analytic.HemispherePunch(20.0),
        analytic.RoundedBox((14.0, 10.0, 20.0), 2.0, centre=(0.0, 0.0, -20.0)),
        TriangulatedSurface(*meshes.hemisphere_punch_mesh(20.0, 1.3), name="revolved"),
    ]
    for shape in symmetric:
        assert checks.mirror_asymmetry(shape) is None, shape.name
    moved = [
        (analytic.Moved(analytic.HemispherePunch(20.0), (0.02, 0.0, 0.0)), "x = 0"),
        (analytic.RoundedBox((14.0, 10.0, 20.0), 2.0, centre=(0.0, 0.2, -20.0)), "y = 0"),
    ]
    v, f = meshes.hemisphere_punch_mesh(20.0, 1.3)
    moved.append((TriangulatedSurface(v + [0.0, 0.2, 0.0], f, name="moved"), "y = 0"))
    for shape, plane in moved:
        message = checks.mirror_asymmetry(shape)
        assert message is not None and f"not mirror-symmetric about {plane}" in message, shape
