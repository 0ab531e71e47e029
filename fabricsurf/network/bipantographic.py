"""Bi-pantographic cell lattice of Barchiesi et al. 2020, §3 (eqs. 18-20, Table 2, Figs. 6-8),
reconstructed.

Reconstruction (figure ``docs/bipantographic_cell.png``: ``benchmarks/bipantographic_cell.py``)
---------------------------------------------------------------------------------------------
The text gives: square cells of side sqrt(2) eps, 4 vertex nodes shared between cells and
9 internal nodes, 16 extensional springs (k_e, l0 = eps/sqrt(3)), 8 pivot springs
(k_r1, phi0 = (-1)^l pi/3), 4 bending springs inside the cell (k_r2, phi0 = 0) and 4
bending springs at each interior vertex (k_r3 = k_r2), gamma = pi/6, and the legible
fragments of Table 2: extensional {4,12}, {11,3}, {12,3}; pivots {0,6,4}, {0,5,4},
{4,7,1}, {4,8,1}, {4,9,2}, {4,10,2}, {3,12,4}, {3,11,4}. The unique geometry consistent
with all of it:

* corners 0 = (i, j) lower left, 1 = (i+1, j+1) upper right, 2 = (i+1, j) lower right,
  3 = (i, j+1) upper left (vertex grid of pitch sqrt(2) eps); 4 = cell centre;
* the two pantographic beams run along the diagonals 0 -> 4 -> 1 (+45 deg) and
  3 -> 4 -> 2 (-45 deg); each half diagonal (length eps) is a rhombus P-S_l-Q-S_r whose
  sides (length eps/sqrt(3)) make gamma = pi/6 with the axis: side nodes 5/6 on 0->4,
  8/7 on 4->1, 10/9 on 4->2, 11/12 on 3->4 (left/right of the axis direction);
* pivots: the turning angle P -> S -> Q at every side node, +pi/3 at right-hand nodes
  (6, 7, 9, 12), -pi/3 at left-hand ones, matching phi0 = (-1)^l pi/3 in Table 2's order;
  these angles change when a rhombus opens, i.e. with the beam stretch rho: they are the
  K_S term of [B (2)] (acos(1 - 2 cos^2(gamma) rho^2) - pi + 2 gamma);
* bending (phi0 = 0): the fibres are straight bars S -> axis node -> S' crossing the axis
  nodes, inside the cell {5,4,7}, {6,4,8}, {11,4,9}, {12,4,10} (k_r2) and, at interior
  vertex V, {7, V, 5'}, {8, V, 6'} (+45 deg beam, cells (i-1,j-1) -> (i,j)) and
  {9, V, 11'}, {10, V, 12'} (-45 deg beam, cells (i-1,j) -> (i,j-1)) (k_r3 = k_r2).

Parameters ([B] Table 3, micro-model) in N, mm: k_e = k_E = 335 N/m = 0.335 N/mm;
k_r1 = k_S = 9.36, k_r2 = k_r3 = k_F = 46.2, read as N mm (the table's "J" is taken as mJ:
in J the grip force would be in kN, and the macro K_S = 34 N/m is of the order of the
lattice's homogenised K_S = 0.0145 N/mm (:mod:`fabricsurf.network.homogenize`) only in the
mJ reading). This unit reading is an assumption. Clamps [B Table 1]: vertices of columns
i = 0, 1 held, of columns i = N-1, N moved by u_bar e_x (the rigid "rhomboidal elements" of
§4 join only vertex hinges, so internal cell nodes stay free).

Micro-macro grid: the beam crossings (vertices and centres) form a square grid of pitch eps
along L = (1, 1)/sqrt(2) and M = (1, -1)/sqrt(2): ``Lattice.grid`` for
:mod:`fabricsurf.network.micromacro` ([B (3)-(6)], p_ij of [B §2]).
"""

from __future__ import annotations

import numpy as np

from fabricsurf.network.engine import SpringNetwork
from fabricsurf.network.hencky import Lattice

TABLE3 = {"k_e": 0.335, "k_r1": 9.36, "k_r2": 46.2}  # N/mm, N mm, N mm (see docstring)
EPS_B = 12.02  # mm
# half diagonals (P, Q, left side node, right side node), local numbering
SEGMENTS = [(0, 4, 5, 6), (4, 1, 8, 7), (4, 2, 10, 9), (3, 4, 11, 12)]
R2 = [(5, 4, 7), (6, 4, 8), (11, 4, 9), (12, 4, 10)]


def cell_geometry(eps: float = 1.0) -> np.ndarray:
    """Reference coordinates (13, 2) of local nodes 0..12 of a cell with corner 0 at 0."""
    c = np.sqrt(2.0) * eps
    x = np.zeros((13, 2))
    x[:5] = [[0, 0], [c, c], [c, 0], [0, c], [c / 2, c / 2]]
    h = eps / (2 * np.sqrt(3.0))  # rhombus half-width: sides make pi/6 with the axis
    for p, q, sl, sr in SEGMENTS:
        e = (x[q] - x[p]) / eps
        n = np.array([-e[1], e[0]])
        mid = 0.5 * (x[p] + x[q])
        x[sl], x[sr] = mid + h * n, mid - h * n
    return x


