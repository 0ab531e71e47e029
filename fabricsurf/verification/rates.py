"""Observed convergence rates and Richardson extrapolation (the C0-IP and bias-extension rungs
of docs/verification.md)."""

from __future__ import annotations

import numpy as np


def rates(errors: list[float], hs: list[float]) -> list[float]:
    """Observed orders log(e_i/e_{i+1}) / log(h_i/h_{i+1})."""
    return [
        float(np.log(errors[i] / errors[i + 1]) / np.log(hs[i] / hs[i + 1]))
        for i in range(len(errors) - 1)
    ]


def richardson_summary(levels: list[int], values: list[float]) -> dict:
    """Observed rate and Richardson limit of a scalar computed on refinement levels.

    ``levels`` must grow by one constant ratio r (e.g. 2, 4, 8): with d_k = F_{k+1} − F_k,
    rate_k = log(|d_k| / |d_{k+1}|) / log r for each consecutive pair of differences (None
    where a difference is 0 or the two differences change sign: oscillation, no rate). The
    limit F_last + d_last / (r^rate − 1) and its error estimate |d_last| / (r^rate − 1) are
    given only when the last rate exists and is positive; otherwise None.
    """
    if len(levels) != len(values) or len(levels) < 2:
        raise ValueError(
            f"richardson_summary: need ≥ 2 levels with one value each, got "
            f"{len(levels)} levels and {len(values)} values"
        )
    ratios = {levels[i + 1] / levels[i] for i in range(len(levels) - 1)}
    if len(ratios) != 1 or min(ratios) <= 1:
        raise ValueError(f"richardson_summary: levels {levels} must grow by one constant ratio")
    r = ratios.pop()
    d = [values[i + 1] - values[i] for i in range(len(values) - 1)]
    rates = [
        float(np.log(abs(d[i] / d[i + 1])) / np.log(r)) if d[i] * d[i + 1] > 0 else None
        for i in range(len(d) - 1)
    ]
    last = rates[-1] if rates else None
    err = abs(d[-1]) / (r**last - 1) if last is not None and last > 0 else None
    return {
        "differences": [abs(x) for x in d],
        "rates": rates,
        "finest_error_estimate": err,
        "extrapolated": None if err is None else values[-1] + d[-1] / (r**last - 1),
    }
