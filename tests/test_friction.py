"""Crossover friction (``crossover_friction``, docs/vocabulary.md): the elastic equivalent of the
inter-yarn friction that gives woven-fabric shear curves their initial knee.

* The density is τ_f γ_f ln cosh(γ/γ_f): its shear stress τ_f tanh(γ/γ_f) and, at the
  reference state, its tangent τ_f/γ_f (the |γ| of the stable form must not lose it).
* Under the ideal three-zone kinematics of the bias test (exact inextensibility on the
  fibre-aligned mesh, whose space holds the pin-jointed-net solution) the grip force equals
  the power balance of Cao et al. 2008 eq. 18 with τ = k_s γ + τ_f tanh(γ/γ_f).
* Bad shape angles are refused by name.
* Friction hidden in Hencky-lattice data (friction springs at the crossings) is diagnosed as
  such in both fibre regimes.
"""

import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.experiments.bias_extension import BiasExtension
from fabricsurf.experiments.three_zone import kinematic_force
from fabricsurf.inverse.contract.checks import unloading_warning
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model import kinematics as kn
from fabricsurf.model.kinematics import Kinematics
from fabricsurf.model.terms import CrossoverFriction, FibreStretch, Shear

TAU_F, GAMMA_F = 0.004, math.radians(1.0)


def _density_and_tangent(gamma: float) -> tuple[float, float, float]:
    """γ, W and d²W/dγ² of the friction term at a homogeneous simple shear of the ±45° net
    that closes the fibre angle by ``gamma`` (UFL, evaluated at a cell midpoint)."""
    msh = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    sc = fem.Constant(msh, 0.0)
    s = ufl.variable(sc)
    x = ufl.SpatialCoordinate(msh)
    L, M = kn.fibre_directions(45.0, -45.0)
    # pure shear along the bisectors: F = [[a, 0], [0, 1/a]] turns ±45° fibres symmetrically
    a = ufl.exp(s)
    F = ufl.grad(ufl.as_vector([a * x[0], x[1] / a]))
    kin = Kinematics(F, None, L, M)
    friction = CrossoverFriction(tau_f=TAU_F, gamma_f=GAMMA_F)
    W = friction.density(kin, friction.values())
    dW = ufl.diff(W, s) / ufl.diff(kin.gamma, s)
    d2 = ufl.diff(ufl.diff(W, s), s) / ufl.diff(kin.gamma, s) ** 2
    # a half-angle closing tan((π/2 − γ)/2) = 1/a² gives s for the wanted γ
    sc.value = 0.5 * math.log(1.0 / math.tan(0.5 * (0.5 * math.pi - gamma)))
    e = fem.Expression(ufl.as_vector([kin.gamma, W, dW, d2]), np.array([[1 / 3, 1 / 3]]))
    g, w, dw, dd = e.eval(np.array([0], dtype=np.int32))[0]
    return g, w, dw, dd


@pytest.mark.parametrize("gamma", [0.0, 0.3 * GAMMA_F, 5 * GAMMA_F, 0.6])
def test_density_stress_and_reference_tangent(gamma):
    g, w, dw, dd = _density_and_tangent(gamma)
    assert abs(g - gamma) < 1e-12
    assert abs(w - TAU_F * GAMMA_F * math.log(math.cosh(gamma / GAMMA_F))) < 1e-15
    assert abs(dw - TAU_F * math.tanh(gamma / GAMMA_F)) < 1e-12 * max(1.0, TAU_F)
    if gamma == 0.0:  # dW/dγ = τ_f tanh(γ/γ_f) has slope τ_f/γ_f at γ = 0
        assert abs(dd - TAU_F / GAMMA_F) < 1e-9 * TAU_F / GAMMA_F


@pytest.mark.parametrize("bad", [0.0, -0.01, math.inf, 1.0, "1"])
def test_bad_shape_angle_is_refused(bad):
    with pytest.raises(ValueError, match="gamma_f"):
        CrossoverFriction(tau_f=1.0, gamma_f=bad)


