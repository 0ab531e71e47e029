"""Forming beyond the symmetric square (docs/forming.md, "Blanks"): blanks of any outline and
fibre pairs without mirror symmetry about both mid-lines, solved on the full blank with its rigid
motions removed (experiments/forming/blank.py) on a fibre lattice clipped to the outline
(geometry/fibre_blank.py).

* the lattice (no FEniCSx form): centrally symmetric (the pole pin relies on it), covering the
  outline, no sliver, its vertices at most MERGE·h outside the outline, and its interior edges
  along the fibres or the parallelograms' diagonals;
* the lattice holds every discrete inextensible net: each triangle lies in one lattice
  triangle, so every discrete Chebyshev net of the lattice in 3D (rhombi folded about their
  diagonals), interpolated linearly, is a P1 deformation of the mesh that stretches no fibre
  anywhere. The mesh builder that snapped the boundary row onto the outline failed it and its
  mesh locked: the 72 mm square at K = 10⁵ N/mm stopped at 9.73 mm of a 12 mm stroke
  (docs/forming.md, "Blanks");
* bad input refused before any computation, naming key and value;
* the full blank of the symmetric square (and of two rectangles, at ±45° and 0/90) against
  the quarter with mirror conditions, on the
  quarter's own mesh unfolded (geometry.fibre_blank.mirrored_quarter), frictionless, at the
  set-up of tests/test_hemisphere.py (its compiled forms: the full blank keeps the quarter's
  mirror terms on edges it does not have). The two differ only in how the mirror lines' slope
  is penalised (a Nitsche term on the quarter, the interior-penalty jump, twice as stiff, on
  the full blank), a discretisation difference of the size test_penalty bounds: measured 0.13 %
  of the punch force at the last step, 1.2 % at the first (0.03 N, bending-dominated);
* the rigid-motion pins carry no load (their reactions vanish against the punch force): the
  pinned answer is an equilibrium of the unpinned problem, so the pins change nothing;
* a circular blank with 0/90 turned by 30° (no fibre along the axes, the full blank on the
  clipped lattice, holder with friction) in the kinematic limit against both drapes drawn with
  its own fibre directions over the contact area, with the bounds of the symmetric square's test
  (tests/test_hemisphere.py: RMS below 1°, max below 3°, below 1° within 0.75 R of the pole;
  measured there 0.70°, 2.50°, 0.78°). Measured here: 1169 points, RMS 0.63°, max 2.12°,
  within 0.75 R 0.70°. The circle's fibre lines through the pole are mirror lines of the set-up
  (any orthogonal pair), so the drapes' geodesic generators are the answer's; on a square at
  30/120 they are not, and the drapes are no reference there (docs/forming.md, "Blanks");
  the drape closed from the continuum's own generators gives the geodesic drape's numbers on
  the circle;
* a rectangle with the unbalanced 40/−50 pair against the drape closed from its own
  generators (verification/drapes/generator_drape.py): the difference falls at least at first order
  in h.
"""

import math

import numpy as np
import pytest
from hemisphere_case import BLANK, FRICTION, TOOLING, H, R
from mpi4py import MPI
from scipy.spatial import cKDTree

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import PluginSetup
from fabricsurf.experiments.forming import blank as forming_blank
from fabricsurf.experiments.hemisphere import HemispherePlugin
from fabricsurf.geometry.fibre_blank import MERGE, clip_lattice, lattice_triangulation, outline
from fabricsurf.model.terms import FibreStretch, NormalBending, Shear, Twist
from fabricsurf.verification.drapes.drape_map import summary
from fabricsurf.verification.drapes.forming_map import (
    compare_with_drapes,
    compare_with_generator_drape,
)

COMM = MPI.COMM_WORLD
CIRCLE = 72.0
"""The circle's diameter: its edge 8 mm beyond where the holder's pressure is full (R +
clearance + 3 lip = 28 mm). A 60 mm circle, held over its last 2 mm only, barely tensions the
fibres (punch force 1.54 N against 5.37 N) and its sheet does not reach the kinematic limit on
the punch (RMS 3.97° from the drapes, docs/forming.md)."""
STROKE, STEPS = 4.0, 4
DEEP, DEEP_STEPS = 12.0, 12
UNBALANCED_STEPS = 16
"""The unbalanced pair's steps to DEEP: its draw-in shears the sheet to 35°, and steps of 1 mm
cut near the end."""
TOUCH = 0.01 * R


def model():
    return [FibreStretch(k_l=1e3, k_m=1e3), Shear(k_s=1.0), NormalBending(k_b=0.1), Twist(k_t=0.1)]


