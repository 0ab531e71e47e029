"""Coupled three-node crossing elements: energies that couple the two fibre strains at a
crossing with each other and with the change of the angle between them.

A crossing element is a triple (i, j, k) with j the vertex, the same triples as the quadrant
shear springs of :func:`~fabricsurf.network.hencky.hencky_lattice`: the arm ``a = x_j - x_i``
lies along one fibre, the arm ``b = x_k - x_j`` along the other. Its kinematics are the arm
strains and the turning-angle deviation of [B (14), (16)] (Barchiesi et al. 2020)::

    e1 = |a| / l0 - 1,   e2 = |b| / l0 - 1,   d = phi2 - phi1 - phi0

and its energy (N mm) is

    W(e1, e2, d) = 1/2 k_st (e1 + e2) d^2 + k_x e1 e2

* ``k_st`` (N mm): the shear-tension coupling. With the quadrant shear spring 1/2 (k_sh/4) d^2
  beside it, the quadrant's shear stiffness is (k_sh/4)(1 + c (e1 + e2)) for
  ``k_st = c k_sh / 4``: the nodal shear stiffness grows with the fibre strains, as measured on
  woven fabrics in biaxial-tension-plus-shear tests (Launay et al. 2008; Harrison et al. 2012);
* ``k_x`` (N mm): the crimp interchange, an energy bilinear in the two fibre strains at the
  crossing (stretching one family deepens the crimp of the other; Kawabata et al. 1973).

Derivatives by the chain rule: with ``W_1 = 1/2 k_st d^2 + k_x e2``, ``W_2 = 1/2 k_st d^2 +
k_x e1``, ``W_d = k_st (e1 + e2) d`` and ``W_12 = k_x``, ``W_1d = W_2d = k_st d``,
``W_dd = k_st (e1 + e2)`` (``W_11 = W_22 = 0``), the element gradient is
``W_1 De1 + W_2 De2 + W_d Dd`` and its Hessian
``sum_pq W_pq Dp Dq^T + W_1 D2e1 + W_2 D2e2 + W_d D2d``, where ``De1 = (-a^, a^, 0) / l0``,
``D2e1`` has the blocks ``+-(I - a^ a^T) / (|a| l0)`` on (i, j), and ``Dd``, ``D2d`` are those
of the rotational spring [B (15)]. For an affine placement F the arm strains are exactly the
fibre strains lam - 1, mu - 1 and d = -+gamma (:mod:`~fabricsurf.network.hencky_moduli`).
"""

from __future__ import annotations

import numpy as np

from fabricsurf.network.engine import _hess_theta, _perp

_I2 = np.eye(2)