def test_bias_force_is_the_three_zone_force_with_friction():
    """230 × 115 mm, ±45°, position clamps, h = W/10 on the default (fibre-aligned) mesh with
    exact inextensibility: the force follows eq. 18 with the friction stress within 1e-3
    (the same discretisation is within 1e-4 for linear shear, tests/test_locking.py)."""
    H, W, k_s = 230.0, 115.0, 0.02
    model = [FibreStretch(inextensible=True), Shear(k_s=k_s), CrossoverFriction(tau_f=TAU_F)]
    res = BiasExtension(model, length=H, width=W, h=W / 10, clamp="position").run(30.0, 3)
    ratio = np.array(res.force) / kinematic_force(np.array(res.ubar), H, W, model)
    friction_share = 1.0 - kinematic_force(np.array(res.ubar), H, W, [Shear(k_s=k_s)]) / np.array(
        res.force
    )
    print(ratio, friction_share)
    assert np.all(friction_share > 0.1), "friction must carry a sizeable part of the force"
    assert np.all(np.abs(ratio - 1.0) < 1e-3), ratio


def _hidden_friction(regime: str, tau_f: float):
    """Hencky-lattice data with friction springs at the crossings (tau_f hidden from a
    fibre_stretch + shear baseline), field + force with noise; the path starts inside the knee
    (a zone-C angle of about 1.5°) and goes to 20–40°. Soft: k_l/k_s = 60 on a 0.8 mm lattice;
    stiff: k_l/k_s = 2500 on a 1.6 mm lattice (the regime of real fabrics)."""
    if regime == "soft":
        exp = sy.template(48.0, 24.0, [0.6, 1.7, 3.4, 5.1, 6.8], np.zeros((0, 2)), name="knee")
        sy.lattice_data(exp, 0.8, every=6, k_l=30.0, k_s=0.5, A_g=0.0, tau_f=tau_f)
        return sy.add_noise(exp, 0.01, 0.02, 7), 4.0
    exp = sy.template(48.0, 24.0, [0.3, 1.0, 2.5, 4.0, 5.8], np.zeros((0, 2)), name="knee")
    sy.lattice_data(exp, 1.6, every=2, k_l=1000.0, k_s=0.4, A_g=0.0, tau_f=tau_f)
    return sy.add_noise(exp, 0.02, 0.02, 7), 3.0


@pytest.mark.parametrize("regime, tau_f", [("soft", 0.05), ("stiff", 0.04)])
def test_hidden_friction_in_lattice_data_is_diagnosed(regime, tau_f):
    """Every in-plane effect is a candidate (shear_locking, the other shear-law term, among
    them): the diagnosis names crossover_friction, by the significance rule of
    docs/diagnosis.md, and its refit recovers the lattice's τ_f within 10 % (the rest is the
    lattice-continuum form error that keeps the refit above the noise)."""
    exp, h = _hidden_friction(regime, tau_f)
    d = diagnose(
        exp, ["fibre_stretch", "shear"], h=h, confirm=1, max_effects=1, check_discretisation=False
    )
    print(d.outcome(), [(r["effect"], r["score"], r["refit_misfit"]) for r in d.ranking])
    assert d.verdict == "crossover_friction" == d.ranking[0]["effect"]
    assert d.ranking[0]["significant"] and d.final_fit.chi2 < d.base_fit.chi2
    assert abs(d.final_fit.params()["crossover_friction"]["tau_f"] / tau_f - 1.0) < 0.10


def test_unloading_path_is_warned_about_with_friction_only():
    """Friction dissipates: a load path that turns back is named (experiment, term, step) when
    the model holds crossover_friction, and not otherwise, nor for a monotonic path."""
    friction = [Shear(k_s=1.0), CrossoverFriction(tau_f=1.0)]
    back = sy.template(48.0, 24.0, [1.0, 2.0, 3.0, 2.5], np.zeros((0, 2)), name="cyclic")
    msg = unloading_warning(back, friction)
    assert msg and "cyclic" in msg and "crossover_friction" in msg and "step 4" in msg
    assert unloading_warning(back, [Shear(k_s=1.0)]) is None
    mono = sy.template(48.0, 24.0, [1.0, 2.0, 2.0, 3.0], np.zeros((0, 2)), name="monotonic")
    assert unloading_warning(mono, friction) is None
