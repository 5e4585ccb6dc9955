"""Small dense linear algebra shared by the compiled kernels (EKF update, PCRLB prediction)."""

from __future__ import annotations

import math

from numba import njit

__all__ = ["cholesky_into"]


@njit(cache=True, nogil=True, error_model="numpy")
def cholesky_into(A, L) -> bool:  # pragma: no cover - compiled
    """Lower Cholesky factor L (n x n, overwritten) with L L^T = A for one symmetric n x n A;
    False (L undefined) when A is not positive definite (a non-positive or NaN pivot)."""
    n = A.shape[0]
    L[:, :] = 0.0
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            return False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    return True
