"""Linear algebra on the tiny matrices of the per-frame path (n <= 8), compiled.

numba's ``np.linalg`` calls LAPACK through SciPy. On a 5 x 5 matrix the call costs
~3 µs when warm, but 40-70 µs when the frame before it ran other code (another
detector, the rest of a control loop): the library's code and work buffers have
left the caches by then. These loops are a few hundred instructions and allocate
nothing but their result. Accuracy is that of LAPACK for these sizes: partial
pivoting for the solves, one-sided Jacobi (Hestenes) for the null vector.

Two elimination orders share one pivoting step (:func:`_pivot`): Gauss-Jordan
(:func:`solve`, :func:`inverse`; the clipped-edge fit and the pose covariance) and
forward elimination with back substitution (:func:`solve_augmented`; the exact pose's
Gauss-Newton steps, which must detect a singular system rather than raise). Both are
exact in exact arithmetic; in floating point they differ in the last bits, and each
caller keeps the order its recorded results were computed with.
"""
from __future__ import annotations

import math

import numpy as np

from localizer._jit import inline, jit


@jit
def solve(A, b):
    """``x`` (n,) with ``A x = b`` for ``A`` (n, n), ``b`` (n,), by Gaussian elimination with
    partial pivoting (neither input is changed). An exactly singular ``A`` raises
    ``ZeroDivisionError``."""
    n = b.size
    M = np.empty((n, n + 1))
    for i in range(n):  # element by element: localizer._kernels.arrays says why
        for j in range(n):
            M[i, j] = A[i, j]
        M[i, n] = b[i]
    _eliminate(M, n, np.int64(1))  # typed int64, not Literal[int](1): one compiled _eliminate
    return M[:, n].copy()


@jit
def inverse(A):
    """``A^-1`` (n, n) by Gauss-Jordan elimination with partial pivoting (``A`` is not
    changed). An exactly singular ``A`` raises ``ZeroDivisionError``."""
    n = A.shape[0]
    M = np.zeros((n, 2 * n))
    for i in range(n):
        for j in range(n):
            M[i, j] = A[i, j]
        M[i, n + i] = 1.0
    _eliminate(M, n, n)
    return M[:, n:].copy()


@inline
def _pivot(M, k, n, ncols):
    """Partial pivoting at column ``k`` of ``M`` (n, ncols): swap into row ``k`` the first row
    ``>= k`` of largest ``|M[i, k]|`` (all ``ncols`` columns)."""
    piv = k
    for i in range(k + 1, n):
        if abs(M[i, k]) > abs(M[piv, k]):
            piv = i
    if piv != k:
        for c in range(ncols):
            M[k, c], M[piv, c] = M[piv, c], M[k, c]


@jit
def _eliminate(M, n, m):
    """Reduce the augmented ``M`` (n, n + m) in place to ``[I | A^-1 B]`` (Gauss-Jordan)."""
    for k in range(n):
        _pivot(M, k, n, n + m)
        d = M[k, k]
        for c in range(k, n + m):
            M[k, c] /= d
        for i in range(n):
            if i != k:
                f = M[i, k]
                if f != 0.0:
                    for c in range(k, n + m):
                        M[i, c] -= f * M[k, c]


@inline
def solve_augmented(M, x):
    """Solve the augmented system ``M = [A | b]`` (n, n + 1) by Gaussian elimination with
    partial pivoting (``M`` is overwritten) and back substitution into ``x`` (n,).

    Returns False, with ``x`` unchanged, when a pivot is exactly zero (a singular ``A``);
    nothing is allocated, so that an iteration can reuse ``M`` and ``x``.
    """
    n = M.shape[0]
    for k in range(n):
        _pivot(M, k, n, n + 1)
        if M[k, k] == 0.0:
            return False
        for i in range(k + 1, n):
            f = M[i, k] / M[k, k]
            for m in range(k, n + 1):
                M[i, m] -= f * M[k, m]
    for k in range(n - 1, -1, -1):
        acc = M[k, n]
        for m in range(k + 1, n):
            acc -= M[k, m] * x[m]
        x[k] = acc / M[k, k]
    return True


@jit
def null_vector(A, sweeps=30):
    """Unit right singular vector (n,) of ``A`` (m, n), m >= n, for its smallest singular
    value: the least-squares solution of ``A v = 0``, ``|v| = 1`` (what
    ``np.linalg.svd(A)[2][-1]`` gives, up to sign).

    One-sided Jacobi: plane rotations ``V`` orthogonalise the columns of ``A V``; their
    norms are then the singular values and ``V``'s columns the right singular vectors.
    """
    m, n = A.shape
    U = A.copy()
    V = np.eye(n)
    for _ in range(sweeps):
        off = 0.0
        for p in range(n - 1):
            for q in range(p + 1, n):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for i in range(m):
                    alpha += U[i, p] * U[i, p]
                    beta += U[i, q] * U[i, q]
                    gamma += U[i, p] * U[i, q]
                if gamma == 0.0 or abs(gamma) <= 1e-15 * math.sqrt(alpha * beta):
                    continue
                off = max(off, abs(gamma) / math.sqrt(alpha * beta))
                zeta = (beta - alpha) / (2.0 * gamma)
                t = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for i in range(m):
                    up, uq = U[i, p], U[i, q]
                    U[i, p] = c * up - s * uq
                    U[i, q] = s * up + c * uq
                for i in range(n):
                    vp, vq = V[i, p], V[i, q]
                    V[i, p] = c * vp - s * vq
                    V[i, q] = s * vp + c * vq
        if off <= 1e-15:
            break
    best = 0
    best_norm = np.inf
    for j in range(n):
        nj = 0.0
        for i in range(m):
            nj += U[i, j] * U[i, j]
        if nj < best_norm:
            best_norm = nj
            best = j
    return V[:, best].copy()
