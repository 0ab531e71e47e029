"""The hyperbolic paraboloid of Steigmann & dell'Isola 2015 §5 (the equations are in
fabricsurf/verification/hypar.py; docs/verification.md).

Asserted on 1 and 2 ranks: Dirichlet case at solver tolerance; natural case recovered with the
error of the traction quadrature (Gauss, exact to degree 5: O(h^6)) until round-off; corner
forces from the computed double force equal A_Γ a (eq. 94); with k̄ ≠ A_Γ the same loads give a
different surface.
"""

import dataclasses

import numpy as np
import pytest

from fabricsurf.geometry.specimen import square
from fabricsurf.verification.hypar import (
    Hypar,
    computed_corner_forces,
    l2_error,
    solve_dirichlet,
    solve_natural,
)
from fabricsurf.verification.rates import rates

SIZES = (0.5, 0.35, 0.25)


@pytest.fixture(scope="module")
def natural():
    hyp = Hypar()
    problems = [solve_natural(square(1.0, h), hyp) for h in SIZES]
    return hyp, problems, [l2_error(p, hyp) for p in problems]


def test_dirichlet_exact_to_solver_tolerance():
    _, err = solve_dirichlet(square(1.0, 0.25), Hypar())
    assert err < 1e-10


def test_natural_case_recovers_hypar(natural):
    _, _, errors = natural
    r = rates(errors, list(SIZES))
    print("natural L2 errors", errors, "rates", r)
    assert max(errors) < 1e-8
    assert r[0] > 4.0  # quadrature error O(h^6) above the round-off floor


def test_corner_forces_equal_A_Gamma_a(natural):
    hyp, problems, _ = natural
    for c, f in computed_corner_forces(problems[-1]).items():
        exact = hyp.corner_force(c)
        assert np.linalg.norm(f - exact) < 1e-6 * np.linalg.norm(exact), (c, f, exact)


def test_mismatched_twist_modulus_departs(natural):
    _, _, errors = natural
    bad = dataclasses.replace(Hypar(), k_t=2.0)
    departure = l2_error(solve_natural(square(1.0, SIZES[-1]), bad), bad)
    print("departure", departure)
    assert departure > 1e-2 and departure > 1e4 * max(errors)
