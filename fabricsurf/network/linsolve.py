"""Sparse direct solves of lattice Hessians with a geometric nested-dissection ordering.

SuperLU's built-in column orderings (COLAMD, MMD) give heavy fill on 2D lattices (e.g.
8.5M factor entries for 20k dofs). Lattices come with node coordinates, so a nested
dissection is cheap: split the node set at the median of its longer extent, take as
separator the nodes of one half coupled (in the Hessian graph) to the other half, recurse,
and number separators last. The permuted matrix is then factorised by
PETSc's MUMPS (petsc4py, a platform package; its own fill-reducing ordering) when available,
otherwise by ``scipy.sparse.linalg.splu`` with the ``NATURAL`` ordering and diagonal pivoting.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

_LEAF = 64


def node_graph(H: sp.csr_matrix) -> sp.csr_matrix:
    """Node adjacency (n x n, boolean pattern) of a node-major 2-dof Hessian."""
    n = H.shape[0] // 2
    Hc = H.tocoo()
    return sp.csr_matrix((np.ones(len(Hc.row), bool), (Hc.row // 2, Hc.col // 2)), shape=(n, n))


def nested_dissection(xy: np.ndarray, graph: sp.csr_matrix) -> np.ndarray:
    """Elimination order of the nodes (a permutation) by geometric nested dissection."""
    out: list[np.ndarray] = []
    seps: list[tuple[int, np.ndarray]] = []
    stack = [(np.arange(len(xy)), 0)]
    while stack:
        idx, depth = stack.pop()
        if len(idx) <= _LEAF:
            out.append(idx)
            continue
        ext = xy[idx].max(0) - xy[idx].min(0)
        c = xy[idx, int(np.argmax(ext))]
        right = c > np.median(c)
        if right.all() or not right.any():
            out.append(idx)
            continue
        sub = graph[idx][:, idx]
        touches = (sub @ right.astype(np.float64)) > 0
        sep = ~right & touches
        seps.append((depth, idx[sep]))
        stack.append((idx[right], depth + 1))
        stack.append((idx[~right & ~sep], depth + 1))
    # leaves first (in discovery order), then separators from the deepest to the root
    seps.sort(key=lambda s: -s[0])
    return np.concatenate(out + [s for _, s in seps])


class MumpsLU:
    """Symmetric (LDLᵀ, indefinite allowed) factorisation of a lattice Hessian block with MUMPS
    on one process — cheaper than its LU on the benchmark lattice (docs/network.md); ``solve(b)``
    like splu. Its PETSc objects live on one process, so :meth:`close` (also run when it goes)
    is safe at any time."""

    def __init__(self, A: sp.spmatrix) -> None:
        from petsc4py import PETSc

        A = sp.csr_matrix(A)
        it = PETSc.IntType
        self.mat = PETSc.Mat().createAIJ(
            size=A.shape,
            comm=PETSc.COMM_SELF,
            csr=(A.indptr.astype(it), A.indices.astype(it), A.data),
        )
        self.ksp = PETSc.KSP().create(PETSc.COMM_SELF)
        self.ksp.setOperators(self.mat)
        self.ksp.setType("preonly")
        pc = self.ksp.getPC()
        self.mat.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        pc.setType("cholesky")
        pc.setFactorSolverType("mumps")
        self.ksp.setUp()
        self.x, self.b = self.mat.createVecs()

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.b.array[:] = b
        self.ksp.solve(self.b, self.x)
        return self.x.array.copy()

    def close(self) -> None:
        """Destroy the factorisation, the matrix and the work vectors."""
        for obj in (self.ksp, self.mat, self.x, self.b):
            if obj.handle:
                obj.destroy()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # a fallback at teardown must never raise
            pass


def factorise(A: sp.spmatrix):
    """MUMPS if petsc4py has it, else SuperLU (natural order on the pre-permuted matrix)."""
    try:
        return MumpsLU(A)
    except (ImportError, RuntimeError):
        return spla.splu(
            sp.csc_matrix(A),
            permc_spec="NATURAL",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )


class FreeDofSolver:
    """Solve the free-free block of Hessians with a fixed sparsity pattern.

    The ordering is computed once (per network and constrained set). The LU factors are
    kept and reused as a preconditioner of GMRES on later Hessians (a lagged Jacobian);
    when GMRES needs more than ``max_krylov`` iterations to reach ``rtol`` the block is
    refactorised. ``stats`` counts factorisations and Krylov iterations.
    """

    def __init__(
        self,
        X: np.ndarray,
        H: sp.csr_matrix,
        free: np.ndarray,
        reuse: bool = True,
        rtol: float = 1e-10,
        max_krylov: int = 25,
    ) -> None:
        order = nested_dissection(np.asarray(X, float), node_graph(H))
        dofs = np.stack([2 * order, 2 * order + 1], 1).ravel()
        self.perm = dofs[free[dofs]]  # free dofs in elimination order
        self.free = free
        self.reuse, self.rtol, self.max_krylov = reuse, rtol, max_krylov
        self.lu = None
        self.stats = {"factorisations": 0, "krylov_iterations": 0}

    def _factorise(self, A: sp.csc_matrix) -> None:
        if isinstance(self.lu, MumpsLU):
            self.lu.close()
        self.lu = factorise(A)
        self.stats["factorisations"] += 1

    def solve(self, H: sp.csr_matrix, rhs_free: np.ndarray) -> np.ndarray:
        """Solve H_ff dx = rhs (rhs and result indexed like ``H[free]``)."""
        fidx = np.nonzero(self.free)[0]
        pos = np.empty(len(self.free), np.int64)
        pos[fidx] = np.arange(len(fidx))
        p = pos[self.perm]
        A = H[self.perm][:, self.perm].tocsc()
        b = rhs_free[p]
        y = None
        if self.reuse and self.lu is not None:
            its = [0]

            def count(_):
                its[0] += 1

            M = spla.LinearOperator(A.shape, matvec=self.lu.solve)
            y, info = spla.gmres(
                A,
                b,
                tol=self.rtol,
                atol=0.0,
                restart=self.max_krylov,
                maxiter=1,
                M=M,
                callback=count,
                callback_type="pr_norm",
            )
            self.stats["krylov_iterations"] += its[0]
            if info != 0:
                y = None
        if y is None:
            self._factorise(A)
            y = self.lu.solve(b)
        out = np.empty_like(rhs_free)
        out[p] = y
        return out
