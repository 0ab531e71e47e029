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
is its inverse (the force an elastic shear response τ(γ) gives under the ideal kinematics). The
shear moment τ(γ) is the model's own: each term's density differentiated in the pure shear of
inextensible fibres (fabricsurf/model/pure_shear.py), so a user's term and a friction term's
shape angle γ_f count.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fabricsurf.model import pure_shear
from fabricsurf.model.terms import Shear, ShearLocking, Term

Model = Sequence[Term]
"""A list of terms: each gives its own shear moment (:mod:`fabricsurf.model.pure_shear`)."""


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


def normalised_shear_force(d, force, length: float, width: float) -> tuple[np.ndarray, np.ndarray]:
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


def shear_moment(gamma, model: Model) -> np.ndarray:
    """τ = dW/dγ (N/mm) of ``model`` under the ideal kinematics (pure shear of inextensible
    ±45° fibres), derived from every term's own density (``Term.shear_moment``,
    fabricsurf/model/pure_shear.py): e.g. k_s γ + k₄γ³ + k₆γ⁵ + τ_f tanh(γ/γ_f) for shear,
    shear_locking and crossover_friction with the friction term's own shape angle γ_f."""
    return pure_shear.shear_moment(list(model), gamma)


def constitutive_shear_force(gamma, model: Model) -> np.ndarray:
    """The normalised shear force τ(γ)/cos γ (N/mm) the model implies (picture-frame norm)."""
    g = np.asarray(gamma, float)
    return shear_moment(g, model) / np.cos(g)


def kinematic_force(d, length: float, width: float, model: Model) -> np.ndarray:
    """Grip force (N) of the ideal three-zone kinematics (inextensible yarns, no slip) for the
    shear response of ``model``: eq. 18 solved for F."""
    H, W = float(length), float(width)
    g = zone_c_shear_angle(d, H, W)
    tau_c, tau_b = shear_moment(np.stack([g, 0.5 * g]), model)  # zones C and B, one assembly
    tau = W * (H - 1.5 * W) * tau_c + 0.5 * W**2 * tau_b
    return tau / (0.5 * (H - W) * (np.cos(0.5 * g) - np.sin(0.5 * g)))


def locking_angle(model: Model) -> float | None:
    """γ (rad) at which the locking moment of the model's ``shear_locking`` equals the linear
    one of its ``shear`` (:meth:`ShearLocking.locking_angle`); None without locking."""
    terms = list(model)
    k_s = sum(t.k_s for t in terms if isinstance(t, Shear))
    lock = next((t for t in terms if isinstance(t, ShearLocking)), None)
    return None if lock is None else lock.locking_angle(k_s)
