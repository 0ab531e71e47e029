"""Observed rates and Richardson extrapolation
(fabricsurf.verification.rates.richardson_summary)."""

import pytest

from fabricsurf.verification.rates import richardson_summary


def test_exact_power_law():
    """F(n) = 3 + 2 n^-1.5 on levels 2, 4, 8, 16: rate 1.5 and limit 3 exactly."""
    levels = [2, 4, 8, 16]
    s = richardson_summary(levels, [3 + 2 * n**-1.5 for n in levels])
    assert s["rates"] == pytest.approx([1.5, 1.5])
    assert s["extrapolated"] == pytest.approx(3.0, abs=1e-12)
    assert s["finest_error_estimate"] == pytest.approx(2 * 16**-1.5)


def test_increasing_sequence_extrapolates_upwards():
    levels = [1, 3, 9]
    s = richardson_summary(levels, [5 - n**-2.0 for n in levels])
    assert s["rates"] == pytest.approx([2.0])
    assert s["extrapolated"] == pytest.approx(5.0, abs=1e-12)


def test_oscillation_and_stagnation_give_no_rate():
    assert richardson_summary([1, 2, 4], [1.0, 2.0, 1.5])["rates"] == [None]
    s = richardson_summary([1, 2, 4], [1.0, 1.0, 1.0])
    assert s["rates"] == [None] and s["extrapolated"] is None
    assert richardson_summary([1, 2], [1.0, 0.5])["finest_error_estimate"] is None


@pytest.mark.parametrize(
    "levels, values", [([2, 4, 6], [1, 2, 3]), ([2, 4], [1]), ([4, 2], [1, 2]), ([2], [1])]
)
def test_bad_levels_rejected(levels, values):
    with pytest.raises(ValueError, match="richardson_summary"):
        richardson_summary(levels, values)
