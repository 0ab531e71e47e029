"""Bias extension (Barchiesi et al. 2020): the bi-pantographic energy of eq. (2) (with its
regularisation beyond the limit stretch), and the continuum-versus-lattice study of the demo
(``fabricsurf.studies.bias_study``) on a coarse run (tolerances from measured differences).

Runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``.
"""

import math
from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.model.kinematics import Kinematics, fibre_directions
from fabricsurf.model.materials import (
    PantographBending,
    bipantographic,
    bipantographic_density_numpy,
)
from fabricsurf.studies.bias_comparison import ideal_centre_shear_deg
from fabricsurf.studies.bias_study import BiasStudySettings, run_bias_study

COMM = MPI.COMM_WORLD


# ------------------------------------------------------------- eq. (2) energy, exact placements
@pytest.fixture(scope="module")
def unit_square():
    return dmesh.create_unit_square(COMM, 6, 6)


def energy(msh, r, angles=(0.0, 90.0), model=None):
    """∫ W over the unit square for a placement r given as a UFL expression of X."""
    model = model or bipantographic()
    for t in model:
        t.bind(msh)
    L, M = fibre_directions(*angles)
    kin = Kinematics(ufl.grad(r), ufl.grad(ufl.grad(r)), L, M)
    W = sum(t.density(kin) for t in model)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 10})
    return COMM.allreduce(fem.assemble_scalar(fem.form(W * dx)), op=MPI.SUM)


def gauss(f, n=40):
    """∫_0^1 f by Gauss–Legendre."""
    s, w = np.polynomial.legendre.leggauss(n)
    return float(np.sum(w * f(0.5 * (s + 1))) / 2)


def test_bipantographic_reference_state_is_stress_free(unit_square):
    X = ufl.SpatialCoordinate(unit_square)
    assert abs(energy(unit_square, ufl.as_vector([X[0], X[1]]), (45.0, -45.0))) < 1e-14
    # reference moduli at ρ = 1 (module docstring): 17.97 and 418.3 N·mm
    a_t, a_r = PantographBending().reference_moduli()
    assert a_t == pytest.approx(297000 * 0.25 / 4132.5, rel=1e-12)
    assert a_r == pytest.approx(297000 * 0.75 / (0.25 * 2130), rel=1e-12)


@pytest.mark.parametrize("angles", [(0.0, 90.0), (45.0, -45.0)])
def test_bipantographic_homogeneous_stretch(unit_square, angles):
    """F = diag(1.05, 0.97): gradient terms vanish; first line of eq. (2), printed acos form."""
    X = ufl.SpatialCoordinate(unit_square)
    a, b = 1.05, 0.97
    got = energy(unit_square, ufl.as_vector([a * X[0], b * X[1]]), angles)
    if angles == (0.0, 90.0):
        rl, rm = a, b
    else:
        rl = rm = math.sqrt((a * a + b * b) / 2)
    expected = sum(bipantographic_density_numpy(r, 0.0, 0.0) for r in (rl, rm))
    assert expected > 1e-5
    assert got == pytest.approx(expected, rel=1e-10)


def test_bipantographic_bending_and_stretch_gradient(unit_square):
    """Placements with a known ∂θ/∂L (arc of radius R) and ∂ρ/∂L (quadratic stretch)."""
    X = ufl.SpatialCoordinate(unit_square)
    R = 4.0
    arc = ufl.as_vector([(R - X[1]) * ufl.sin(X[0] / R), R - (R - X[1]) * ufl.cos(X[0] / R)])
    # L = e_x: ρ_L = (R − Y)/R, ∂θ_L/∂L = 1/R, ∂ρ_L/∂L = 0; M = e_y: ρ_M = 1, no gradients
    exp_arc = gauss(lambda y: bipantographic_density_numpy((R - y) / R, 1 / R, 0.0)
                    + bipantographic_density_numpy(1.0, 0.0, 0.0))
    assert energy(unit_square, arc) == pytest.approx(exp_arc, rel=1e-8)
    c = 0.03
    quad = ufl.as_vector([X[0] + c * X[0] ** 2, X[1]])
    # ρ_L = 1 + 2cX, ∂ρ_L/∂L = 2c, θ_L = 0
    exp_quad = gauss(lambda x: bipantographic_density_numpy(1 + 2 * c * x, 0.0, 2 * c))
    assert energy(unit_square, quad) == pytest.approx(exp_quad, rel=1e-8)


