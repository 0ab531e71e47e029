"""Bending rigidities of the fabric model (normal_bending + twist) with fibres at any angles:
the plate rigidity D, the narrow-strip rigidity and the cylindrical rigidity (docs/bending.md).
"""

from __future__ import annotations

import numpy as np


def _curvature_map(angles_deg: tuple[float, float]) -> np.ndarray:
    """A with (K_L, K_M, T) = A (κ_xx, κ_yy, κ_xy) for small deflections of a flat sheet:
    K_A = A·κB with κ the curvature tensor of the deflection (docs/bending.md)."""
    a, b = (np.radians(t) for t in angles_deg)
    L, M = np.array([np.cos(a), np.sin(a)]), np.array([np.cos(b), np.sin(b)])

    def row(A, B):
        return [A[0] * B[0], A[1] * B[1], A[0] * B[1] + A[1] * B[0]]

    return np.array([row(L, L), row(M, M), row(L, M)])


def plate_rigidity(k_b: float, k_t: float, angles_deg: tuple[float, float]) -> np.ndarray:
    """D (3×3) with W = ½ κᵀDκ, κ = (κ_xx, κ_yy, κ_xy), of ½k_b(K_L² + K_M²) + ½k_t T²."""
    A = _curvature_map(angles_deg)
    return A.T @ np.diag([k_b, k_b, k_t]) @ A


def narrow_strip_rigidity(k_b: float, k_t: float, angles_deg: tuple[float, float]) -> float:
    """Bending rigidity per unit width of a narrow strip along x (N·mm): the cross curvature
    κ_yy and twist κ_xy are free (no moment across the strip), so D_eff is the Schur complement
    D_xx − D_x,r D_rr⁻¹ D_r,x. Orthogonal fibres at θ: 1/D_eff = (cos⁴θ + sin⁴θ)/k_b +
    4cos²θ sin²θ/k_t; at ±45°, D_eff = 2k_b k_t/(k_t + 2k_b), zero without twist."""
    D = plate_rigidity(k_b, k_t, angles_deg)
    return float(D[0, 0] - D[0, 1:] @ np.linalg.pinv(D[1:, 1:]) @ D[1:, 0])


def cylindrical_rigidity(k_b: float, k_t: float, angles_deg: tuple[float, float]) -> float:
    """Rigidity per unit width in cylindrical bending (κ_yy = κ_xy = 0: a wide plate or the
    clamped end), D_xx = k_b(L_x⁴ + M_x⁴) + k_t L_x² M_x² (N·mm)."""
    return float(plate_rigidity(k_b, k_t, angles_deg)[0, 0])
