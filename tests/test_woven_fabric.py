"""Woven fabric: hidden shear locking is found, the Cao et al. 2008 curve is refitted, and the
benchmark formulas are exact.

* Lattice data: the Hencky lattice with nonlinear shear springs (k_sh4, k_sh6) on a 48 × 24 mm
  specimen, sheared to a zone-C angle of ~40° (where k₄γ³ ≈ 1.8 k_s γ), field + force, noise
  0.01 mm / 0.02 N. From a fibre_stretch + shear baseline the diagnosis must rank
  shear_locking first and add it; the linear k_s, which acts at every angle, must then be the
  lattice's within 10 % (the rest is the model-form error of a lattice with sharp zone
  boundaries against P2 elements, which keeps the refit above the noise level).
* The Cao curve itself is compared, fitted and diagnosed in demos/demo_woven_fabric.py (run by
  tests/test_demos.py); its params round trip is in tests/test_experiments.py.
* Eq. 18 applied to the ideal-kinematics force of a shear response returns τ/cos γ (to the
  second-order error of its interpolation).
"""

import numpy as np

from fabricsurf.experiments import three_zone as tz
from fabricsurf.inverse.diagnosis.diagnose import diagnose
from fabricsurf.inverse.synthetic import generate as sy
from fabricsurf.model.terms import Shear, ShearLocking

LATTICE = {"k_l": 30.0, "k_s": 0.5, "A_g": 0.0, "k4": 2.0, "k6": 2.0}


def test_eq18_inverts_ideal_kinematics():
    """Eq. 18 of the ideal-kinematics force returns τ/cos γ up to the linear interpolation of
    F_sh(γ/2): second order in the angle step (4× smaller per halving; ≥ 8× over two)."""
    lock = ShearLocking(k4=0.01, k6=0.005)
    params = [Shear(k_s=0.02), lock]
    err = []
    for n in (80, 320):
        g = np.radians(np.linspace(80.0 / n, 80.0, n))
        d = tz.displacement_at_angle(g, 230.0, 115.0)
        assert np.allclose(tz.zone_c_shear_angle(d, 230.0, 115.0), g, rtol=1e-12)
        F = tz.kinematic_force(d, 230.0, 115.0, params)
        _, fsh = tz.normalised_shear_force(d, F, 230.0, 115.0)
        err.append(np.max(np.abs(fsh / tz.constitutive_shear_force(g, params) - 1.0)))
    assert err[0] < 2e-4 and err[1] < err[0] / 8.0, err
    gl = tz.locking_angle(params)
    assert np.isclose(tz.shear_moment(gl, [lock]), 0.02 * gl, rtol=1e-12)


def test_hidden_locking_in_lattice_data_is_diagnosed():
    exp = sy.template(48.0, 24.0, [1.7, 3.4, 5.1, 6.8], np.zeros((0, 2)), name="locking")
    sy.lattice_data(exp, 0.8, every=6, **LATTICE)
    sy.add_noise(exp, 0.01, 0.02, 7)
    assert np.degrees(tz.zone_c_shear_angle(6.8, 48.0, 24.0)) > 40.0
    d = diagnose(
        exp, ["fibre_stretch", "shear"], h=4.0, confirm=1, max_effects=1, check_discretisation=False
    )
    print(
        d.base_fit.misfit["combined"],
        [(r["effect"], r["score"], r["refit_misfit"]) for r in d.ranking],
        d.final_fit.params(),
    )
    assert d.verdict == "shear_locking" == d.ranking[0]["effect"]
    assert d.ranking[0]["significant"]
    assert abs(d.final_fit.params()["shear"]["k_s"] / LATTICE["k_s"] - 1.0) < 0.10
    assert d.final_fit.chi2 < d.base_fit.chi2
