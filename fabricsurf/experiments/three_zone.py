"""The ideal three-zone kinematics of the bias-extension test and its normalisation (Cao et al.
2008, eqs. 13 and 18): zone-C shear angle, normalised shear force, and the force an elastic
shear response gives under these kinematics.

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

from fabricsurf.constants import FRICTION_ANGLE


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
    """τ = dW/dγ (N/mm) of ``shear`` + ``shear_locking`` + ``crossover_friction``:
    k_s γ + k₄γ³ + k₆γ⁵ + τ_f tanh(γ/γ_f), γ_f the friction term's default shape angle."""
    g = np.asarray(gamma, float)
    ks = params.get("shear", {}).get("k_s", 0.0)
    lk = params.get("shear_locking", {})
    tau_f = params.get("crossover_friction", {}).get("tau_f", 0.0)
    return (ks * g + lk.get("k4", 0.0) * g**3 + lk.get("k6", 0.0) * g**5
            + tau_f * np.tanh(g / FRICTION_ANGLE))


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
