"""Dispersion of discrete chains/lattices against (gradient) continua (Mühlhaus & Oka 1996 §2,
docs/theory.md).

Notation (Mühlhaus & Oka 1996 §2): a chain of point masses m, springs k, spacing D; c0² = kD²/m.
Plane waves u_j = A exp iq(jD - v_p t) give the exact discrete relation (eq. 12)

    ω² = (2k/m)(1 - cos qD),   v_p²/c0² = 2(1 - cos qD)/(qD)² = Σ_n 2(-1)ⁿ(qD)²ⁿ/(2n+2)!,

and the continuum of eq. (10), truncated after the ∂², ∂⁴, ∂⁶ terms, gives the first one, two,
three terms of that series (eqs. 14, 15). As an energy per unit length (Mühlhaus & Oka 1996
footnote, eq. 20)
the truncated continuum reads ½∫ a u'² + b u''² + c u'''² with (a, b, c) = kD(1, -D²/12, D⁴/360):
b < 0 is the destabilising D²/12 term, c > 0 restores well-posedness.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI


def omega2_chain(qD: np.ndarray, k: float = 1.0, m: float = 1.0) -> np.ndarray:
    """Exact discrete dispersion ω² = (2k/m)(1 - cos qD) of the linear chain (Mühlhaus & Oka 1996
    eq. 12)."""
    return 2.0 * k / m * (1.0 - np.cos(qD))


def vp2_exact(qD: np.ndarray) -> np.ndarray:
    """Normalised phase velocity² v_p²/c0² = 2(1 - cos qD)/(qD)² (Mühlhaus & Oka 1996 eqs. 12,
    14)."""
    x = np.asarray(qD, dtype=float)
    return np.sinc(x / (2.0 * np.pi)) ** 2  # = 4 sin²(x/2)/x² = 2(1 - cos x)/x²


def series_coefficients(order: int) -> list[float]:
    """Coefficients 2(-1)ⁿ/(2n+2)! of (qD)²ⁿ kept by the ∂^order continuum (eqs. 10, 15)."""
    if order not in (2, 4, 6, 8):
        raise ValueError(f"order must be 2, 4, 6 or 8, got {order}")
    return [2.0 * (-1) ** n / math.factorial(2 * n + 2) for n in range(order // 2)]


def vp2_truncated(qD: np.ndarray, order: int) -> np.ndarray:
    """v_p²/c0² of the continuum truncated at ∂^order: 1 - (qD)²/12 + (qD)⁴/360 … (eq. 15)."""
    x2 = np.asarray(qD, dtype=float) ** 2
    return sum(c * x2**n for n, c in enumerate(series_coefficients(order)))


def gradient_moduli(order: int, k: float = 1.0, D: float = 1.0) -> tuple[float, float, float]:
    """Moduli (a, b, c) of ½∫a u'² + b u''² + c u'''² per unit length (eqs. 10, 20).

    Euler-Lagrange: rho ü = a u'' - b u'''' + c u⁽⁶⁾, so b = -kD³/12 reproduces the + D²/12 ∂⁴
    term of eq. (10) with the destabilising sign of the footnote, and c = kD⁵/360 the ∂⁶ term.
    """
    coef = series_coefficients(order) + [0.0] * (3 - order // 2)
    return k * D * coef[0], k * D**3 * coef[1], k * D**5 * coef[2]


def fixed_chain_wavenumbers(N: int, D: float = 1.0) -> np.ndarray:
    """Wavenumbers q_n = nπ/((N+1)D), n = 1..N, of a chain of N masses with fixed ends."""
    return np.arange(1, N + 1) * np.pi / ((N + 1) * D)


def chain_modes(N: int, k: float = 1.0, m: float = 1.0, D: float = 1.0) -> np.ndarray:
    """ω² of the N masses of a fixed-fixed chain, from the network engine's Hessian.

    Nodes 0 and N+1 are clamped; the stiffness of the longitudinal dofs is the Hessian of the
    spring network (docs/network.md) at the reference state. Eigenvalues are ascending, so entry n-1
    belongs to q_n = nπ/((N+1)D) and should equal eq. (12) of Mühlhaus & Oka 1996.
    """
    from fabricsurf.network.engine import SpringNetwork

    X = np.column_stack([np.arange(N + 2) * D, np.zeros(N + 2)])
    net = SpringNetwork(X, np.column_stack([np.arange(N + 1), np.arange(1, N + 2)]), k)
    dofs = 2 * np.arange(1, N + 1)
    K = net.hessian(X)[dofs][:, dofs].toarray()
    return scipy.linalg.eigvalsh(K) / m


def fabric_omega2(q: np.ndarray, k2: float, A: float, rho: float = 1.0) -> np.ndarray:
    """rho ω² = k q² + A q⁴ along a fibre: (k_l, A_s) longitudinal, (k_s, A_g) transverse."""
    return (k2 * q**2 + A * q**4) / rho


def hencky_omega2(
    q: np.ndarray, eps: float, k2: float, A: float = 0.0, rho: float = 1.0
) -> np.ndarray:
    """Hencky lattice along a fibre: rho ω² = k (2/ε)² sin²(qε/2) + A (2/ε)⁴ sin⁴(qε/2).

    The discrete analogue of :func:`fabric_omega2` (eq. 12 of Mühlhaus & Oka 1996 for each spring
    family):
    (k_l, 0) longitudinal, (k_s, A_g) transverse, with k_l = k_e, k_s = k_sh/ε², A_g = k_b.
    """
    s2 = (2.0 / eps * np.sin(0.5 * q * eps)) ** 2
    return (k2 * s2 + A * s2**2) / rho


def departure_point(x: np.ndarray, ratio: np.ndarray, tol: float = 0.01) -> float:
    """First x where |ratio - 1| exceeds tol (linear interpolation); inf if it never does."""
    dev = np.abs(np.asarray(ratio) - 1.0) - tol
    idx = np.flatnonzero(dev > 0)
    if idx.size == 0:
        return math.inf
    i = int(idx[0])
    if i == 0:
        return float(x[0])
    return float(x[i - 1] - dev[i - 1] * (x[i] - x[i - 1]) / (dev[i] - dev[i - 1]))


def fit_order(x: np.ndarray, err: np.ndarray) -> float:
    """Least-squares slope of log|err| against log x: the measured order of an error in qD."""
    return float(np.polyfit(np.log(x), np.log(np.abs(err)), 1)[0])


def bloch_omega2(
    H: sp.spmatrix, X: np.ndarray, i0: int, q: np.ndarray, e: np.ndarray, mass: float
) -> tuple[np.ndarray, np.ndarray]:
    """Longitudinal and transverse ω²(q) of a 2D lattice from its Hessian (Bloch analysis).

    For a wave u_j = U exp(iq e·X_j), uniform across the fibres normal to e, the dynamical matrix
    of an interior node i0 is Σ_j H[i0, j] exp(iq e·(X_j - X_i0)) (2x2 blocks of the Hessian
    rows of i0). Projections on e and on e rotated +90° give ω² for the two polarisations.
    """
    rows = sp.csr_matrix(H)[2 * i0 : 2 * i0 + 2].tocoo()
    phase = (X[rows.col // 2] - X[i0]) @ e
    t = np.array([-e[1], e[0]])
    pair = [np.outer(e, e), np.outer(t, t)]
    out = []
    for P in pair:
        w = P[rows.row, rows.col % 2]
        out.append(np.array([np.sum(w * rows.data * np.cos(qq * phase)) for qq in q]) / mass)
    return out[0], out[1]


class GradientContinuum1D:
    """Modes of ½∫ a u'² + b u''² + c u'''² on (0, L), u = 0 at both ends, with dolfinx.

    Second and third derivatives are broken (cellwise); C0-IP terms on interior points (as in
    dolfinx's demo_biharmonic) make the b-term consistent, symmetric-interior-penalty terms on
    the jumps of u' and u'' the c-term. u'' = 0 at the ends is imposed by Nitsche's method for
    the c-term; for c = 0 it is the natural condition. Sines sin(nπx/L) are then exact modes,
    with rho ω² = a q² + b q⁴ + c q⁶ (Mühlhaus & Oka 1996 eqs. 10, 15). Moduli live in fem.Constant.

    With b < 0 the b-penalty is negative too; for c > 0 the c-penalty must dominate it,
    h² < c·s0/(|b|·s1) (h < 0.9 D for the moduli of Mühlhaus & Oka 1996 and degree 5), else spurious
    negative modes appear. Low modes are accurate to round-off, about eps·max|λ|/ω_1².
    """

    def __init__(self, comm: MPI.Comm, L: float, n_cells: int, degree: int = 4) -> None:
        self.comm, self.L = comm, L
        self.msh = mesh.create_interval(comm, n_cells, [0.0, L])
        self.V = fem.FunctionSpace(self.msh, ("Lagrange", degree))
        c = {s: fem.Constant(self.msh, 0.0) for s in ("a", "b", "c", "rho")}
        self.const = c
        u, v = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        n, h = ufl.FacetNormal(self.msh)[0], ufl.CellDiameter(self.msh)
        md = {"quadrature_degree": 2 * degree}
        dx, dS, ds = ufl.dx(metadata=md), ufl.dS(metadata=md), ufl.ds(metadata=md)
        s1, s0 = 4.0 * degree**2, 4.0 * degree**4  # penalties on [u''] (1/h), [u'] (1/h³)

        def d(w, j):
            for _ in range(j):
                w = w.dx(0)
            return w

        def jmp(w):  # = -(w_right - w_left) for any scalar w
            return w("+") * n("+") + w("-") * n("-")

        def ip(j):  # consistency + symmetry terms for ∫ d^j u d^j v with d^(j-1) broken
            t = -(ufl.avg(d(u, j)) * jmp(d(v, j - 1)) + ufl.avg(d(v, j)) * jmp(d(u, j - 1)))
            if j == 3:
                t += ufl.avg(d(u, 4)) * jmp(d(v, 1)) + ufl.avg(d(v, 4)) * jmp(d(u, 1))
            return t

        hf = ufl.avg(h)
        Kb = d(u, 2) * d(v, 2) * dx + (ip(2) + s1 / hf * jmp(d(u, 1)) * jmp(d(v, 1))) * dS
        Kc = (
            d(u, 3) * d(v, 3) * dx
            + (
                ip(3)
                + s1 / hf * jmp(d(u, 2)) * jmp(d(v, 2))
                + s0 / hf**3 * jmp(d(u, 1)) * jmp(d(v, 1))
            )
            * dS
            + (-(d(u, 3) * d(v, 2) + d(v, 3) * d(u, 2)) * n + s1 / h * d(u, 2) * d(v, 2)) * ds
        )
        self.K = fem.form(c["a"] * d(u, 1) * d(v, 1) * dx + c["b"] * Kb + c["c"] * Kc)
        self.M = fem.form(c["rho"] * u * v * dx)
        imap = self.V.dofmap.index_map
        self.r0, self.r1 = imap.local_range
        x = self.V.tabulate_dof_coordinates()[: self.r1 - self.r0, 0]
        xs = comm.gather(x, root=0)
        self.x = np.concatenate(xs) if comm.rank == 0 else None
        bd = fem.locate_dofs_geometrical(
            self.V, lambda p: np.isclose(p[0], 0.0) | np.isclose(p[0], L)
        )
        bd = imap.local_to_global(bd[bd < self.r1 - self.r0].astype(np.int32))
        bds = comm.gather(bd, root=0)
        self.bdofs = np.unique(np.concatenate(bds)) if comm.rank == 0 else None

    def _gather(self, form: fem.FormMetaClass) -> sp.csr_matrix | None:
        A = fem_petsc.assemble_matrix(form)
        A.assemble()
        r0, r1 = A.getOwnershipRange()
        ai, aj, av = A.getValuesCSR()
        rows = np.repeat(np.arange(r0, r1), np.diff(ai))
        parts = self.comm.gather((rows, aj, av), root=0)
        A.destroy()
        if self.comm.rank != 0:
            return None
        r, cc, vv = (np.concatenate([p[i] for p in parts]) for i in range(3))
        n = self.V.dofmap.index_map.size_global
        return sp.csr_matrix((vv, (r, cc)), shape=(n, n))

    def modes(
        self, a: float, b: float, c: float, rho: float, n_modes: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Solve K v = ω² M v (dense, rank 0) and pick the mode closest to each sin(nπx/L).

        Returns (ω² of modes n = 1..n_modes, their overlaps with the sines in the M-norm,
        all eigenvalues, eigenvectors of the picked modes in global dof order); same on all ranks.
        """
        for s, val in zip(("a", "b", "c", "rho"), (a, b, c, rho)):
            self.const[s].value = val
        K, M = self._gather(self.K), self._gather(self.M)
        res = None
        if self.comm.rank == 0:
            free = np.setdiff1d(np.arange(K.shape[0]), self.bdofs)
            Kf, Mf = K[free][:, free].toarray(), M[free][:, free].toarray()
            lam, phi = scipy.linalg.eigh(0.5 * (Kf + Kf.T), 0.5 * (Mf + Mf.T))
            q = np.arange(1, n_modes + 1) * np.pi / self.L
            S = np.sin(np.outer(self.x[free], q))
            S /= np.sqrt(np.einsum("in,ij,jn->n", S, Mf, S))
            ov = S.T @ Mf @ phi
            pick = np.argmax(np.abs(ov), axis=1)
            ovp = ov[np.arange(n_modes), pick]
            vecs = np.zeros((n_modes, K.shape[0]))
            vecs[:, free] = phi[:, pick].T * np.sign(ovp)[:, None]  # same sign as the sine
            res = (lam[pick], np.abs(ovp), lam, vecs)
        return self.comm.bcast(res, root=0)

    def function(self, vec: np.ndarray) -> fem.Function:
        """A dolfinx Function with the owned entries of a global dof vector (e.g. a mode)."""
        f = fem.Function(self.V)
        f.x.array[: self.r1 - self.r0] = vec[self.r0 : self.r1]
        f.x.scatter_forward()
        return f