def soft():
    """The kinematic limit of tests/test_hemisphere.py: stiff fibres, shear and bending a
    hundred times softer."""
    return [
        FibreStretch(k_l=1e3, k_m=1e3),
        Shear(k_s=1e-2),
        NormalBending(k_b=0.05),
        Twist(k_t=0.05),
    ]


def setup(blank="square", angles=(45.0, -45.0), size=(BLANK, BLANK), **extra):
    return PluginSetup("hemisphere", *size, angles, dict(TOOLING, blank=blank, **extra))


@pytest.mark.serial("numpy only: the lattice is built on one process")
@pytest.mark.parametrize(
    "shape, a, b, angles",
    [
        ("circle", 30.0, 30.0, (30.0, 120.0)),
        ("circle", 30.0, 30.0, (20.0, -50.0)),
        ("rectangle", 36.0, 30.0, (40.0, -50.0)),
        ("rectangle", 36.0, 30.0, (10.0, 70.0)),
    ],
)
def test_clipped_lattice(shape, a, b, angles):
    X, tri, quality = clip_lattice(shape, a, b, angles, H)
    phi = outline(shape, a, b)
    assert cKDTree(X).query(-X)[0].max() < 1e-9 * a  # centrally symmetric
    p, q, r = (X[tri[:, k]] for k in range(3))
    area = 0.5 * np.abs(np.cross(q - p, r - p))
    exact = math.pi * a * a if shape == "circle" else 4 * a * b
    assert abs(area.sum() / exact - 1.0) < 0.01  # measured 0.9989–1.0003
    assert abs(quality["area_fraction"] * exact - area.sum()) < 1e-9 * exact
    assert quality["min_angle_deg"] > 5.0  # no sliver (measured 7.5–16.1°)
    assert phi(X).max() < MERGE * H + 1e-9 * a  # a crossing moved along an edge
    L, M = (np.array([math.cos(math.radians(t)), math.sin(math.radians(t))]) for t in angles)
    allowed = [L, M, L + M, L - M]
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    e = np.sort(edges, axis=1)
    _, count = np.unique(e, axis=0, return_counts=True)
    assert count.max() == 2  # conforming: no edge shared by three cells
    outer = np.unique(e, axis=0)[count == 1]
    assert np.abs(phi(X[outer.ravel()])).max() < MERGE * H + 1e-9 * a  # no hanging vertex
    inner = np.unique(e, axis=0)[count == 2]
    inner = inner[(np.abs(phi(X[inner[:, 0]])) > 1e-9) & (np.abs(phi(X[inner[:, 1]])) > 1e-9)]
    v = X[inner[:, 1]] - X[inner[:, 0]]
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    off = np.min([np.abs(np.cross(v, w / np.linalg.norm(w))) for w in allowed], axis=0)
    assert off.max() < 1e-9  # every edge between interior vertices along a fibre or diagonal


def unit(deg: float) -> np.ndarray:
    return np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])


def discrete_net(n: int, L: np.ndarray, M: np.ndarray, rng) -> np.ndarray:
    """A discrete Chebyshev net in 3D on the lattice indices −n..n: x[i, j] with every fibre
    edge of length H. Its generators (j = 0 and i = 0) are polylines of steps H near L and M,
    tilted out of the plane at random; every other vertex completes the quad towards the axes
    as a rhombus folded about its diagonal by a random angle (the rhombus's fourth vertex
    turned about the line through its two neighbours)."""
    x = np.zeros((2 * n + 1, 2 * n + 1, 3))

    def step(v):
        a = rng.uniform(-0.3, 0.3, 2)
        w = np.array(
            [
                *(
                    math.cos(a[0]) * v[0] - math.sin(a[0]) * v[1],
                    math.sin(a[0]) * v[0] + math.cos(a[0]) * v[1],
                ),
                0.0,
            ]
        )
        return H * (math.cos(a[1]) * w + [0.0, 0.0, math.sin(a[1])])

    for k in range(1, n + 1):
        for s in (1, -1):
            x[n + s * k, n] = x[n + s * (k - 1), n] + s * step(L)
            x[n, n + s * k] = x[n, n + s * (k - 1)] + s * step(M)
    for r in range(2, 2 * n + 1):
        for i in range(-n, n + 1):
            j = r - abs(i)
            for jj in {j, -j}:
                if i == 0 or not 0 < j <= n:
                    continue
                si, sj = int(np.sign(i)), int(np.sign(jj))
                a, b = x[n + i - si, n + jj], x[n + i, n + jj - sj]
                p = a + b - x[n + i - si, n + jj - sj]
                m, ax = 0.5 * (a + b), (a - b) / np.linalg.norm(a - b)
                t, v = rng.uniform(-0.3, 0.3), p - 0.5 * (a + b)
                x[n + i, n + jj] = m + math.cos(t) * v + math.sin(t) * np.cross(ax, v)
    return x


