"""Woven fabric in the bias-extension test (Cao et al. 2008): the ranges no elastic term can
follow and the moduli covariance of the benchmark. The three-zone kinematics and normalisation
(eqs. 13 and 18) are in :mod:`fabricsurf.experiments.three_zone`.
"""

from __future__ import annotations

import numpy as np

from fabricsurf.experiments.three_zone import zone_c_shear_angle

KNEE = "initial knee (friction at the crossovers: no elastic term starts with a finite force)"
BEYOND = "beyond locking (yarn slip, wrinkling: softer than any elastic shear response)"
MIDDLE = "intermediate range"


def force_errors(model, measured) -> dict:
    """RMS and max |model − measured| in N and in % of the largest measured force."""
    e = np.asarray(model, float) - np.asarray(measured, float)
    fmax = float(np.max(np.abs(measured)))
    rms, mx = float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(e)))
    return {"rms_N": rms, "max_N": mx, "rms_pct": 100 * rms / fmax, "max_pct": 100 * mx / fmax}


def unexplained_ranges(d, error, measured, s_F: float, length: float, width: float
                       ) -> list[dict]:
    """Displacement ranges where |force error| exceeds three noise levels (the criterion of
    :func:`fabricsurf.inverse.fitting.report.where_unexplained`), each named. A range is the initial
    knee if every point before it has a measured force below three noise levels (there the
    data cannot tell any response from zero, so it is where the curve first departs); a range
    reaching the last point is beyond locking; anything else is an intermediate range."""
    d, error, measured = (np.asarray(a, float) for a in (d, error, measured))
    bad = np.abs(error) > 3.0 * s_F
    out, k = [], 0
    while k < len(d):
        if not bad[k]:
            k += 1
            continue
        j = k
        while j + 1 < len(d) and bad[j + 1]:
            j += 1
        quiet_before = bool(np.all(np.abs(measured[:k]) < 3.0 * s_F))
        kind = KNEE if quiet_before else BEYOND if j == len(d) - 1 else MIDDLE
        g = np.degrees(zone_c_shear_angle(d[[k, j]], length, width))
        out.append({"kind": kind, "displacement_mm": [float(d[k]), float(d[j])],
                    "zone_c_angle_deg": [float(g[0]), float(g[1])],
                    "points": int(j - k + 1),
                    "max_abs_error_N": float(np.max(np.abs(error[k:j + 1]))),
                    "sign": "model above data" if error[k:j + 1].mean() > 0 else
                    "model below data"})
        k = j + 1
    return out


def moduli_covariance(fm, free: list[int]) -> tuple[object, np.ndarray]:
    """One forward run of ``fm`` at its current moduli with sensitivities: (prediction,
    covariance of the moduli ``free``), Cov(p) = P Cov(θ) P with P = diag(p), θ = log p, as
    :func:`fabricsurf.inverse.fitting.fit.covariance` (scaled by the reduced χ² without a stated
    noise level). Used for combinations of moduli, e.g. the mean fibre stiffness (k_l + k_m)/2."""
    from fabricsurf.inverse.fitting.fit import covariance

    vals = fm.values()
    pred = fm.run(sens=free)
    r, Jr = fm.residuals(pred)
    C = covariance(Jr * vals[free], float(r @ r), fm.noise_known)
    return pred, C * np.outer(vals[free], vals[free])