def _ids(n_x: int, n_y: int) -> np.ndarray:
    """Global ids (n_x, n_y, 13) of the local nodes of every cell [B (18)]."""
    nv = (n_x + 1) * (n_y + 1)
    i, j = np.meshgrid(np.arange(n_x), np.arange(n_y), indexing="ij")
    ids = np.empty((n_x, n_y, 13), np.int64)
    for k, (di, dj) in enumerate([(0, 0), (1, 1), (1, 0), (0, 1)]):
        ids[..., k] = (i + di) * (n_y + 1) + (j + dj)
    ids[..., 4:] = nv + 9 * (i * n_y + j)[..., None] + np.arange(9)
    return ids


def bipantographic_lattice(
    n_x: int = 11,
    n_y: int = 7,
    eps: float = EPS_B,
    k_e: float = TABLE3["k_e"],
    k_r1: float = TABLE3["k_r1"],
    k_r2: float = TABLE3["k_r2"],
) -> Lattice:
    """The 13-node-cell lattice of [B §3] on n_x x n_y cells of side sqrt(2) eps.

    Energy [B (20)]: 16 extensional (k_e, l0 = eps/sqrt(3)), 8 pivot (k_r1, +-pi/3) and
    4 bending (k_r2, 0) springs per cell, 4 bending springs (k_r3 = k_r2) per interior
    vertex. Defaults: [B] Table 3 and eps = 12.02 mm, i.e. the 187 x 119 mm specimen of
    11 x 7 cells. Returns a :class:`Lattice` (``spring_sets`` keys: ``extension``,
    ``pivot``, ``bending``) with the Table 1 clamp / grip vertex sets.
    """
    ids = _ids(n_x, n_y).reshape(-1, 13)
    c = np.sqrt(2.0) * eps
    i, j = np.meshgrid(np.arange(n_x), np.arange(n_y), indexing="ij")
    X = np.zeros(((n_x + 1) * (n_y + 1) + 9 * n_x * n_y, 2))
    loc = cell_geometry(eps)
    X[ids] = loc[None] + c * np.stack([i.ravel(), j.ravel()], 1)[:, None, :]
    ext = np.concatenate(
        [ids[:, [p, s]] for p, q, sl, sr in SEGMENTS for s in (sl, sr)]
        + [ids[:, [s, q]] for p, q, sl, sr in SEGMENTS for s in (sl, sr)]
    )
    piv = np.concatenate([ids[:, [p, s, q]] for p, q, sl, sr in SEGMENTS for s in (sr, sl)])
    bend = [ids[:, list(t)] for t in R2]
    cid = _ids(n_x, n_y)
    a, b = cid[:-1, :-1], cid[1:, 1:]  # cells (i-1, j-1) and (i, j) around vertex (i, j)
    d, e = cid[:-1, 1:], cid[1:, :-1]  # cells (i-1, j) and (i, j-1)
    V = b[..., 0]
    bend += [
        np.stack([a[..., 7], V, b[..., 5]], -1).reshape(-1, 3),
        np.stack([a[..., 8], V, b[..., 6]], -1).reshape(-1, 3),
        np.stack([d[..., 9], V, e[..., 11]], -1).reshape(-1, 3),
        np.stack([d[..., 10], V, e[..., 12]], -1).reshape(-1, 3),
    ]
    bend = np.concatenate(bend)
    rot = np.concatenate([piv, bend])
    phi0 = np.concatenate([np.full(len(piv), np.nan), np.zeros(len(bend))])
    k_rot = np.concatenate([np.full(len(piv), k_r1), np.full(len(bend), k_r2)])
    net = SpringNetwork(X, ext, k_e, l0=eps / np.sqrt(3.0), rot=rot, k_rot=k_rot, phi0=phi0)
    net.phi0[: len(piv)] = net.turning_angles(X)[: len(piv)]
    nv = n_y + 1
    clamp = np.arange(2 * nv)
    grip = np.arange((n_x - 1) * nv, (n_x + 1) * nv)
    L, M = np.array([1.0, 1.0]) / np.sqrt(2), np.array([1.0, -1.0]) / np.sqrt(2)
    sets = {
        "extension": np.arange(len(ext)),
        "pivot": np.arange(len(piv)),
        "bending": len(piv) + np.arange(len(bend)),
    }
    return Lattice(net, _axis_grid(n_x, n_y, cid), L, M, float(eps), clamp, grip, sets)


def _axis_grid(n_x: int, n_y: int, cid: np.ndarray) -> np.ndarray:
    """Grid of beam crossings: vertex (i, j) -> (i + j, i - j), centre -> (i + j + 1, i - j)."""
    grid = -np.ones((n_x + n_y + 1, n_x + n_y + 1), np.int64)
    i, j = np.meshgrid(np.arange(n_x + 1), np.arange(n_y + 1), indexing="ij")
    grid[i + j, i - j + n_y] = i * (n_y + 1) + j
    i, j = np.meshgrid(np.arange(n_x), np.arange(n_y), indexing="ij")
    grid[i + j + 1, i - j + n_y] = cid[..., 4]
    return grid
