"""The second kinematic drape (fabricsurf/verification/drapes/goursat_drape.py) on its own, the two
drapes against each other over the whole punch, and the map comparison of a continuum result
(fabricsurf/verification/drapes/drape_map.py).

Checks that can fail independently of each other:
* on a cylinder and a cone (developable) the net is the flat net rolled onto the surface, in
  closed form: the node positions converge to it and the shear to zero at rate 2 (the box
  scheme and the geodesic scheme are both centred, second order);
* on the sphere the generators are great circles: node k at the polar angle k h / R, to O(h²);
  near the pole the shear is K sin θ0 u v (Hazzidakis' equation linearised, non-orthogonal
  fibres), and at a point 0.6 rad from the pole it converges at rate 2 to the Chebyshev net of
  Hazzidakis' equation (fishnet.chebyshev_shear, solved intrinsically on its own grid);
* the fishnet and the Goursat net, which share no code, agree over the whole hemispherical cap
  (every grid point whose draped position lies above the equator), their max and RMS
  difference falling at rate 2 with the cell size (each is O(a²) from the same Chebyshev net);
* shear_difference_map returns the differences of a given field from the drapes: a field made
  of the fine Goursat net plus a known perturbation gives the perturbation's max and RMS.

All of it is numpy: the 2-rank session skips it (no MPI path).
"""

import math

import numpy as np
import pytest

from fabricsurf.verification.drapes import drape_map, goursat_drape
from fabricsurf.verification.drapes.fishnet import chebyshev_shear

pytestmark = pytest.mark.serial("numpy only: nothing here depends on the ranks")
R = 20.0
ANGLES = (30.0, -40.0)
"""Non-orthogonal fibres at angles to the cylinder's axis and the cone's generatrix (θ0 = 70°)."""


def rate(coarse: float, fine: float) -> float:
    return math.log2(coarse / fine)


def reference_points(net) -> np.ndarray:
    k = np.arange(-net.n, net.n + 1) * net.h
    return k[:, None, None] * net.L + k[None, :, None] * net.M


def cylinder_error(h: float) -> tuple[float, float]:
    """(largest position error, largest |γ|) of the net on a cylinder of radius 30 mm, axis
    along the frame's e2, over |u|, |v| ≤ 24 mm: exact r = (ρ sin(ξ/ρ), η, ρ cos(ξ/ρ))."""
    rho = 30.0
    net = goursat_drape.drape(
        goursat_drape.Cylinder(rho),
        np.array([0.0, 0.0, rho]),
        np.eye(3)[:2],
        ANGLES,
        h,
        round(24.0 / h),
    )
    X = reference_points(net)
    exact = np.stack(
        [rho * np.sin(X[..., 0] / rho), X[..., 1], rho * np.cos(X[..., 0] / rho)], axis=-1
    )
    return float(np.abs(net.x - exact).max()), float(np.abs(net.shear).max())


def cone_error(h: float) -> tuple[float, float]:
    """The same on a cone of half-angle 30° from a point 80 mm from its apex, over |u|, |v| ≤
    20 mm: the development's polar coordinates (s, φ) about the apex give the azimuth φ / sin α."""
    al, s0 = math.radians(30.0), 80.0
    e1 = np.array([math.sin(al), 0.0, math.cos(al)])
    net = goursat_drape.drape(
        goursat_drape.Cone(al), s0 * e1, np.array([e1, [0.0, 1.0, 0.0]]), ANGLES, h, round(20.0 / h)
    )
    X = reference_points(net)
    d0, d1 = s0 + X[..., 0], X[..., 1]
    s, psi = np.hypot(d0, d1), np.arctan2(d1, d0) / math.sin(al)
    exact = np.stack(
        [s * math.sin(al) * np.cos(psi), s * math.sin(al) * np.sin(psi), s * math.cos(al)], axis=-1
    )
    return float(np.abs(net.x - exact).max()), float(np.abs(net.shear).max())


@pytest.mark.parametrize("case", [cylinder_error, cone_error])
def test_developable_surfaces(case):
    """Measured: cylinder position errors 0.0189, 0.00472 mm and shear 1.4e-3, 3.4e-4 rad at
    h = 2, 1 mm (rates 2.00, 2.00); cone 0.00264, 0.00066 mm and 6.6e-4, 1.8e-4 rad (rates 2.00,
    1.91: the largest shear sits at a corner, one-sided differences; 1.95 from h = 1 to 0.5)."""
    (x2, g2), (x1, g1) = case(2.0), case(1.0)
    assert rate(x2, x1) > 1.9 and rate(g2, g1) > 1.8, (x2, x1, g2, g1)
    assert x1 < 2e-4 * 30.0 and g1 < 1e-3


