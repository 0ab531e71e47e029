"""The curvature of a tool given as a surface, for the exact tangent of its tabulated contact
that the sensitivities solve with (experiments/forming/tabulated_tools.py; Newton keeps the
frozen normal; docs/tool_surfaces.md, "The tool's curvature").

The penalty ½ k_c ⟨−d⟩² of the signed distance d has the Hessian
k_c H(−d) n ⊗ n − k_c ⟨−d⟩ ∇∇d, and ∇∇d = ∇n, the derivative of the outward normal at the
point (for a sphere of radius R seen from distance ρ to its centre, (I − n ⊗ n)/ρ). A table
holding n at the current placement gives the first term only; this module gives the second.
For an analytic shape ∇n is taken by central differences of its normal, which is the exact
gradient of its distance everywhere. A triangle mesh's normal is constant over each face, so
its ∇n vanishes there: :func:`has_curvature` says which surfaces carry it.
"""

from __future__ import annotations

import numpy as np

HESSIAN_STEP = 1e-5
"""Step of the central differences of the normal, in tool sizes: their truncation error
relative to the curvature is (step / radius)², their rounding error 10⁻¹⁶ / step."""
KINK = 1e-2
"""Relative difference of the one-sided differences above which the normal field is taken to
have a kink within the step (an edge, a seam where the curvature jumps, the medial surface
inside the tool): ∇n is set to zero there, the frozen normal's tangent."""


def has_curvature(surface) -> bool:
    """Whether the tool's table should carry ∇n: an analytic shape (also moved), not a
    triangle mesh (one with a ``near`` search), whose faces are flat."""
    return getattr(surface, "near", None) is None


def distance_hessian(surface, x: np.ndarray) -> np.ndarray:
    """∇∇d = ∇n of ``surface`` at the points x (m, 3), symmetric (m, 3, 3); zero at points
    within a difference step of a kink of the normal (:data:`KINK`)."""
    h = HESSIAN_STEP * surface.size
    floor = 1e-3 / surface.size  # far below any curvature a tool of this size resolves
    n0 = surface.normal(x)
    grad = np.empty((len(x), 3, 3))
    kink = np.zeros(len(x), dtype=bool)
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        forward = (surface.normal(x + step) - n0) / h
        backward = (n0 - surface.normal(x - step)) / h
        grad[:, :, j] = 0.5 * (forward + backward)
        size = np.maximum(np.linalg.norm(forward, axis=1), np.linalg.norm(backward, axis=1))
        kink |= np.linalg.norm(forward - backward, axis=1) > KINK * size + floor * KINK
    hessian = 0.5 * (grad + grad.transpose(0, 2, 1))
    hessian[kink] = 0.0
    return hessian