@pytest.mark.serial("numpy only: the lattice is built on one process")
@pytest.mark.parametrize(
    "shape, a, b, angles",
    [
        ("rectangle", 36.0, 36.0, (45.0, -45.0)),
        ("circle", 42.0, 42.0, (30.0, 120.0)),
        ("rectangle", 36.0, 30.0, (40.0, -50.0)),
        ("circle", 30.0, 30.0, (20.0, -50.0)),
    ],
)
def test_clipped_lattice_holds_every_fibre_net(shape, a, b, angles):
    """Stiff fibres do not lock on the clipped lattice: a discrete Chebyshev net of the lattice
    (fibre edges of length h, each parallelogram a rhombus folded about the diagonal the
    lattice's triangles share), interpolated linearly over the lattice's triangles, keeps
    every fibre's length in every cell of the mesh (|F L| = |F M| = 1), in 3D, as on the aligned
    quarter: each cell lies in one lattice triangle. A cell that leaves it (a vertex snapped
    onto the outline) spans a fold or a kink, stretches its fibres under such a net, and at
    large K stiffens the whole blank."""
    X, tri, _ = clip_lattice(shape, a, b, angles, H)
    X0, tri0 = lattice_triangulation(shape, a, b, angles, H)
    L, M = unit(angles[0]), unit(angles[1])
    ij = np.rint(np.linalg.solve(np.column_stack([L, M]), X0.T).T / H).astype(int)
    n = int(np.abs(ij).max())
    x = discrete_net(n, L, M, np.random.default_rng(7))[ij[:, 0] + n, ij[:, 1] + n]
    # each mesh vertex's value: the net's linear interpolant on a lattice triangle holding it
    P = X0[tri0]
    T = np.linalg.inv(np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2))
    st = np.einsum("tij,vtj->vti", T, X[:, None, :] - P[None, :, 0])
    bary = np.concatenate([1.0 - st.sum(axis=2, keepdims=True), st], axis=2)
    k = bary.min(axis=2).argmax(axis=1)
    assert bary.min(axis=2).max(axis=1).min() > -1e-9  # every vertex on the lattice
    w = bary[np.arange(len(X)), k]
    y = np.einsum("vk,vkd->vd", w, x[tri0[k]])
    A = np.stack([X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]], axis=2)
    B = np.stack([y[tri[:, 1]] - y[tri[:, 0]], y[tri[:, 2]] - y[tri[:, 0]]], axis=2)
    F = B @ np.linalg.inv(A)
    stretch = np.concatenate([np.linalg.norm(F @ L, axis=1), np.linalg.norm(F @ M, axis=1)])
    assert np.abs(stretch - 1.0).max() < 1e-9


def test_bad_blanks_refused_before_computing():
    with pytest.raises(DataError, match=r"\[tooling\] blank = 'oval'"):
        HemispherePlugin.parse_options({"tooling": {"punch_radius": R, "blank": "oval"}}, 1.0, "t")
    with pytest.raises(DataError, match=r"blank_domain = 'half'"):
        HemispherePlugin.parse_options(
            {"tooling": {"punch_radius": R, "blank_domain": "half"}}, 1.0, "t"
        )
    with pytest.raises(DataError, match=r"circle blank 40 × 40 mm .*die opening"):
        HemispherePlugin.check_specimen(setup("circle", size=(40.0, 40.0)), "t")
    with pytest.raises(DataError, match=r"rectangle blank 80 × 44 mm .*die opening"):
        HemispherePlugin.check_specimen(setup("rectangle", size=(80.0, 44.0)), "t")
    with pytest.raises(DataError, match=r"blank = 'circle' needs length = width"):
        HemispherePlugin.check_specimen(setup("circle", size=(60.0, 50.0)), "t")
    with pytest.raises(DataError, match=r"fibre_angles_deg = \[30.0, 50.0\].* 20° apart"):
        HemispherePlugin(setup("circle", (30.0, 50.0)), model(), H, COMM)
    with pytest.raises(DataError, match=r"'quarter': a square with fibre_angles_deg = \[30\.0"):
        HemispherePlugin(setup("square", (30.0, 120.0), blank_domain="quarter"), model(), H, COMM)
    with pytest.raises(DataError, match=r"'quarter': no fibre-aligned lattice of a 36 × 29\.1"):
        forming_blank.domain(setup("rectangle", size=(72.0, 58.2), blank_domain="quarter"), H)
    with pytest.raises(DataError, match=r"h = 12 mm is more than 0.5 of the punch radius"):
        forming_blank.check_mesh(setup("circle"), 12.0, False)
    narrow = setup("rectangle", (30.0, 120.0), (80.0, 50.0))
    forming_blank.check_stroke(narrow, 25.0)
    with pytest.raises(DataError, match=r"stroke 30 mm is outside 0 < stroke ≤ 25\.96"):
        forming_blank.check_stroke(narrow, 30.0)  # the short side's reach, not the long one's