def test_sphere_generators_are_great_circles():
    errors = []
    for h in (2.0, 1.0):
        net = goursat_drape.hemisphere(R, ANGLES, h, 0.5 * math.pi * R)
        x = net.x[net.n :, net.n]  # the generator along +L
        polar = np.arccos(np.clip(x[:, 2] / R, -1.0, 1.0))
        k = np.arange(len(x))
        errors.append(np.abs(polar - k * h / R).max())
        assert np.abs(x[:, :2] @ np.array([-net.L[1], net.L[0]])).max() < 1e-12 * R
        assert np.abs(np.linalg.norm(net.x, axis=-1) - R).max() < 1e-12 * R
    assert rate(*errors) > 1.9, errors


def test_sphere_near_the_pole():
    """Hazzidakis' γ_uv = K sin(θ0 − γ), γ = 0 on the generators, expanded in K u v:
    γ = K s u v (1 − K c u v / 4 + O((K u v)²)), s = sin θ0, c = cos θ0. At u = v = R/20
    (K u v = 1/400) the second term is −2.1e-4 and the next 6e-6; the net's relative deviation
    from the first term is −1.73e-4, −2.04e-4, −2.11e-4 at h = R/100, R/200, R/400 (its O(h²)
    error falling by 4). On a generator the shear vanishes to the scheme's truncation."""
    h, u = R / 400.0, R / 20.0
    net = goursat_drape.hemisphere(R, ANGLES, h, 2 * u)
    m = net.n + round(u / h)
    s, c, kuv = math.sin(math.radians(70.0)), math.cos(math.radians(70.0)), u * u / R**2
    assert abs(net.shear[m, m] / (s * kuv) - (1.0 - c * kuv / 4.0)) < 2e-5
    assert abs(net.shear[net.n + 3, net.n]) < 1e-6 * s * kuv


def test_sphere_converges_to_the_chebyshev_net():
    """At u = v = 12 mm = 0.6 R (0/90 fibres): errors 4.4e-4, 1.2e-4 rad at h = 2, 1 mm."""
    u = 12.0
    ref = (4 * chebyshev_shear(R, u, u, 120) - chebyshev_shear(R, u, u, 60)) / 3
    errors = []
    for h in (2.0, 1.0):
        net = goursat_drape.hemisphere(R, (0.0, 90.0), h, u + h)
        m = net.n + round(u / h)
        errors.append(abs(net.shear[m, m] - ref))
    assert rate(*errors) > 1.8 and errors[1] < 2e-3 * ref, (errors, ref)


@pytest.mark.parametrize("angles", [(45.0, -45.0), (30.0, -30.0)])
def test_two_drapes_agree_over_the_cap(angles):
    """Measured (±45°, 705 points of the whole cap, shear up to 50°): max 0.115, 0.0286,
    0.00713° and RMS 0.0541, 0.0135, 0.00336° at a = R/10, R/20, R/40 (ratios 4.0)."""
    pts = drape_map.cap_grid(R, angles, R / 20.0, 90.0)
    runs = [drape_map.drape_agreement(R, R / k, angles, pts) for k in (10, 20, 40)]
    assert runs[0]["points"] > 500 and runs[0]["largest_shear_deg"] > 40.0
    for key in ("max_deg", "rms_deg"):
        values = [r[key] for r in runs]
        assert rate(values[0], values[1]) > 1.9 and rate(values[1], values[2]) > 1.9, values
    assert runs[-1]["max_deg"] < 0.02


def test_difference_map(tmp_path):
    pts = drape_map.cap_grid(R, (45.0, -45.0), R / 10.0, 60.0)
    net = goursat_drape.hemisphere(R, (45.0, -45.0), R / 200.0, 1.1 * R)
    bump = 0.5 * np.sin(pts[:, 0] / 3.0)
    field = np.degrees(net.shear_at(pts)) + bump
    on = pts[:, 1] < 15.0
    out = drape_map.shear_difference_map(R, pts, field, (45.0, -45.0), on, R / 40.0)
    exact = drape_map.differences(bump[on], 0.0)
    for key in ("continuum_vs_fishnet", "continuum_vs_goursat"):  # the drapes' own error at
        # a = R/40 is below 0.004° within 60° of the pole (0.0039° between them)
        assert abs(out[key]["max_deg"] - exact["max_deg"]) < 0.01, out[key]
        assert abs(out[key]["rms_deg"] - exact["rms_deg"]) < 0.01, out[key]
    assert out["fishnet_vs_goursat"]["max_deg"] < 0.01
    assert drape_map.summary(out)["points"] == on.sum()
    drape_map.draw_difference_map(tmp_path / "map.png", out, R)
    assert (tmp_path / "map.png").stat().st_size > 10_000
    with pytest.raises(ValueError, match="3 points, 2 shear angles"):
        drape_map.shear_difference_map(R, pts[:3], field[:2])
    with pytest.raises(ValueError, match="no point on the punch"):
        drape_map.shear_difference_map(R, pts, field, on=np.zeros(len(pts), bool))
