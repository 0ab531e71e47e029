"""The die's and the holder's opening as a rectangle with rounded corners
(fabricsurf/experiments/forming/surfaces/opening.py, opening_form.py; docs/tool_surfaces.md,
"The die's opening").

Checks that can fail independently of each other:

* σ is the signed distance to the outline: against the distance to 20 000 points on the outline
  per unit of radius (a point cloud is never nearer than the curve, and at most half its
  spacing farther) and against an independent inside test (matplotlib's point-in-polygon on
  that cloud), on a slot, a sharp-cornered and a rounded rectangle and a square of corner
  radius equal to its half-side (the circle); its gradient is its central difference;
* the UFL form of σ and ∇σ equals the numpy one at the quadrature points of a deformed sheet;
* the circle given as a rectangle (sides 2 R_o, corner radius R_o, the rectangle's formula)
  forms the blank as the circle does: forces and energies agree to the Newton tolerance;
* a rectangle 2a × 2b and the same rotated (2b × 2a), with fibres at ±45° on a square blank
  (a mirror image in the diagonal, the aligned quarter mesh its own mirror image): the same
  punch force at every step, to the Newton tolerance, though the opening is not square;
* the hemisphere in a slot narrower than the punch is refused at the stroke where it meets the
  lip: its centre, at s − R, lies R + r_d from the lip's spine line y = b + r_d, z = z_t, at
  s* = z_t + R − √((R + r_d)² − (b + r_d)²);
* bad options and a blank that does not cover the opening are refused, naming key and sizes.
"""

import math

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from hemisphere_case import BLANK, TOOLING, H, R
from matplotlib.path import Path as PolyPath
from mpi4py import MPI
from scipy.spatial import cKDTree

from fabricsurf.discretise.quadrature import quadrature_points
from fabricsurf.errors import DataError, InputError
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming import options as forming_options
from fabricsurf.experiments.forming.surfaces.opening import Opening
from fabricsurf.experiments.forming.surfaces.opening_form import OpeningForm
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist

COMM = MPI.COMM_WORLD
RNG = np.random.default_rng(11)
OUTLINES = [
    Opening("rectangle", 30.0, 18.0, 18.0),  # a slot with round ends
    Opening("rectangle", 30.0, 18.0, 0.0),  # sharp corners
    Opening("rectangle", 30.0, 18.0, 6.0),
    Opening("rectangle", 22.0, 22.0, 22.0),  # the circle, by the rectangle's formula
]
STROKE, STEPS = 4.0, 4
R_O = TOOLING["punch_radius"] + TOOLING["clearance"]


def outline_points(o: Opening, spacing: float) -> np.ndarray:
    """Points along the outline (straight sides and corner arcs), ``spacing`` apart at most,
    in order (a closed polygon)."""
    a, b, c = o.half_length, o.half_width, o.corner
    pts = []
    for k, (sx, sy) in enumerate([(1, 1), (-1, 1), (-1, -1), (1, -1)]):
        t0 = k * math.pi / 2
        n = max(2, math.ceil(c * math.pi / 2 / spacing))
        t = t0 + np.linspace(0.0, math.pi / 2, n)
        arc = np.column_stack([sx * (a - c) + c * np.cos(t), sy * (b - c) + c * np.sin(t)])
        end = arc[-1]
        # the straight side to the next corner
        nx, ny = [(-1, 1), (-1, -1), (1, -1), (1, 1)][k]
        start = np.array([nx * (a - c), ny * (b - c)]) + c * np.array(
            [math.cos(t0 + math.pi / 2), math.sin(t0 + math.pi / 2)]
        )
        m = max(2, math.ceil(np.linalg.norm(start - end) / spacing) + 1)
        pts += [arc, end + np.linspace(0.0, 1.0, m)[:, None] * (start - end)]
    return np.vstack(pts)


