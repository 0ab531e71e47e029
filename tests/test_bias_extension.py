"""Bias extension (seed 000): the bi-pantographic energy of eq. (2), and the demo's
continuum-versus-lattice comparison on a coarse run (tolerances from measured differences).

Runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``.
"""

import importlib.util
import json
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

COMM = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parents[1]


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


# ------------------------------------------------------------------------- the demo, quick run
def _load_demo():
    spec = importlib.util.spec_from_file_location(
        "demo_bias_extension", ROOT / "demos" / "demo_bias_extension.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = COMM.bcast(str(tmp_path_factory.mktemp("bias")) if COMM.rank == 0 else None, root=0)
    demo = _load_demo()
    summary = demo.main(["--quick", "--out", out])
    return demo, summary, Path(out)


def test_demo_outputs(quick_run):
    _, summary, out = quick_run
    keys = {"force_rel_diff", "angle_A_max_diff_deg", "angle_B_max_diff_deg",
            "position_rms_diff", "curves"}
    extra = {"hencky": set(), "bipantographic": {"force_ratio_continuum_to_lattice"},
             "bipantographic_identified": {"force_ratio_continuum_to_lattice", "clamp_offset"}}
    for name, more in extra.items():
        assert set(summary[name]) == keys | more
        assert len(summary[name]["curves"]["ubar"]) == 4
    if COMM.rank == 0:
        on_disk = json.loads((out / "summary.json").read_text())
        assert on_disk["hencky"]["force_rel_diff"] == summary["hencky"]["force_rel_diff"]
        for f in ("curves.png", "deformed_hencky.png", "rho_y_hencky.png", "zones_hencky.png",
                  "deformed_bipantographic.png", "rho_y_bipantographic.png",
                  "force_convergence.png", "hencky/bias.xdmf", "bipantographic/bias.xdmf",
                  "bipantographic_identified/bias.xdmf"):
            assert (out / f).exists(), f


def test_continuum_vs_hencky_coarse(quick_run):
    """h = 8 mm, ε = 6.01 mm, ū ≤ 18.7 mm. Measured (1 and 2 ranks): force 1.4 %, γ_A 0.08°,
    γ_B 0.42°, position rms 0.12 mm. Tolerances: twice these, rounded up; the differences are
    the O(ε) clamp offset of the lattice (two held layers 4.25 mm wide vs a clamp line), the
    bending identification exact only at λ = 1, and the P2/C0-IP error at h = 8 mm."""
    hk = quick_run[1]["hencky"]
    assert hk["force_rel_diff"] < 0.03
    assert hk["angle_A_max_diff_deg"] < 0.3
    assert hk["angle_B_max_diff_deg"] < 1.0
    assert hk["position_rms_diff"] < 0.25


def test_three_zones(quick_run):
    """Near-rigid clamp triangle, half-sheared side zone, fully sheared centre (module docstring
    of the demo): measured γ = 1.8°, 13.6°, 23.1° at ū = 18.7 mm (ratios 0.08 and 0.59 of γ_B).
    The ideal inextensible-net value γ_C = 38.7° is not reached: fibres stretch by up to 8.6 %
    (k_l/k_s = 60) and bending smooths the zone boundaries, so only an upper bound is checked."""
    demo, summary, _ = quick_run
    z = summary["three_zones"]["check"]
    assert z["ubar"] == pytest.approx(18.7)
    assert z["clamp_triangle"] < 0.15 * z["centre_B"]
    assert 0.45 * z["centre_B"] < z["half_sheared"] < 0.7 * z["centre_B"]
    assert z["centre_B"] < z["ideal_centre_deg"] == pytest.approx(demo.ideal_centre_shear_deg(18.7))
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
    conv = quick_run[1]["force_convergence"]
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
    s = quick_run[1]
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
