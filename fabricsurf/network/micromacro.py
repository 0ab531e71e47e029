"""Micro-macro post-processing on a node grid [B (3)-(6)].

A lattice exposes a *grid* of node ids ``grid[a, b]`` (-1 where absent) whose index
directions a, b run along the fibre / pantographic-beam directions L, M with spacing eps
(the Hencky crossings, or the vertices and centres of the bi-pantographic cells). On it:

* positions: chi(x_i, y_j) = p_ij                                             [B (3)]
* stretches: rho_x ~ |p_{i+1,j} - p_ij| / eps,  rho_y ~ |p_{i,j+1} - p_ij| / eps   [B (4)]
* shear:     pi/2 - arccos of the cosine between the two arms                 [B (5)]
* gradients: du/da ~ (u_{i+1,j} - u_ij)/eps, du/db ~ (u_{i,j+1} - u_ij)/eps       [B (6)]

Forward differences are used where the +1 neighbour exists, backward ones otherwise (the
second line of [B (6)], on the far boundary). With the grid along L, M, rho_x, rho_y and
the shear angle are the continuum lambda = |FL|, mu = |FM| and gamma (sin gamma = l.m)
up to O(eps); the affine case is exact.
"""

from __future__ import annotations

import numpy as np


def _arm(grid: np.ndarray, x: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Difference p_{+1} - p (forward, else backward) along ``axis``; NaN if none."""
    pad = np.pad(grid, [(1, 1) if ax == axis else (0, 0) for ax in range(2)], constant_values=-1)
    sl = [slice(None), slice(None)]
    sl[axis] = slice(2, None)
    nxt = pad[tuple(sl)]
    sl[axis] = slice(0, -2)
    prv = pad[tuple(sl)]
    xg = np.where((grid >= 0)[..., None], x[np.maximum(grid, 0)], np.nan)
    fwd = np.where((nxt >= 0)[..., None], x[np.maximum(nxt, 0)] - xg, np.nan)
    bwd = np.where((prv >= 0)[..., None], xg - x[np.maximum(prv, 0)], np.nan)
    return np.where(np.isnan(fwd), bwd, fwd), np.isnan(fwd)


def grid_fields(grid: np.ndarray, X: np.ndarray, x: np.ndarray, spacing: float) -> dict:
    """Micro-macro fields on the node grid [B (3)-(6)].

    Parameters
    ----------
    grid : (na, nb) int array of node ids, -1 where absent.
    X, x : (n, 2) reference and current node positions (mm).
    spacing : eps, reference distance between grid neighbours (mm).

    Returns
    -------
    dict of (na, nb) arrays (NaN where absent or undefined): ``X``, ``Y``, ``ux``, ``uy``
    (eq. 3), ``rho_x``, ``rho_y`` (eq. 4), ``shear`` (rad, eq. 5), and (na, nb, 2) arrays
    ``du_da``, ``du_db`` (eq. 6).
    """
    X = np.asarray(X, float)
    x = np.asarray(x, float)
    u = x - X
    ok = grid >= 0
    Xg = np.where(ok[..., None], X[np.maximum(grid, 0)], np.nan)
    ug = np.where(ok[..., None], u[np.maximum(grid, 0)], np.nan)
    da, _ = _arm(grid, x, 0)
    db, _ = _arm(grid, x, 1)
    la, lb = np.linalg.norm(da, axis=-1), np.linalg.norm(db, axis=-1)
    cos = np.clip(np.einsum("...i,...i", da, db) / (la * lb), -1.0, 1.0)
    return {
        "X": Xg[..., 0],
        "Y": Xg[..., 1],
        "ux": ug[..., 0],
        "uy": ug[..., 1],
        "rho_x": la / spacing,
        "rho_y": lb / spacing,
        "shear": np.pi / 2 - np.arccos(cos),
        "du_da": _arm(grid, u, 0)[0] / spacing,
        "du_db": _arm(grid, u, 1)[0] / spacing,
    }
