"""The significance rule of a nested effect (fabricsurf/inverse/diagnosis/significance.py).

The cases are those met on real data (docs/diagnosis.md, "Significant"): each of the two tests
alone lets through a case the other stops.
"""

import pytest

from fabricsurf.inverse.diagnosis import significance as sg


@pytest.mark.parametrize("n", [30, 300, 3000])
def test_singular_refit_is_not_significant(n):
    """The real fabric's inert yarn_slip: χ² 72.517 → 72.499 with one added modulus and a Wald
    p of 10⁻³⁶ (a nearly singular covariance). F = Δχ²/max(1, χ²/ν) ≤ 0.018 lies far below
    F₀.₉₉₉(1, ν) ≥ 10.8 for any ν: the χ² decrease is nothing; the Wald test alone accepted it."""
    base, new, p_base = 72.517, 72.499, 2
    assert sg.f_statistic(base, p_base, new, p_base + 1, n) <= 0.018 * (1 + 1e-9)
    assert not sg.significant(base, p_base, new, p_base + 1, n, wald_p=1e-36)
    # the Wald part on its own (the former rule) passes it: the F-test is what stops it
    assert 1e-36 < 1.0 - sg.LEVEL


def test_clear_effect_is_significant():
    """The same diagnosis's crossover_friction: χ² 532.93 → 72.517, a Wald p far below 10⁻³
    (F = 460.4/1 against a residual variance of 1 when χ²/ν ≤ 1: far beyond F₀.₉₉₉)."""
    n, p_base = 90, 2
    assert sg.significant(532.93, p_base, 72.517, p_base + 1, n, wald_p=1e-9)


def test_wald_still_decides_on_correlated_residuals():
    """A large χ² decrease whose modulus is not distinguishable from zero on the cluster-robust
    covariance (p = 0.0088, the second round's shear_locking refit) is not significant, though the
    F-test on independent residuals passes (Δχ² = 100 with χ²/ν < 1)."""
    n, p_base = 200, 3
    assert sg.f_test(300.0, p_base, 200.0, p_base + 1, n)
    assert not sg.significant(300.0, p_base, 200.0, p_base + 1, n, wald_p=0.0088)


def test_no_decrease_is_never_significant():
    """χ² must decrease whatever the tests say."""
    assert not sg.significant(50.0, 2, 50.0, 3, 100, wald_p=0.0)
    assert not sg.significant(50.0, 2, 51.0, 3, 100)


def test_woven_full_run_second_round():
    """The woven demo's full run as stored in its diagnosis.json (35 points, 2 moduli after
    crossover_friction): the refits of the second round, sorted by χ², are shear_locking
    (k = 2, χ² 48.667, Wald p 0.0088) and yarn_slip (k = 1, χ² 72.499, Wald p 0). shear_locking
    fails both tests: F = 11.93/(48.667/31) = 7.6 < F₀.₉₉₉(2, 31) = 8.7; yarn_slip has
    F = 0.008 < F₀.₉₉₉(1, 32) = 13.1. Nothing is added; the former rule added yarn_slip."""
    n, p, base = 35, 2, 72.51748
    assert 7.5 < sg.f_statistic(base, p, 48.66674, p + 2, n) < 7.7
    assert not sg.f_test(base, p, 48.66674, p + 2, n)
    assert not sg.significant(base, p, 48.66674, p + 2, n, wald_p=0.0088420)
    assert sg.f_statistic(base, p, 72.49899, p + 1, n) < 0.01
    assert not sg.significant(base, p, 72.49899, p + 1, n, wald_p=0.0)