class CrossingCouplings:
    """Coupled crossing elements attached to a :class:`~.engine.SpringNetwork`.

    Parameters
    ----------
    rot_index : (m,) int array
        Index of each element's triple in ``net.rot`` (its energy, forces and Hessian are
        added to that rotational spring's).
    tri : (m, 3) int array
        The node triples (i, j, k), j the vertex.
    l0 : (m,) array or scalar
        Rest length of both arms (mm).
    phi0 : (m,) array
        Rest turning angle (rad).
    k_st, k_x : (m,) arrays or scalars
        Shear-tension and crimp-interchange coefficients (N mm), module docstring.
    """

    def __init__(
        self,
        rot_index: np.ndarray,
        tri: np.ndarray,
        l0: np.ndarray | float,
        phi0: np.ndarray | float,
        k_st: np.ndarray | float = 0.0,
        k_x: np.ndarray | float = 0.0,
    ) -> None:
        self.rot_index = np.asarray(rot_index, np.int64).ravel()
        self.tri = np.asarray(tri, np.int64).reshape(-1, 3)
        m = len(self.tri)
        if len(self.rot_index) != m:
            raise ValueError("CrossingCouplings: one rot_index per triple")
        self.l0, self.phi0, self.k_st, self.k_x = (
            np.broadcast_to(np.asarray(v, float), (m,)).copy() for v in (l0, phi0, k_st, k_x)
        )

    def _kin(self, x: np.ndarray):
        i, j, k = self.tri.T
        a, b = x[j] - x[i], x[k] - x[j]
        la, lb = np.hypot(a[:, 0], a[:, 1]), np.hypot(b[:, 0], b[:, 1])
        c, s = np.cos(self.phi0), np.sin(self.phi0)
        ra = np.stack([c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1]], axis=1)
        d = np.arctan2(ra[:, 0] * b[:, 1] - ra[:, 1] * b[:, 0], np.einsum("ij,ij->i", ra, b))
        return a, b, la, lb, la / self.l0 - 1.0, lb / self.l0 - 1.0, d

    def energies(self, x: np.ndarray) -> np.ndarray:
        """Element energies W (N mm), shape (m,)."""
        _, _, _, _, e1, e2, d = self._kin(np.asarray(x, float).reshape(-1, 2))
        return 0.5 * self.k_st * (e1 + e2) * d * d + self.k_x * e1 * e2

    def _first(self, x: np.ndarray):
        a, b, la, lb, e1, e2, d = self._kin(x)
        m = len(a)
        ah, bh = a / la[:, None], b / lb[:, None]
        De1, De2 = np.zeros((m, 6)), np.zeros((m, 6))
        De1[:, :2], De1[:, 2:4] = -ah / self.l0[:, None], ah / self.l0[:, None]
        De2[:, 2:4], De2[:, 4:] = -bh / self.l0[:, None], bh / self.l0[:, None]
        ga = _perp(a) / (la * la)[:, None]
        gb = _perp(b) / (lb * lb)[:, None]
        Dd = np.concatenate([ga, -ga - gb, gb], axis=1)
        half = 0.5 * self.k_st * d * d
        W1, W2, Wd = half + self.k_x * e2, half + self.k_x * e1, self.k_st * (e1 + e2) * d
        return (a, b, la, lb, e1, e2, d, ah, bh), (De1, De2, Dd), (W1, W2, Wd)

    def element_gradients(self, x: np.ndarray) -> np.ndarray:
        """dW/dq per element, shape (m, 6) (dofs of i, j, k)."""
        _, (De1, De2, Dd), (W1, W2, Wd) = self._first(np.asarray(x, float).reshape(-1, 2))
        return W1[:, None] * De1 + W2[:, None] * De2 + Wd[:, None] * Dd

    def element_hessians(self, x: np.ndarray) -> np.ndarray:
        """d2W/dq2 per element, shape (m, 6, 6) (module docstring)."""
        x = np.asarray(x, float).reshape(-1, 2)
        (a, b, la, lb, e1, e2, d, ah, bh), (De1, De2, Dd), (W1, W2, Wd) = self._first(x)

        def outer(p, q):
            return np.einsum("mi,mj->mij", p, q)

        H = self.k_x[:, None, None] * (outer(De1, De2) + outer(De2, De1))
        Wed = (self.k_st * d)[:, None, None]
        H += Wed * (outer(De1, Dd) + outer(Dd, De1) + outer(De2, Dd) + outer(Dd, De2))
        H += (self.k_st * (e1 + e2))[:, None, None] * outer(Dd, Dd)
        Ka = (_I2 - np.einsum("mi,mj->mij", ah, ah)) / (la * self.l0)[:, None, None]
        Kb = (_I2 - np.einsum("mi,mj->mij", bh, bh)) / (lb * self.l0)[:, None, None]
        Ka, Kb = W1[:, None, None] * Ka, W2[:, None, None] * Kb
        H[:, :2, :2] += Ka
        H[:, 2:4, 2:4] += Ka + Kb
        H[:, :2, 2:4] -= Ka
        H[:, 2:4, :2] -= Ka
        H[:, 4:, 4:] += Kb
        H[:, 2:4, 4:] -= Kb
        H[:, 4:, 2:4] -= Kb
        Ha, Hb = Wd[:, None, None] * _hess_theta(a), Wd[:, None, None] * _hess_theta(b)
        H[:, :2, :2] -= Ha  # W_d times the second derivative of the angle [B (15)]
        H[:, 2:4, 2:4] += Hb - Ha
        H[:, :2, 2:4] += Ha
        H[:, 2:4, :2] += Ha
        H[:, 4:, 4:] += Hb
        H[:, 2:4, 4:] -= Hb
        H[:, 4:, 2:4] -= Hb
        return H