def test_regularised_energy_continues_eq2_beyond_the_limit_stretch(unit_square):
    """limit_stretch ρ_r = 1.02, F = diag(1.05, 0.97), fibres 0/90: λ = 1.05 lies beyond ρ_r,
    where the pivot energy is the second-order Taylor polynomial of eq. (2) at ρ_r (value,
    slope and curvature from finite differences of the printed acos form), μ = 0.97 below,
    where it is eq. (2) itself; the gradient terms vanish. ρ = 1.2 (ρ cos γ = 1.04, outside
    eq. 2's domain) gives a finite energy."""
    X = ufl.SpatialCoordinate(unit_square)
    model = bipantographic(limit_stretch=1.02)
    got = energy(unit_square, ufl.as_vector([1.05 * X[0], 0.97 * X[1]]), model=model)
    r, h, d = 1.02, 1e-4, 0.03
    W = [float(bipantographic_density_numpy(r + k * h, 0.0, 0.0)) for k in (-1, 0, 1)]
    taylor = W[1] + (W[2] - W[0]) / (2 * h) * d + 0.5 * (W[2] - 2 * W[1] + W[0]) / h**2 * d**2
    expected = taylor + float(bipantographic_density_numpy(0.97, 0.0, 0.0))
    assert got == pytest.approx(expected, rel=1e-6)
    far = energy(unit_square, ufl.as_vector([1.2 * X[0], X[1]]), model=model)
    assert math.isfinite(far) and far > got
    with pytest.raises(ValueError, match="cos γ < 1"):
        bipantographic(limit_stretch=1.2)


# --------------------------------------------------------------------- the study, quick run
@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = COMM.bcast(str(tmp_path_factory.mktemp("bias")) if COMM.rank == 0 else None, root=0)
    summary, _ = run_bias_study(BiasStudySettings(out=Path(out)).quick(), COMM)
    return summary, Path(out)


def test_study_outputs(quick_run):
    summary, out = quick_run
    keys = {"force_rel_diff", "angle_A_max_diff_deg", "angle_B_max_diff_deg",
            "position_rms_diff", "curves"}
    bip = {"force_ratio_continuum_to_lattice", "max_stretch"}
    extra = {"hencky": set(), "bipantographic": bip, "bipantographic_half": bip,
             "bipantographic_identified": bip | {"clamp_offset"}}
    for name, more in extra.items():
        assert set(summary[name]) == keys | more
        assert len(summary[name]["curves"]["ubar"]) == 4
    assert "bipantographic_range" not in summary  # quick: no whole-range study
    if COMM.rank == 0:
        for f in ("hencky/bias.xdmf", "bipantographic/bias.xdmf",
                  "bipantographic_identified/bias.xdmf"):
            assert (out / f).exists(), f


def test_continuum_vs_hencky_coarse(quick_run):
    """h = 8 mm, ε = 6.01 mm, ū ≤ 18.7 mm. Measured (1 and 2 ranks): force 1.4 %, γ_A 0.08°,
    γ_B 0.42°, position rms 0.12 mm. Tolerances: twice these, rounded up; the differences are
    the O(ε) clamp offset of the lattice (two held layers 4.25 mm wide vs a clamp line), the
    bending identification exact only at λ = 1, and the P2/C0-IP error at h = 8 mm."""
    hk = quick_run[0]["hencky"]
    assert hk["force_rel_diff"] < 0.03
    assert hk["angle_A_max_diff_deg"] < 0.3
    assert hk["angle_B_max_diff_deg"] < 1.0
    assert hk["position_rms_diff"] < 0.25


