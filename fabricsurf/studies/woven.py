"""Woven fabric in the bias-extension test: the kinematics and normalisation of the benchmark
(Cao et al. 2008), the ranges no elastic term can follow, and predictions of other specimens.

Notation of Cao et al. 2008, §5: free length H (along the load), width W, crosshead
displacement d, fibres at ±45°. With inextensible yarns and no slip three zones form: A (at the
grips, undeformed, area W²/2), B (half-sheared, area W²) and C (the centre, fully sheared, area
W(H − 3W/2)). Zone C's shear angle is (their eq. 13)

    γ = π/2 − 2 arccos((H − W + d) / (√2 (H − W))),

which reaches 90° at d = (√2 − 1)(H − W): the test itself locks geometrically there. The power
balance F ḋ = S_C τ(γ) γ̇ + S_B τ(γ/2) γ̇/2, with τ = dW/dγ the shear moment per reference area
and ḋ = ½(H − W)(cos γ/2 − sin γ/2) γ̇, written with the picture-frame normalised shear force
F_sh = τ / cos γ (force per unit frame length, Harrison et al. 2004), is their eq. 18:

    F_sh(γ) = [(H/W − 1) F (cos γ/2 − sin γ/2) − W F_sh(γ/2) cos γ/2] / ((2H − 3W) cos γ).

:func:`normalised_shear_force` evaluates eq. 18 on a measured curve, :func:`kinematic_force`
is its inverse (the force an elastic shear response τ(γ) gives under the ideal kinematics).
"""

from __future__ import annotations

import numpy as np

KNEE = "initial knee (friction at the crossovers: no elastic term starts with a finite force)"
BEYOND = "beyond locking (yarn slip, wrinkling: softer than any elastic shear response)"
MIDDLE = "intermediate range"


def lock_displacement(length: float, width: float) -> float:
    """d at which the zone-C angle of Cao et al. 2008 eq. 13 reaches 90° (mm)."""
    return (np.sqrt(2.0) - 1.0) * (length - width)


def zone_c_shear_angle(d, length: float, width: float) -> np.ndarray:
    """Kinematic shear angle of zone C (rad), Cao et al. 2008 eq. 13; NaN beyond the lock."""
    D = length - width
    c = (D + np.asarray(d, float)) / (np.sqrt(2.0) * D)
    with np.errstate(invalid="ignore"):
        return np.where(c <= 1.0, np.pi / 2 - 2.0 * np.arccos(np.minimum(c, 1.0)), np.nan)


def displacement_at_angle(gamma, length: float, width: float) -> np.ndarray:
    """Inverse of :func:`zone_c_shear_angle`: d (mm) for a zone-C angle γ (rad)."""
    D = length - width
    return np.sqrt(2.0) * D * np.cos(np.pi / 4 - 0.5 * np.asarray(gamma, float)) - D


def normalised_shear_force(d, force, length: float, width: float
                           ) -> tuple[np.ndarray, np.ndarray]:
    """(γ, F_sh): zone-C angle (rad) and normalised shear force (N/mm) of Cao et al. 2008
    eq. 18 from a force curve. The recursion needs F_sh(γ/2): it is interpolated, in order of
    increasing γ, from the values already found, with F_sh(0) = 0 (the elastic reference);
    where γ/2 lies below every angle found so far (the first point), F_sh is taken linear
    there, F_sh(γ/2) = F_sh(γ)/2, and eq. 18 is solved for F_sh(γ)."""
    H, W = float(length), float(width)
    g = zone_c_shear_angle(d, H, W)
    F = np.asarray(force, float)
    order = np.argsort(g)
    fs = np.full(len(g), np.nan)
    done_g, done_f = [0.0], [0.0]
    for i in order:
        if not np.isfinite(g[i]):
            continue
        c2, s2 = np.cos(0.5 * g[i]), np.sin(0.5 * g[i])
        a, b = (H / W - 1.0) * F[i] * (c2 - s2), (2 * H - 3 * W) * np.cos(g[i])
        if 0.5 * g[i] > done_g[-1]:
            fs[i] = a / (b + 0.5 * W * c2)
        else:
            fs[i] = (a - W * float(np.interp(0.5 * g[i], done_g, done_f)) * c2) / b
        done_g.append(float(g[i]))
        done_f.append(float(fs[i]))
    return g, fs


def shear_moment(gamma, params: dict) -> np.ndarray:
    """τ = dW/dγ (N/mm) of ``shear`` + ``shear_locking``: k_s γ + k₄γ³ + k₆γ⁵."""
    g = np.asarray(gamma, float)
    ks = params.get("shear", {}).get("k_s", 0.0)
    lk = params.get("shear_locking", {})
    return ks * g + lk.get("k4", 0.0) * g**3 + lk.get("k6", 0.0) * g**5


def constitutive_shear_force(gamma, params: dict) -> np.ndarray:
    """The normalised shear force τ(γ)/cos γ (N/mm) the moduli imply (picture-frame norm)."""
    g = np.asarray(gamma, float)
    return shear_moment(g, params) / np.cos(g)


def kinematic_force(d, length: float, width: float, params: dict) -> np.ndarray:
    """Grip force (N) of the ideal three-zone kinematics (inextensible yarns, no slip) for the
    shear response of ``params``: eq. 18 solved for F."""
    H, W = float(length), float(width)
    g = zone_c_shear_angle(d, H, W)
    tau = (W * (H - 1.5 * W) * shear_moment(g, params)
           + 0.5 * W**2 * shear_moment(0.5 * g, params))
    return tau / (0.5 * (H - W) * (np.cos(0.5 * g) - np.sin(0.5 * g)))


def locking_angle(params: dict) -> float | None:
    """γ (rad) at which the locking moment k₄γ³ + k₆γ⁵ equals the linear k_s γ (the shear
    stiffness has doubled); None without locking moduli."""
    ks = params.get("shear", {}).get("k_s", 0.0)
    lk = params.get("shear_locking", {})
    k4, k6 = lk.get("k4", 0.0), lk.get("k6", 0.0)
    if k4 <= 0 and k6 <= 0:
        return None
    if k6 <= 0:
        return float(np.sqrt(ks / k4))
    x = (-k4 + np.sqrt(k4**2 + 4 * k6 * ks)) / (2 * k6)  # x = γ²
    return float(np.sqrt(x))


def force_errors(model, measured) -> dict:
    """RMS and max |model − measured| in N and in % of the largest measured force."""
    e = np.asarray(model, float) - np.asarray(measured, float)
    fmax = float(np.max(np.abs(measured)))
    rms, mx = float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(e)))
    return {"rms_N": rms, "max_N": mx, "rms_pct": 100 * rms / fmax, "max_pct": 100 * mx / fmax}


def unexplained_ranges(d, error, measured, s_F: float, length: float, width: float
                       ) -> list[dict]:
    """Displacement ranges where |force error| exceeds three noise levels (the criterion of
    :func:`fabricsurf.inverse.report.where_unexplained`), each named. A range is the initial
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
    :func:`fabricsurf.inverse.fit.covariance` (scaled by the reduced χ² without a stated noise
    level). Used for combinations of moduli, e.g. the mean fibre stiffness (k_l + k_m)/2."""
    from fabricsurf.inverse.fit import covariance

    vals = fm.values()
    pred = fm.run(sens=free)
    r, Jr = fm.residuals(pred)
    C = covariance(Jr * vals[free], float(r @ r), fm.noise_known)
    return pred, C * np.outer(vals[free], vals[free])