def test_domain_choice():
    """The quarter wherever an aligned quarter mesh exists at h: squares and rectangles with
    fibres at ±θ or 0/90, a rectangle at ±θ only when its sides fit a lattice at that angle
    (36 × 30 at ±45°: 12 × 10 cells of 3 mm; 36 × 29.1: none within 0.05° near h = 4 mm, nor
    the 60 mm square at ±30°, which stopped with that ValueError before)."""
    domain = forming_blank.domain
    assert domain(setup(), H) == "quarter"
    assert domain(setup(angles=(0.0, 90.0)), H) == "quarter"
    assert domain(setup("rectangle", size=(72.0, 60.0)), H) == "quarter"
    assert domain(setup("rectangle", (0.0, 90.0), (72.0, 58.2)), H) == "quarter"
    assert domain(setup("rectangle", size=(72.0, 58.2)), H) == "full"
    assert domain(setup(angles=(30.0, -30.0)), H) == "full"  # none within 0.05° near 4 mm
    assert domain(setup(angles=(30.0, 120.0)), H) == "full"
    assert domain(setup(angles=(40.0, -50.0)), H) == "full"
    assert domain(setup("circle"), H) == "full"
    assert domain(setup(blank_domain="full"), H) == "full"
    assert forming_blank.bisector_deg((30.0, 120.0)) == -15.0  # (the other one: 75)
    assert forming_blank.bisector_deg((20.0, -50.0)) == -15.0


def formed(
    s: PluginSetup, moduli, stroke: float, steps: int, h: float = H
) -> tuple[HemispherePlugin, dict]:
    e = HemispherePlugin(s, moduli, h, COMM)
    e.run(stroke, steps)
    return e, {
        "force": np.array(e.force),
        "shear": e.max_shear_deg(),
        "pins": e.pin_reactions(),
        "record": e.discretisation,
    }


@pytest.mark.serial(
    "a rank-independent identity of two discretisations; the full blank on 2 ranks "
    "is exercised by test_circle_rotated_pair_against_drapes (CI budget)"
)
@pytest.mark.parametrize(
    "blank, angles, size",
    [
        ("square", (45.0, -45.0), (BLANK, BLANK)),
        ("rectangle", (45.0, -45.0), (72.0, 60.0)),
        ("rectangle", (0.0, 90.0), (72.0, 64.0)),
    ],
)
def test_full_blank_matches_quarter(blank, angles, size):
    quarter, q = formed(setup(blank, angles, size), model(), STROKE, STEPS)
    quarter.close()
    full, f = formed(setup(blank, angles, size, blank_domain="full"), model(), STROKE, STEPS)
    full.close()
    assert q["record"]["domain"] == "quarter" and f["record"]["domain"] == "full"
    assert f["record"]["cells"] == 4 * q["record"]["cells"]
    rel = np.abs(f["force"][1:] / q["force"][1:] - 1.0)
    print(
        f"full / quarter punch force - 1 per step: {rel}; max shear {f['shear']:.4f} "
        f"against {q['shear']:.4f} deg; pins {f['pins']}"
    )
    assert rel[-1] < 3e-3 and rel.max() < 2e-2
    assert abs(f["shear"] - q["shear"]) < 2e-2
    assert set(f["pins"]) == {"pole_x", "pole_y", "rotation_x"}  # frictionless: all three
    assert max(abs(v) for v in f["pins"].values()) < 1e-8 * f["force"][-1]


