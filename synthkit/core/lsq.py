"""Sparse weighted linear least squares with a cached factorization (factor once, solve many).

Minimises ``sum_i w_i (A x - b)_i^2`` through the normal equations ``(A^T W A) x = A^T W b``. The
normal matrix is factored once with SuperLU (``scipy.sparse.linalg.splu``) tuned for a symmetric
positive definite matrix: ``permc_spec="MMD_AT_PLUS_A"`` (minimum degree on A^T + A), no partial
pivoting (``diag_pivot_thresh=0``) and ``SymmetricMode``; a sparse Cholesky (cholespy) would be
faster still but is not a dependency. Every right-hand side then costs two triangular solves.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["LeastSquares", "solve_least_squares"]


class LeastSquares:
    """Factor ``A^T W A`` once for ``A (m, n)`` sparse and solve for many right-hand sides.

    Parameters
    ----------
    A : (m, n) sparse matrix (or dense array), ``m >= n``, full column rank
    weights : (m,) non-negative floats, optional (default all 1)

    Raises ValueError for bad shapes or weights and for a rank-deficient system (the factorization
    finds a zero pivot).
    """

    def __init__(self, A, *, weights=None):
        A = sp.csr_matrix(A, dtype=np.float64)
        m, n = A.shape
        if m == 0 or n == 0:
            raise ValueError(f"A must be non-empty, got shape {A.shape}")
        if weights is None:
            w = np.ones(m)
        else:
            w = np.asarray(weights, dtype=np.float64).reshape(-1)
            if len(w) != m:
                raise ValueError(f"weights must have {m} entries, got {len(w)}")
            if not np.all(np.isfinite(w)) or np.any(w < 0):
                raise ValueError("weights must be finite and non-negative")
        if not np.all(np.isfinite(A.data)):
            raise ValueError("A holds NaN or infinite entries")
        self.shape = (m, n)
        self._AtW = (A.T @ sp.diags(w)).tocsr()
        N = (self._AtW @ A).tocsc()
        try:
            self._lu = splu(
                N,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except RuntimeError as exc:
            raise ValueError(f"normal matrix A^T W A is singular (A is rank deficient): {exc}") from None
        diag = np.abs(self._lu.U.diagonal())
        if diag.min() <= 1e-13 * max(diag.max(), 1e-300):
            raise ValueError("normal matrix A^T W A is numerically singular (A is rank deficient)")

    def solve(self, b) -> np.ndarray:
        """Least-squares solution ``x (n,)`` for ``b (m,)``, or ``X (n, k)`` for ``b (m, k)``."""
        b = np.asarray(b, dtype=np.float64)
        if b.shape[0] != self.shape[0] or b.ndim not in (1, 2):
            raise ValueError(f"b must have shape ({self.shape[0]},) or ({self.shape[0]}, k), got {b.shape}")
        return self._lu.solve(np.asarray(self._AtW @ b))


def solve_least_squares(A, b, *, weights=None) -> np.ndarray:
    """One-shot :class:`LeastSquares` ``(A, weights=weights).solve(b)``."""
    return LeastSquares(A, weights=weights).solve(b)