@pytest.mark.parametrize("o", OUTLINES, ids=lambda o: o.name)
def test_sigma_is_the_distance_to_the_outline(o):
    spacing = 1e-3
    cloud = outline_points(o, spacing)
    x = RNG.uniform(-45.0, 45.0, (600, 2))
    d_cloud = cKDTree(cloud).query(x)[0]
    sigma = o.sigma(x)
    delta = 1e-9 * (o.half_length + o.half_width)
    err = d_cloud - np.abs(sigma)
    assert err.min() > -2 * delta - 1e-9 and err.max() < 0.5 * spacing + delta, (
        err.min(),
        err.max(),
    )
    inside = PolyPath(cloud).contains_points(x)
    assert np.array_equal(inside, sigma < 0)
    h = 1e-6
    grad = np.column_stack([(o.sigma(x + h * e) - o.sigma(x - h * e)) / (2 * h) for e in np.eye(2)])
    q = np.abs(x) - np.array([o.half_length, o.half_width]) + o.corner
    smooth = (sigma > 1e-4) | (np.abs(q[:, 0] - q[:, 1]) > 1e-4)  # off the inside's creases
    assert smooth.mean() > 0.95
    assert np.abs(grad - o.gradient(x))[smooth].max() < 1e-6


@pytest.mark.parametrize("o", OUTLINES, ids=lambda o: o.name)
def test_ufl_form_matches_numpy(o):
    msh = mesh.create_rectangle(COMM, [[-45.0, -45.0], [45.0, 45.0]], [12, 12])
    V = fem.VectorFunctionSpace(msh, ("CG", 1), dim=3)
    u = fem.Function(V)
    u.interpolate(lambda x: np.vstack([0.1 * x[1], -0.05 * x[0], 0.01 * x[0] * x[1]]))
    x = ufl.SpatialCoordinate(msh)
    r = ufl.as_vector([x[0] + u[0], x[1] + u[1], u[2]])
    form = OpeningForm(msh, o)
    points = quadrature_points(msh)
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    rq = fem.Expression(r, points).eval(cells).reshape(-1, 3)
    sigma = fem.Expression(form.sigma(r), points).eval(cells).ravel()
    grad = fem.Expression(form.gradient(r), points).eval(cells).reshape(-1, 2)
    assert np.abs(sigma - o.sigma(rq)).max() < 1e-12 * 60.0
    assert np.abs(grad - o.gradient(rq)).max() < 1e-12


def model():
    return [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]


def form(options: dict, angles=(45.0, -45.0), blank: float = BLANK) -> dict:
    with HemispherePlugin(
        PluginSetup("hemisphere", blank, blank, angles, options), model(), H, COMM
    ) as e:
        e.run(STROKE, STEPS)
        stored, tools = e.energies()
        return {"force": np.array(e.force), "stored": stored, "tools": tools}


def rectangle(length: float, width: float, corner: float) -> dict:
    return {
        **TOOLING,
        "die_opening_length": length,
        "die_opening_width": width,
        "die_corner_radius": corner,
    }


def test_circle_as_a_rectangle_forms_as_the_circle():
    circle = form(dict(TOOLING))
    square = form(rectangle(2 * R_O, 2 * R_O, R_O))
    print(f"circle {circle['force']}, as a rectangle {square['force']}")
    assert np.allclose(square["force"], circle["force"], rtol=1e-8, atol=1e-12)
    for k in ("stored", "tools"):
        assert math.isclose(square[k], circle[k], rel_tol=1e-8), k


def test_rotated_opening_gives_the_same_force():
    """A slot 2a × 2b wider than the punch both ways, against its rotation by 90°."""
    blank = 80.0
    along_x = form(rectangle(56.0, 48.0, 8.0), blank=blank)
    along_y = form(rectangle(48.0, 56.0, 8.0), blank=blank)
    circle = form(dict(TOOLING), blank=blank)
    print(f"x {along_x['force']}, y {along_y['force']}, circle {circle['force']}")
    assert np.allclose(along_x["force"], along_y["force"], rtol=1e-8, atol=1e-12)
    assert math.isclose(along_x["stored"], along_y["stored"], rel_tol=1e-8)
    # the opening is wider than the circle of radius 22 mm, so the sheet spans farther
    # before it reaches the lip: the two runs differ from the circle's
    assert abs(along_x["force"][-1] - circle["force"][-1]) > 1e-3 * circle["force"][-1]