def test_circle_rotated_pair_against_drapes():
    """0/90 turned by 30° on a circular blank in the kinematic limit: the drapes with the
    same fibre directions from the pole. With friction the rotation is not pinned; the pole
    pins carry no load."""
    s = PluginSetup(
        "hemisphere", CIRCLE, CIRCLE, (30.0, 120.0), dict(TOOLING, **FRICTION, blank="circle")
    )
    e, out = formed(s, soft(), DEEP, DEEP_STEPS)
    with e:
        m = compare_with_drapes(e, a=R / 40.0)
        g = compare_with_generator_drape(e)
    inner = np.hypot(*m["points"].T) < 0.75 * R
    d = np.abs(m["continuum_deg"] - m["fishnet_deg"])
    print(
        f"circle, fibres 30/120: {out['record']}, force {out['force'][-1]:.4f} N, "
        f"{summary(m)}, within 0.75 R ({inner.sum()} points) max {d[inner].max():.3f} deg, "
        f"pins {out['pins']}"
    )
    assert out["record"]["domain"] == "full" and set(out["pins"]) == {"pole_x", "pole_y"}
    assert len(m["points"]) > 1000 and np.abs(m["fishnet_deg"]).max() > 15.0
    assert m["fishnet_deg"].min() < -15.0  # both signs: across the fibres through the pole
    for key in ("continuum_vs_fishnet", "continuum_vs_goursat"):
        assert m[key]["rms_deg"] < 1.0 and m[key]["max_deg"] < 3.0, (key, m[key])
    assert d[inner].max() < 1.0
    assert max(abs(v) for v in out["pins"].values()) < 1e-6 * out["force"][-1]
    # the continuum's own generators are the geodesics here (mirror lines of the set-up): the
    # drape closed from them is the fishnet's (measured 0.623723° against 0.623722° RMS)
    assert g["left_out"] == 0 and len(g["points"]) == len(m["points"])
    own = g["continuum_vs_generator_drape"]
    assert abs(own["rms_deg"] - m["continuum_vs_fishnet"]["rms_deg"]) < 1e-2, own


@pytest.mark.serial(
    "two forming runs (CI budget); the generator drape on 2 ranks is "
    "test_circle_rotated_pair_against_drapes"
)
def test_rectangle_unbalanced_pair_against_its_own_generators():
    """A 72 × 60 mm rectangle with the unbalanced 40/−50 pair in the kinematic limit: no mirror
    line of the set-up is a fibre, the draw-in bends the fibres through the pole, and the
    geodesic drapes are no reference (RMS 12° from the continuum). The drape closed from the
    continuum's own generators (verification/drapes/generator_drape.py) is: what is left is the
    discretisation's difference, which must fall at least at first order in h (measured RMS
    2.28°, 1.20°, 0.76° at h = 5.66, 4, 2.83 mm; within 0.75 R max 6.2°, 2.4°, 1.4°, in 12
    steps). In 16 steps of 0.75 mm (:data:`UNBALANCED_STEPS`) RMS 2.29° and 1.18°, max 6.1°
    and 2.3° at h = 5.66 and 4 mm: in 12 the last steps cut their increments four times, and
    the test took 64 s instead of 37 s."""
    s = PluginSetup(
        "hemisphere", 72.0, 60.0, (40.0, -50.0), dict(TOOLING, **FRICTION, blank="rectangle")
    )
    rms, inner = [], []
    for h in (4.0 * math.sqrt(2.0), H):
        e, out = formed(s, soft(), DEEP, UNBALANCED_STEPS, h)
        with e:
            g = compare_with_generator_drape(e)
            geodesic = compare_with_drapes(e, a=R / 40.0)["continuum_vs_fishnet"]
        d = np.abs(g["continuum_deg"] - g["drape_deg"])
        rms.append(g["continuum_vs_generator_drape"]["rms_deg"])
        inner.append(d[np.hypot(*g["points"].T) < 0.75 * R].max())
        print(
            f"h = {h:.2f}: {out['record']['cells']} cells, {len(g['points'])} points "
            f"({g['left_out']} left out), own generators {g['continuum_vs_generator_drape']}, "
            f"within 0.75 R max {inner[-1]:.3f} deg; geodesic drapes {geodesic}; generators "
            f"up to {g['generators_largest_gap_mm']:.3f} mm off the cap"
        )
        assert out["record"]["domain"] == "full" and len(g["points"]) > 1000
        assert g["left_out"] < 0.05 * len(g["points"])
        # generator samples lifted off the cap between contact points (0.30, 0.20 mm measured):
        # their projection onto it errs by that, below 2 % of R
        assert g["generators_largest_gap_mm"] < 0.02 * R
        assert np.abs(g["drape_deg"]).max() > 15.0 and geodesic["rms_deg"] > 5.0
    assert rms[1] < rms[0] / math.sqrt(2.0) and inner[1] < inner[0] / math.sqrt(2.0)
    assert rms[1] < 1.5 and inner[1] < 3.0
