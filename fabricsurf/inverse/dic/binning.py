"""Binning a point cloud to a pitch, and the noise level estimated from the data, both in O(N)
memory and numpy-vectorised (a sort, then sums per cell with ``np.bincount``).

Binning: the points of one step that fall into the same pitch × pitch cell of the specimen are
replaced by their mean position and mean displacement (exact for a field linear in the cell).

Noise: in cells of about :data:`NOISE_CELL_POINTS` points a plane is fitted to each
displacement component; the residual variance per cell, RSS/(n − 3), estimates σ² where the
field is smooth at the cell's scale. The median over cells (divided by the median of χ²ₖ/k,
Wilson–Hilferty) keeps the cells across a kink of the field (the zone boundaries of a bias
test) from inflating it.
"""

from __future__ import annotations

import math

import numpy as np

NOISE_CELL_POINTS = 16
"""Points per cell of the noise estimate (4 × 4 on a regular grid)."""
MIN_CELL_POINTS = 6
"""Cells with fewer points do not enter the noise estimate (3 parameters per plane)."""
MIN_CELLS = 5
"""Fewer usable cells give no estimate (noise_std None: give [data] noise_std)."""


def _cells(step: np.ndarray, X: np.ndarray, pitch: float) -> tuple[np.ndarray, int]:
    """(cell index of every row, number of cells): cells of size ``pitch`` per step."""
    ix = np.floor(X[:, 0] / pitch).astype(np.int64)
    iy = np.floor(X[:, 1] / pitch).astype(np.int64)
    ix -= ix.min()
    iy -= iy.min()
    key = (step.astype(np.int64) * (ix.max() + 1) + ix) * (iy.max() + 1) + iy
    _, inverse = np.unique(key, return_inverse=True)
    return inverse.ravel(), int(inverse.max()) + 1


def bin_points(
    step: np.ndarray, X: np.ndarray, u: np.ndarray, pitch: float, min_points: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(step, X, u, count) of the cells of ``pitch`` (mm) holding ≥ ``min_points`` points,
    sorted by step; X and u are the cells' mean positions and displacements."""
    cell, m = _cells(step, X, pitch)
    count = np.bincount(cell, minlength=m)
    keep = count >= min_points
    mean = lambda a: (np.bincount(cell, weights=a, minlength=m) / np.maximum(count, 1))[keep]  # noqa: E731
    first = np.zeros(m, dtype=np.int64)
    first[cell[::-1]] = np.arange(len(cell))[::-1]
    Xb = np.column_stack([mean(X[:, 0]), mean(X[:, 1])])
    ub = np.column_stack([mean(u[:, k]) for k in range(u.shape[1])])
    sb = step[first][keep]
    order = np.argsort(sb, kind="stable")
    return sb[order], Xb[order], ub[order], count[keep][order]


def typical_spacing(step: np.ndarray, X: np.ndarray) -> float:
    """The mean spacing of the points of one step: √(area of their bounding box / count),
    averaged over the steps."""
    out = []
    for s in np.unique(step):
        P = X[step == s]
        area = np.ptp(P[:, 0]) * np.ptp(P[:, 1])
        if len(P) > 1 and area > 0:
            out.append(math.sqrt(area / len(P)))
    return float(np.mean(out)) if out else 0.0


def noise_estimate(step: np.ndarray, X: np.ndarray, u: np.ndarray) -> dict:
    """σ of the displacements estimated from local plane residuals (module docstring):
    {"noise_std", "cells", "cell_mm", "per_component"}; noise_std None when fewer than
    MIN_CELLS cells hold MIN_CELL_POINTS points."""
    spacing = typical_spacing(step, X)
    if spacing <= 0:
        return {"noise_std": None, "cells": 0, "cell_mm": None, "per_component": []}
    size = spacing * math.sqrt(NOISE_CELL_POINTS)
    cell, m = _cells(step, X, size)
    n = np.bincount(cell, minlength=m).astype(float)
    centre = np.column_stack([np.bincount(cell, X[:, k], m) / np.maximum(n, 1) for k in range(2)])
    d = X - centre[cell]
    basis = [np.ones(len(X)), d[:, 0], d[:, 1]]
    A = np.empty((m, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            A[:, i, j] = A[:, j, i] = np.bincount(cell, basis[i] * basis[j], m)
    ok = n >= MIN_CELL_POINTS
    ok &= np.abs(np.linalg.det(A)) > 1e-12 * np.maximum(n, 1) * size**4
    if ok.sum() < MIN_CELLS:
        return {"noise_std": None, "cells": int(ok.sum()), "cell_mm": size, "per_component": []}
    dof = n[ok] - 3
    per = []
    for k in range(u.shape[1]):
        b = np.column_stack([np.bincount(cell, basis[i] * u[:, k], m) for i in range(3)])
        beta = np.linalg.solve(A[ok], b[ok][..., None])[..., 0]
        rss = np.bincount(cell, u[:, k] ** 2, m)[ok] - np.einsum("ij,ij->i", beta, b[ok])
        s2 = np.maximum(rss, 0.0) / dof
        k_med = float(np.median(dof))
        per.append(float(np.median(s2) / (1 - 2 / (9 * k_med)) ** 3))
    return {
        "noise_std": math.sqrt(float(np.mean(per))),
        "cells": int(ok.sum()),
        "cell_mm": size,
        "per_component": [math.sqrt(p) for p in per],
    }
