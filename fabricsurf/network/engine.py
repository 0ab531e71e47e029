"""Spring-network engine: extensional and rotational springs in the plane [B §3].

Notation follows Barchiesi et al. 2020 ([B], Barchiesi et al. 2020, §3). Nodes carry positions
``x`` of shape ``(n, 2)`` (mm); the generalised coordinates q of [B (18)] are ``x.ravel()``
(node-major: ``[x0, y0, x1, y1, ...]``), so dof ``2*a + c`` is component ``c`` of node ``a``.

Extensional spring (i, j) with stiffness k (N/mm) and rest length l0 (mm) [B (8)-(11)]::

    E_e = 1/2 k (l - l0)^2,   l = |x_j - x_i|

optionally with a slipping part f_s l0 eps_s ln cosh((l - l0)/(l0 eps_s)) (tension capped at
f_s: yarns sliding through the crossings, the ``yarn_slip`` effect).

Rotational spring (i, j, k) with stiffness kr (N mm / rad^2) and rest angle phi0 [B (12)-(17)]::

    E_r = 1/2 kr d^2 + 1/4 kr4 d^4 + 1/6 kr6 d^6,   d = phi2 - phi1 - phi0,
    phi1 = atan2 of (x_j - x_i),  phi2 = atan2 of (x_k - x_j)        [B (14)]

The quartic and sextic parts (kr4, kr6 in N mm, default 0) make a nonlinear shear spring that
stiffens as the angle change grows: the discrete counterpart of the ``shear_locking`` effect
(yarn jamming, Cao et al. 2008). With ``E_r'(d) = kr d + kr4 d^3 + kr6 d^5`` and
``E_r''(d) = kr + 3 kr4 d^2 + 5 kr6 d^4`` the gradient is ``E_r' dphi`` and the Hessian
``E_r'' dphi dphi^T + E_r' d2phi``.

i.e. ``phi = phi2 - phi1`` is the *turning angle* at the middle node j (0 for three
aligned nodes walked i -> j -> k, +pi/2 for a left turn).  Wrap-safety: the deviation
``phi - phi0`` is evaluated as the signed angle between ``R(phi0) (x_j - x_i)`` and
``x_k - x_j`` with ``atan2(cross, dot)``, which lies in (-pi, pi] and is smooth everywhere
except at deviations of +-pi; so branch cuts of atan2 (the (-pi, pi] range noted under
[B (15)]) never produce 2*pi jumps.

All evaluations are vectorised over springs; the sparse Hessian pattern is computed
once and values are scattered with ``numpy.bincount``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

_I2 = np.eye(2)


def _perp(v: np.ndarray) -> np.ndarray:
    """Rotate vectors by +90 degrees: (vx, vy) -> (-vy, vx)."""
    return np.stack([-v[:, 1], v[:, 0]], axis=1)


def _hess_theta(v: np.ndarray) -> np.ndarray:
    """Hessian of atan2(vy, vx) with respect to v, shape (m, 2, 2)."""
    x, y = v[:, 0], v[:, 1]
    r4 = (x * x + y * y) ** 2
    h = np.empty((len(v), 2, 2))
    h[:, 0, 0] = 2 * x * y / r4
    h[:, 1, 1] = -h[:, 0, 0]
    h[:, 0, 1] = h[:, 1, 0] = (y * y - x * x) / r4
    return h


class SpringNetwork:
    """A planar network of extensional and rotational springs [B (10), (16), (20)].

    Parameters
    ----------
    X : (n, 2) array
        Reference node coordinates (mm).
    ext : (m_e, 2) int array
        Node pairs (i, j) of the extensional springs.
    k_ext, l0 : (m_e,) arrays or scalars
        Stiffness (N/mm) and rest length (mm); ``l0=None`` takes the reference length.
    rot : (m_r, 3) int array
        Node triples (i, j, k) of the rotational springs, j the vertex.
    k_rot, phi0 : (m_r,) arrays or scalars
        Stiffness (N mm) and rest turning angle (rad), ``phi0 = phi2 - phi1`` of [B (16)];
        ``phi0=None`` takes the reference turning angle.
    k_rot4, k_rot6 : (m_r,) arrays or scalars
        Quartic and sextic coefficients (N mm) of the rotational springs (default 0: linear).
    m_fric, phi_f : (m_r,) array or scalar, and a positive scalar
        Saturating (friction-like) part of the rotational springs: energy
        ``m_fric phi_f ln cosh(d / phi_f)``, moment ``m_fric tanh(d / phi_f)`` (N mm), rising
        over the first ``phi_f`` (rad) of rotation and then constant (default 0: none).
    f_slip, eps_slip : (m_e,) array or scalar, and a positive scalar
        Slipping (friction-capped) part of the extensional springs: energy
        ``f_slip l0 eps_slip ln cosh(s)``, ``s = (l - l0) / (l0 eps_slip)``, tension
        ``f_slip tanh(s)`` (N) mobilised within the strain ``eps_slip`` and then constant:
        the yarns' friction at the crossings against sliding through them (default 0: none).
    s_comp : (m_e,) array or scalar
        Compression softness of the extensional springs: tension ``k (l - l0)`` for l > l0 and
        ``(1 - s_comp) k (l - l0)`` for l < l0 (default 0: symmetric). Not smoothed: the energy
        is C1 with a jump of its second derivative at l = l0, which the line-searched Newton of
        :mod:`~.equilibrium` handles (yarns that buckle out of their crimp under compression).
    couplings : :class:`~fabricsurf.network.couplings.CrossingCouplings` or None
        Coupled crossing elements, added to the rotational springs they index.
    """

    def __init__(
        self,
        X,
        ext,
        k_ext,
        l0=None,
        rot=None,
        k_rot=0.0,
        phi0=None,
        k_rot4=0.0,
        k_rot6=0.0,
        m_fric=0.0,
        phi_f: float = 1.0,
        f_slip=0.0,
        eps_slip: float = 1.0,
        s_comp=0.0,
        couplings=None,
    ) -> None:
        self.X = np.asarray(X, dtype=float).reshape(-1, 2)
        self.ext = np.asarray(ext, dtype=np.int64).reshape(-1, 2)
        self.rot = np.asarray(rot if rot is not None else [], dtype=np.int64).reshape(-1, 3)
        me, mr = len(self.ext), len(self.rot)
        self.k_ext = np.broadcast_to(np.asarray(k_ext, float), (me,)).copy()
        self.k_rot = np.broadcast_to(np.asarray(k_rot, float), (mr,)).copy()
        self.k_rot4 = np.broadcast_to(np.asarray(k_rot4, float), (mr,)).copy()
        self.k_rot6 = np.broadcast_to(np.asarray(k_rot6, float), (mr,)).copy()
        self.m_fric = np.broadcast_to(np.asarray(m_fric, float), (mr,)).copy()
        if not (np.isfinite(phi_f) and phi_f > 0.0):
            raise ValueError(f"SpringNetwork: friction shape angle phi_f = {phi_f!r} must be > 0")
        self.phi_f = float(phi_f)
        self.f_slip = np.broadcast_to(np.asarray(f_slip, float), (me,)).copy()
        if not (np.isfinite(eps_slip) and eps_slip > 0.0):
            raise ValueError(f"SpringNetwork: slip strain eps_slip = {eps_slip!r} must be > 0")
        self.eps_slip = float(eps_slip)
        self.s_comp = np.broadcast_to(np.asarray(s_comp, float), (me,)).copy()
        self.couplings = couplings
        self.l0 = (
            self.lengths(self.X)
            if l0 is None
            else np.broadcast_to(np.asarray(l0, float), (me,)).copy()
        )
        self.phi0 = (
            self.turning_angles(self.X)
            if phi0 is None
            else np.broadcast_to(np.asarray(phi0, float), (mr,)).copy()
        )
        self._pattern = None

    # ------------------------------------------------------------------ sizes
    @property
    def n_nodes(self) -> int:
        return len(self.X)

    @property
    def n_dofs(self) -> int:
        return 2 * len(self.X)

    # ------------------------------------------------------------ kinematics
    def lengths(self, x: np.ndarray) -> np.ndarray:
        """Spring lengths l [B (8)], shape (m_e,)."""
        d = x[self.ext[:, 1]] - x[self.ext[:, 0]]
        return np.hypot(d[:, 0], d[:, 1])

    def turning_angles(self, x: np.ndarray) -> np.ndarray:
        """Turning angles phi2 - phi1 at the middle nodes [B (14)], in (-pi, pi]."""
        a, b = self._arms(x)
        return np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b))

    def angle_deviations(self, x: np.ndarray) -> np.ndarray:
        """Wrap-safe ``phi2 - phi1 - phi0`` in (-pi, pi] [B (16)]."""
        a, b = self._arms(x)
        c, s = np.cos(self.phi0), np.sin(self.phi0)
        ra = np.stack([c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1]], axis=1)
        return np.arctan2(ra[:, 0] * b[:, 1] - ra[:, 1] * b[:, 0], np.einsum("ij,ij->i", ra, b))

    def _arms(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        i, j, k = self.rot.T
        return x[j] - x[i], x[k] - x[j]

    # ---------------------------------------------------------------- energy
    def spring_energies(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-spring energies (N mm): extensional [B (10)] and rotational [B (16)]."""
        x = np.asarray(x, float).reshape(-1, 2)
        stretch = self.lengths(x) - self.l0
        ee = 0.5 * self.k_ext * (1.0 - self.s_comp * (stretch < 0.0)) * stretch**2
        s = np.abs(stretch) / (self.l0 * self.eps_slip)  # ln cosh s without overflow
        ee = ee + self.f_slip * self.l0 * self.eps_slip * (
            s + np.log1p(np.exp(-2.0 * s)) - np.log(2.0)
        )
        d = self.angle_deviations(x)
        d2 = d * d
        er = (0.5 * self.k_rot + (0.25 * self.k_rot4 + self.k_rot6 / 6.0 * d2) * d2) * d2
        y = np.abs(d) / self.phi_f  # ln cosh y without overflow
        er = er + self.m_fric * self.phi_f * (y + np.log1p(np.exp(-2.0 * y)) - np.log(2.0))
        if self.couplings is not None:  # the crossing elements' energies on their triples
            er = er + np.bincount(self.couplings.rot_index, self.couplings.energies(x), len(er))
        return ee, er

    def energy(self, x: np.ndarray) -> float:
        """Total potential energy E(q) [B (20)] in N mm."""
        ee, er = self.spring_energies(x)
        return float(ee.sum() + er.sum())

    def _ext_terms(self, x):
        """Unit vectors, lengths, tensions t = E_e'(l) and stiffnesses E_e''(l)."""
        d = x[self.ext[:, 1]] - x[self.ext[:, 0]]
        ell = np.hypot(d[:, 0], d[:, 1])
        ts = np.tanh((ell - self.l0) / (self.l0 * self.eps_slip))
        ke = self.k_ext * (1.0 - self.s_comp * (ell < self.l0))
        t = ke * (ell - self.l0) + self.f_slip * ts
        k = ke + self.f_slip * (1.0 - ts * ts) / (self.l0 * self.eps_slip)
        return d / ell[:, None], ell, t, k

    def _rot_terms(self, x):
        a, b = self._arms(x)
        ga = _perp(a) / np.einsum("ij,ij->i", a, a)[:, None]
        gb = _perp(b) / np.einsum("ij,ij->i", b, b)[:, None]
        dphi = np.concatenate([ga, -ga - gb, gb], axis=1)  # (m_r, 6), [B (15)]
        d = self.angle_deviations(x)
        d2 = d * d
        t = np.tanh(d / self.phi_f)
        moment = (self.k_rot + (self.k_rot4 + self.k_rot6 * d2) * d2) * d + self.m_fric * t
        stiff = (
            self.k_rot
            + (3.0 * self.k_rot4 + 5.0 * self.k_rot6 * d2) * d2
            + self.m_fric * (1.0 - t * t) / self.phi_f
        )  # E_r'(d), E_r''(d)
        return a, b, dphi, moment, stiff

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """Internal generalised forces f = dE/dq [B (11), (17), (22)], shape (n, 2) in N."""
        x = np.asarray(x, float).reshape(-1, 2)
        n = len(x)
        e, _, t, _ = self._ext_terms(x)
        fe = t[:, None] * e  # force on node j; -fe on node i
        _, _, dphi, m, _ = self._rot_terms(x)
        fr = m[:, None] * dphi
        if self.couplings is not None:
            np.add.at(fr, self.couplings.rot_index, self.couplings.element_gradients(x))
        idx = np.concatenate([self.ext[:, 1], self.ext[:, 0], self.rot.T.ravel()])
        g = np.empty((n, 2))
        for c in range(2):
            w = np.concatenate([fe[:, c], -fe[:, c], fr[:, c], fr[:, 2 + c], fr[:, 4 + c]])
            g[:, c] = np.bincount(idx, weights=w, minlength=n)
        return g

    # --------------------------------------------------------------- hessian
    def _element_dofs(self) -> tuple[np.ndarray, np.ndarray]:
        """Node-major dofs of each spring: (m_e, 4) [2i, 2i+1, 2j, 2j+1] and (m_r, 6)."""
        de = (2 * self.ext[:, :, None] + np.arange(2)).reshape(-1, 4)
        return de, (2 * self.rot[:, :, None] + np.arange(2)).reshape(-1, 6)

    def _build_pattern(self) -> None:
        de, dr = self._element_dofs()
        rows = np.concatenate([np.repeat(de, 4, axis=1).ravel(), np.repeat(dr, 6, axis=1).ravel()])
        cols = np.concatenate([np.tile(de, (1, 4)).ravel(), np.tile(dr, (1, 6)).ravel()])
        nd = self.n_dofs
        keys, inv = np.unique(rows * nd + cols, return_inverse=True)
        r, c = keys // nd, keys % nd
        indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=nd))])
        self._pattern = (inv, c.astype(np.int32), indptr.astype(np.int32), len(keys))

    def element_hessians(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Dense spring Hessians: (m_e, 4, 4) extensional and (m_r, 6, 6) rotational."""
        x = np.asarray(x, float).reshape(-1, 2)
        e, ell, t, k = self._ext_terms(x)
        ee = np.einsum("mi,mj->mij", e, e)
        K = k[:, None, None] * ee + (t / ell)[:, None, None] * (_I2 - ee)
        He = np.empty((len(K), 4, 4))
        He[:, :2, :2] = He[:, 2:, 2:] = K
        He[:, :2, 2:] = He[:, 2:, :2] = -K
        a, b, dphi, m, kappa = self._rot_terms(x)
        Ha, Hb = _hess_theta(a), _hess_theta(b)
        d2 = np.zeros((len(Ha), 6, 6))  # second derivative of phi [B (15)]
        d2[:, :2, :2] = d2[:, 2:4, 2:4] = -Ha
        d2[:, :2, 2:4] = d2[:, 2:4, :2] = Ha
        d2[:, 2:4, 2:4] += Hb
        d2[:, 4:, 4:] = Hb
        d2[:, 2:4, 4:] = d2[:, 4:, 2:4] = -Hb
        Hr = kappa[:, None, None] * np.einsum("mi,mj->mij", dphi, dphi) + m[:, None, None] * d2
        if self.couplings is not None:
            np.add.at(Hr, self.couplings.rot_index, self.couplings.element_hessians(x))
        return He, Hr

    def hessian(self, x: np.ndarray) -> sp.csr_matrix:
        """Sparse Hessian d2E/dq2 (scipy CSR, 2n x 2n, node-major dofs)."""
        if self._pattern is None:
            self._build_pattern()
        inv, indices, indptr, nnz = self._pattern
        He, Hr = self.element_hessians(x)
        data = np.bincount(inv, weights=np.concatenate([He.ravel(), Hr.ravel()]), minlength=nnz)
        return sp.csr_matrix((data, indices, indptr), shape=(self.n_dofs, self.n_dofs))