def test_hemisphere_in_a_narrow_slot_refused_where_it_meets_the_lip():
    b, lip = 18.0, TOOLING["die_lip"]
    z_t = lip - TOOLING["holder_pressure"] / TOOLING["contact_stiffness"]
    exact = z_t + R - math.sqrt((R + lip) ** 2 - (b + lip) ** 2)
    opts = rectangle(48.0, 2 * b, b)  # a slot with round ends of radius b
    e = HemispherePlugin(
        PluginSetup("hemisphere", BLANK, BLANK, (45.0, -45.0), opts), model(), H, COMM
    )
    try:
        e.check_stroke(exact - 0.2)
        with pytest.raises(InputError, match=r"hemispherical punch .* the stroke of 14 mm") as err:
            e.run(14.0, 4)
        stop = float(str(err.value).split("stroke of ")[-1].split(" mm")[0])
        # the die check's grid: a spacing of 0.51 mm (a quarter lip radius, widened to at most
        # 2e6 points), its points projected onto the punch within 0.36 mm of the first
        # contact, whose stroke they overestimate by at most 0.36² (1/R + 1/r_d) / 2
        assert 0.0 <= stop - exact < 0.36**2 * (1 / R + 1 / lip) / 2, (stop, exact)
        assert e.steps == []
    finally:
        e.close()


def parse(tooling: dict) -> dict:
    return HemispherePlugin.parse_options({"tooling": {"punch_radius": 50.0, **tooling}}, 1.0, "t")


def test_options_and_their_defaults():
    o = parse({"die_opening_length": 200.0})
    assert (o["die_opening_length"], o["die_opening_width"], o["die_corner_radius"]) == (
        200.0,
        120.0,
        60.0,
    )
    op = forming_options.opening(o)
    assert (op.kind, op.half_length, op.half_width, op.corner) == ("rectangle", 100.0, 60.0, 60.0)
    assert forming_options.opening(parse({})).kind == "circle"
    cm = HemispherePlugin.parse_options(
        {"tooling": {"punch_radius": 5.0, "die_opening_length": 20.0, "die_corner_radius": 1.0}},
        10.0,
        "t",
    )
    assert (cm["die_opening_length"], cm["die_corner_radius"]) == (200.0, 10.0)


@pytest.mark.parametrize(
    "tooling, words",
    [
        ({"die_opening_length": 200.0, "die_corner_radius": 70.0}, r"die_corner_radius = 70 .*60"),
        ({"die_opening_width": -1.0}, r"die_opening_width = -1.0 must be a positive"),
        ({"die_opening_length": "wide"}, r"die_opening_length = 'wide'"),
    ],
)
def test_bad_options_refused(tooling, words):
    with pytest.raises(DataError, match=words):
        parse(tooling)


def test_blank_must_cover_the_opening():
    o = rectangle(70.0, 30.0, 5.0)
    with pytest.raises(DataError, match=r"opening 70 × 30 mm .* 74 × 34 mm"):
        HemispherePlugin.check_specimen(PluginSetup("hemisphere", 60.0, 60.0, (45, -45), o), "t")
    with pytest.raises(DataError, match=r"circle blank 76 × 76 mm .*opening 70 × 30"):
        HemispherePlugin.check_specimen(
            PluginSetup("hemisphere", 76.0, 76.0, (30, -60), {**o, "blank": "circle"}), "t"
        )
    message = forming_options.unheld_edge(o, 40.0, 40.0)
    assert message is not None and "41, 21 mm" in message and "82 × 42 mm" in message
    assert forming_options.unheld_edge(o, 41.0, 41.0) is None
    with pytest.raises(InputError, match="corner radius"):
        Opening("rectangle", 10.0, 5.0, 6.0)