def test_three_zones(quick_run):
    """Near-rigid clamp triangle, half-sheared side zone, fully sheared centre (module docstring
    of the demo): measured γ = 1.8°, 13.6°, 23.1° at ū = 18.7 mm (ratios 0.08 and 0.59 of γ_B).
    The ideal inextensible-net value γ_C = 38.7° is not reached: fibres stretch by up to 8.6 %
    (k_l/k_s = 60) and bending smooths the zone boundaries, so only an upper bound is checked."""
    summary = quick_run[0]
    z = summary["three_zones"]["check"]
    assert z["ubar"] == pytest.approx(18.7)
    assert z["clamp_triangle"] < 0.15 * z["centre_B"]
    assert 0.45 * z["centre_B"] < z["half_sheared"] < 0.7 * z["centre_B"]
    assert z["centre_B"] < z["ideal_centre_deg"] == pytest.approx(ideal_centre_shear_deg(18.7))
    # γ_B ≈ 2 γ_A at A, the apex of the clamp triangle where the half-sheared zones meet
    c = summary["hencky"]["curves"]
    assert 1.2 < c["angle_B_continuum_deg"][-1] / c["angle_A_continuum_deg"][-1] < 2.0


def test_force_convergence(quick_run):
    """Grip force at ū = 18.7 mm on nested edge-graded meshes, square side 8.5, 4.25, 2.1 mm
    (min 3.4, 1.7, 0.85 mm at the edges). Measured (1 and 2 ranks): 45.7033, 45.4741,
    45.3653 N, differences 0.229, 0.109 N, rate 1.07 (level 16 adds 45.3249 N, rate 1.43:
    benchmarks/bias_convergence.py). The gradient-clamp boundary layer (√(A_g/k_l) ≈ 1.2 mm)
    and the clamp corners limit the rate below the smooth-solution value; on uniform meshes
    coarser than the layer the differences were not monotone at all."""
    conv = quick_run[0]["force_convergence"]
    d = conv["differences"]
    assert conv["levels"] == [2, 4, 8]
    assert d[1] < 0.6 * d[0]
    assert 0.8 < conv["rates"][0] < 2.5
    assert abs(conv["force"][-1] - conv["extrapolated_force"]) < 0.005 * conv["force"][-1]


def test_bipantographic_factor_explained(quick_run):
    """Table 3 continuum vs lattice: force ratio 1.9–2.1 (h = 8 mm) while the kinematics agree.
    The numerical homogenisation of the lattice gives K_S and a_θ(1) at 0.43 and 0.53 × Table
    3's; with them the ratio is 0.75–0.81, and the continuum on the full length (clamp lines)
    and on the free length between the 17 mm held lattice strips brackets the lattice force
    (0.75× and 1.38× at ū = 4.7 mm)."""
    s = quick_run[0]
    ident = s["settings"]["bipantographic"]["identified"]
    assert ident["K_S"] == pytest.approx(0.01446, rel=1e-3)
    assert ident["a_theta"] == pytest.approx(9.557, rel=1e-3)
    r_t3 = s["bipantographic"]["force_ratio_continuum_to_lattice"]
    r_id = s["bipantographic_identified"]["force_ratio_continuum_to_lattice"]
    assert min(r_t3) > 1.5
    assert max(abs(r - 1) for r in r_id) < 0.3
    br = s["bipantographic_identified"]["clamp_offset"]
    full = s["bipantographic_identified"]["curves"]["force_continuum"]
    assert all(a < b < c for a, b, c in zip(full, br["force_lattice"], br["force_free_length"]))


def test_factor_two_is_the_half_convention(quick_run):
    """Eq. (2) read as ½·(printed density), like the springs' ½k(·)², is the Table 3 energy
    with all three moduli halved (a_θ, a_ρ are homogeneous of degree 1 in K_E, K_F): under
    displacement control the kinematics are identical and the force halves exactly, and the
    ratio to the Table 3 micro lattice becomes 0.97–1.13 (measured, h = 8 mm, ū = 4.7–18.7 mm;
    Table 3 as printed: 1.93–2.27) instead of ≈ 2; it grows with ū (the ρ-dependence of eq. 2's
    coefficients, which the lattice does not share, docs/network.md)."""
    t3, half = quick_run[0]["bipantographic"], quick_run[0]["bipantographic_half"]
    c3, ch = t3["curves"], half["curves"]
    assert np.allclose(ch["force_continuum"], 0.5 * np.array(c3["force_continuum"]), rtol=1e-6)
    assert np.allclose(ch["angle_B_continuum_deg"], c3["angle_B_continuum_deg"], atol=1e-6)
    assert all(0.95 < r < 1.15 for r in half["force_ratio_continuum_to_lattice"])
