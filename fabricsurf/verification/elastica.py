"""The heavy elastica: an inextensible cantilever under its own weight (docs/bending.md).

A strip of overhang L, clamped horizontally at s = 0 and free at s = L, carries its weight q per
unit length; θ(s) is the droop angle of the tangent below the horizontal, s the arclength. The
moment of the weight beyond s, B θ'(s) = ∫_s^L q (x(σ) − x(s)) dσ, gives

    θ'' = −(L − s) cos θ / c³,   θ(0) = 0,  θ'(L) = 0,   x' = cos θ,  z' = −sin θ,

with c = (B/q)^(1/3) the bending length of Peirce (1930); for a strip of width w, B = D w and
q = ρ_A g w, so c = (D/(ρ_A g))^(1/3) whatever the width. The only parameter is L/c. Solved with
scipy's ``solve_bvp`` (a collocation method independent of the finite elements), by
continuation in (L/c)³ from the small-deflection solution θ = (L³ − (L − s)³)/(6c³), whose tip
deflection is δ = L⁴/(8c³) (the uniform-load cantilever, w L⁴/(8B)).

Also here: Peirce's bending-length formula. The rigidities of the fabric model with fibres at
any angles (normal_bending + twist, derived in docs/bending.md) are in fabricsurf.model.rigidity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_bvp


@dataclass
class Elastica:
    """A solved heavy elastica of overhang ``length`` and bending length ``c`` (mm)."""

    length: float
    c: float
    sol: object

    def at(self, s: np.ndarray) -> np.ndarray:
        """(θ, x, z) at arclengths s (n×3; s = reference x of an inextensible strip)."""
        y = self.sol.sol(np.asarray(s, float) / self.length)
        return np.column_stack([y[0], self.length * y[2], self.length * y[3]])

    def displacement(self, s: np.ndarray) -> np.ndarray:
        """(u_x, u_z) = (x(s) − s, z(s)) of the centre line (n×2, mm)."""
        th_x_z = self.at(s)
        return np.column_stack([th_x_z[:, 1] - np.asarray(s, float), th_x_z[:, 2]])

    @property
    def tip_deflection(self) -> float:
        """δ = −z(L) (mm, positive downwards)."""
        return float(-self.at([self.length])[0, 2])

    @property
    def tip_angle(self) -> float:
        """θ(L) (rad)."""
        return float(self.at([self.length])[0, 0])

    @property
    def chord_angle(self) -> float:
        """Angle below the horizontal of the chord from the clamp to the tip (rad): the angle
        of Peirce's inclined plane (41.5° in the standard test)."""
        _, x, z = self.at([self.length])[0]
        return float(math.atan2(-z, x))


def _rhs(eps: float):
    def f(sig, y):
        th, dth = y[0], y[1]
        return np.vstack([dth, -eps * (1.0 - sig) * np.cos(th), np.cos(th), -np.sin(th)])

    return f


def _bc(ya, yb):
    return np.array([ya[0], yb[1], ya[2], ya[3]])


def solve_elastica(
    length: float, c: float, nodes: int = 101, tol: float = 1e-10, continuation: int = 8
) -> Elastica:
    """The heavy elastica of overhang ``length`` and bending length ``c`` (module docstring),
    in the unit arclength σ = s/L with ε = (L/c)³; raises RuntimeError if it fails."""
    if not (length > 0 and c > 0 and math.isfinite(length / c)):
        raise ValueError(f"elastica: length = {length!r} and c = {c!r} must be positive")
    eps_final = (length / c) ** 3
    sig = np.linspace(0.0, 1.0, nodes)
    sol = None
    for eps in eps_final * np.linspace(0.0, 1.0, continuation + 1)[1:]:
        if sol is None:
            th = eps * (1.0 - (1.0 - sig) ** 3) / 6.0
            y0 = np.vstack([th, 0.5 * eps * (1.0 - sig) ** 2, sig, -np.cumsum(th) / nodes])
            mesh = sig
        else:
            mesh, y0 = sol.x, sol.y
        sol = solve_bvp(_rhs(eps), _bc, mesh, y0, tol=tol, max_nodes=100000)
        if not sol.success:
            raise RuntimeError(f"elastica: solve_bvp failed at (L/c)^3 = {eps:.4g}: {sol.message}")
    return Elastica(float(length), float(c), sol)


def small_deflection_tip(length: float, c: float) -> float:
    """δ = L⁴/(8c³): the linear cantilever under a uniform load, q L⁴/(8B) (mm)."""
    return length**4 / (8.0 * c**3)


def peirce_bending_length(overhang: float, chord_angle: float) -> float:
    """Peirce (1930): c = l (cos(θ/2)/(8 tan θ))^(1/3), θ the chord angle (rad); l/2 at 41.5°.
    For small θ it is the linear relation θ = l³/(8c³), i.e. δ = l⁴/(8c³)."""
    return overhang * (math.cos(0.5 * chord_angle) / (8.0 * math.tan(chord_angle))) ** (1 / 3)


def bending_length(rigidity: float, weight_per_area: float) -> float:
    """c = (D/(ρ_A g))^(1/3) (mm) from the rigidity per unit width D (N·mm) and the weight per
    unit area (N/mm²)."""
    return (rigidity / weight_per_area) ** (1.0 / 3.0)
