"""Linear algebra of tall residual Jacobians in O(N·p) memory (docs/uncertainty.md, "Scale").

A fit has N residuals (10⁵–10⁶ for a DIC field) and p moduli (a few): nothing here forms an
N × N array. The R factor of the thin QR decomposition J = QR is built block by block (the
tall-skinny QR: R = qr([R; J_block]) over blocks of :data:`CHUNK` rows), so LAPACK never needs
more than a block's workspace; R (p × p) has J's singular values and right singular vectors, and
RᵀR = JᵀJ without squaring J's condition number.

Every result is checked: numpy's LAPACK wrappers answer a workspace they cannot allocate (under
a memory limit: ``init_gesdd failed init``) by leaving the output unwritten or NaN, without an
exception. A non-finite result, or an R whose Frobenius norm is not J's (an orthogonal
factor preserves it), raises :class:`NumericalError` naming the computation.
"""

from __future__ import annotations

import numpy as np

CHUNK = 1 << 15
"""Rows per block of the tall-skinny QR (a block of 32 768 × p doubles: ¼ MB per modulus)."""

NORM_TOL = 1e-8
"""The largest relative difference between ‖R‖_F and ‖J‖_F accepted from the QR."""


class NumericalError(RuntimeError):
    """A linear-algebra routine failed or returned non-finite numbers."""


def finite(x: np.ndarray, what: str) -> np.ndarray:
    """``x``, after checking that every entry is finite (else :class:`NumericalError`)."""
    a = np.asarray(x)
    if not np.isfinite(a).all():
        bad = int(np.count_nonzero(~np.isfinite(a)))
        raise NumericalError(
            f"{what}: {bad} of {a.size} entries are NaN or infinite (a linear-algebra routine "
            "failed, e.g. LAPACK could not allocate its workspace under a memory limit, or the "
            "residuals or sensitivities are not finite)"
        )
    return x


def r_factor(J: np.ndarray, what: str = "QR of the Jacobian") -> np.ndarray:
    """The R factor (k × p, k = min(N, p)) of J = QR, by blocks of :data:`CHUNK` rows (module
    docstring); checked finite and norm-preserving."""
    n, p = J.shape
    finite(J, what + " (its input)")
    R = np.zeros((0, p))
    for start in range(0, n, CHUNK):
        R = np.linalg.qr(np.vstack([R, J[start : start + CHUNK]]), mode="r")
    finite(R, what)
    nJ, nR = float(np.linalg.norm(J)), float(np.linalg.norm(R))
    if abs(nR - nJ) > NORM_TOL * max(nJ, 1e-300):
        raise NumericalError(
            f"{what}: the R factor has norm {nR:.6g}, the Jacobian {nJ:.6g} "
            "(LAPACK returned an unwritten or wrong result)"
        )
    return R


def thin_q(J: np.ndarray, what: str) -> np.ndarray:
    """The N × k orthonormal factor Q of the thin QR decomposition of J (O(N·p) memory), checked
    finite and orthonormal in trace (‖Q‖_F² = k)."""
    Q = finite(np.linalg.qr(finite(J, what + " (its input)"))[0], what)
    k = Q.shape[1]
    if abs(float(np.sum(Q * Q)) - k) > NORM_TOL * max(k, 1):
        raise NumericalError(
            f"{what}: the Q factor is not orthonormal (LAPACK returned an "
            "unwritten or wrong result)"
        )
    return Q


def off_span(J: np.ndarray | None, v: np.ndarray, what: str) -> np.ndarray:
    """``v`` without its part in the span of ``J``'s columns (``v`` itself when J has none):
    what a least-squares refit in J's parameters leaves of a change of the data
    (:func:`thin_q`)."""
    if J is None or J.shape[1] == 0:
        return v
    Q = thin_q(J, what)
    return v - Q @ (Q.T @ v)


def right_singular(
    J: np.ndarray, what: str = "SVD of the Jacobian"
) -> tuple[np.ndarray, np.ndarray]:
    """(σ, Vᵀ): J's p singular values (zeros appended when N < p), largest first, and its right
    singular vectors (rows of the p × p Vᵀ), from the SVD of :func:`r_factor`."""
    p = J.shape[1]
    R = r_factor(J, what)
    R = np.vstack([R, np.zeros((p - R.shape[0], p))])
    _, sv, Vt = np.linalg.svd(R)
    finite(sv, what)
    finite(Vt, what)
    return sv, Vt


def singular_values(J: np.ndarray, what: str = "SVD of the Jacobian") -> np.ndarray:
    """J's min(N, p) singular values, largest first (:func:`right_singular`)."""
    return right_singular(J, what)[0][: min(J.shape)]


def gram_pinv(J: np.ndarray, what: str = "(JᵀJ)⁺") -> np.ndarray:
    """The pseudo-inverse of the p × p Fisher matrix JᵀJ, checked finite."""
    return finite(np.linalg.pinv(finite(J.T @ J, what)), what)


def pinv(A: np.ndarray, what: str) -> np.ndarray:
    """The pseudo-inverse of a small matrix, checked finite."""
    return finite(np.linalg.pinv(finite(A, what)), what)


def lstsq(A: np.ndarray, b: np.ndarray, what: str) -> np.ndarray:
    """The least-squares solution of A x ≈ b (A tall, N × p), checked finite."""
    return finite(np.linalg.lstsq(finite(A, what), finite(b, what), rcond=None)[0], what)


def eigh(A: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (ascending) and eigenvectors of a small symmetric matrix, checked finite."""
    lam, V = np.linalg.eigh(finite(A, what))
    return finite(lam, what), finite(V, what)


def block_sums(values: np.ndarray, inverse: np.ndarray, groups: int) -> np.ndarray:
    """Σ over the rows of each group: (groups × p) from ``values`` (N × p) and each row's group
    index ``inverse`` (one pass per column, O(N) memory; ``np.add.at`` is ~30× slower)."""
    return (
        np.column_stack(
            [
                np.bincount(inverse, weights=values[:, k], minlength=groups)
                for k in range(values.shape[1])
            ]
        )
        if values.shape[1]
        else np.zeros((groups, 0))
    )
