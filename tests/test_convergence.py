"""Rung 2: C0-IP convergence on manufactured solutions of the nonlinear fabric energy.

Theory for degree-2 C0 interior penalty on fourth-order problems (Brenner & Sung 2005;
Engel et al. 2002): broken-H2 error O(h), H1 and L2 errors O(h²) (for k = 2 duality gives no
extra order in L2). Asserted with a margin of 0.2 on the rate between the two finest meshes.
"""

import pytest
import ufl

from fabricsurf.model.terms import (
    FibreStretch,
    GeodesicBending,
    NormalBending,
    Shear,
    ShearGradient,
    StretchGradient,
    Twist,
)
from fabricsurf.verification.manufactured import manufactured_solve
from fabricsurf.verification.rates import rates

THEORY = {"L2": 2.0, "H1": 2.0, "H2": 1.0}
MARGIN = 0.2
MESHES = (4, 8, 16)


def in_plane_model():
    return [FibreStretch(k_l=1.0, k_m=2.0), Shear(k_s=1.0), GeodesicBending(A_g=1.0),
            StretchGradient(A_s=0.5), ShearGradient(A_Gamma=0.7)]


def u_2d(x):
    return 0.1 * ufl.as_vector((ufl.sin(2 * x[0] + x[1]), ufl.cos(x[0] - 2 * x[1])))


def u_3d(x):
    return ufl.as_vector((0.1 * ufl.sin(2 * x[0] + x[1]), 0.1 * ufl.cos(x[0] - 2 * x[1]),
                          0.2 * ufl.sin(ufl.pi * x[0]) * ufl.sin(ufl.pi * x[1])))


CASES = {
    2: (in_plane_model, u_2d),
    3: (lambda: in_plane_model() + [NormalBending(k_b=1.0), Twist(k_t=0.8)], u_3d),
}


@pytest.mark.parametrize("d", [2, 3])
def test_manufactured_convergence_rates(d):
    model_fn, ue = CASES[d]
    model = model_fn()
    errors = [manufactured_solve(model, ue, n, d)[0] for n in MESHES]
    hs = [1.0 / n for n in MESHES]
    for norm, expected in THEORY.items():
        r = rates([e[norm] for e in errors], hs)
        print(f"d = {d}: {norm} errors {[e[norm] for e in errors]}, rates {r}")
        assert r[-1] > expected - MARGIN, f"{norm} rate {r[-1]:.2f} below {expected} - {MARGIN}"


def test_penalty_insensitivity():
    """α ∈ [4, 64] changes the L2/H1 errors by < 25 % of those at α = 8, while one refinement
    changes them by a factor 4: the results are governed by h, not by the penalty."""
    model = in_plane_model()
    ref, _ = manufactured_solve(model, u_2d, 8, 2, penalty=8.0)
    for alpha in (4.0, 16.0, 64.0):
        e, _ = manufactured_solve(model, u_2d, 8, 2, penalty=alpha)
        for norm in ("L2", "H1"):
            ratio = e[norm] / ref[norm]
            print(f"alpha = {alpha}: {norm} error ratio to alpha = 8: {ratio:.3f}")
            assert 0.75 < ratio < 1.25
