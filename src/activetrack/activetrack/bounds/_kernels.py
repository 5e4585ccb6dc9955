"""Compiled PCRLB pieces for stacks of small matrices (the planner scores hundreds per call):
:func:`predicted_stack`, (Q + F J^{-1} F^T)^{-1} of Hernandez eq. 3 by the Cholesky steps of
the numpy form, and :func:`rmse_bounds`, eq. 10 by one LU factorisation with partial pivoting
and two solves per J, as ``numpy.linalg.solve`` (dgesv). Equal to numpy to round-off (tested
to 1e-12). numba compiles on first use and caches next to this file (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.kernels.linalg import cholesky_into

__all__ = ["predicted_stack", "rmse_bounds", "warm_up"]


@numba.njit(cache=True, nogil=True)
def _solve_columns(A: FloatArray, perm: np.ndarray, z: FloatArray, out: FloatArray) -> bool:
    """x = A^{-1} e_0 and y = A^{-1} e_2 for one n x n A (overwritten by its LU factors);
    out = (x[0], y[2]). False if A is singular (a zero pivot). perm, z: work arrays (n,).
    n = 4, a constant, so that the compiler unrolls the loops."""
    n = 4
    for k in range(n):
        perm[k] = k
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(A[i, k]) > abs(A[p, k]):
                p = i
        if A[p, k] == 0.0:
            return False
        if p != k:
            for j in range(n):
                A[k, j], A[p, j] = A[p, j], A[k, j]
            perm[k], perm[p] = perm[p], perm[k]
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            A[i, k] = f
            for j in range(k + 1, n):
                A[i, j] -= f * A[k, j]
    for slot in range(2):
        col = 2 * slot
        for i in range(n):  # forward: L z = P e_col
            s = 1.0 if perm[i] == col else 0.0
            for j in range(i):
                s -= A[i, j] * z[j]
            z[i] = s
        for i in range(n - 1, -1, -1):  # back: U x = z
            s = z[i]
            for j in range(i + 1, n):
                s -= A[i, j] * z[j]
            z[i] = s / A[i, i]
        out[slot] = z[col]
    return True


@numba.njit(cache=True, nogil=True)
def rmse_bounds(J: FloatArray) -> tuple[FloatArray, int]:
    """b_k = sqrt(max((J^{-1})(1,1), (J^{-1})(3,3))) of each of N matrices ``(N, 4, 4)``:
    ``(N,)`` and a status: 0, or 1 if a J is singular, 2 if a variance is not positive."""
    N = J.shape[0]
    out = np.empty(N)
    n = 4
    A = np.empty((n, n))
    perm = np.empty(n, dtype=np.int64)
    z = np.empty(n)
    var = np.empty(2)
    for m in range(N):
        A[:, :] = J[m]
        if not _solve_columns(A, perm, z, var):
            return out, 1
        v = max(var[0], var[1])
        if not v > 0.0:  # NaN too, as the numpy form
            return out, 2
        out[m] = np.sqrt(v)
    return out, 0


@numba.njit(cache=True, nogil=True)
def _lower_inverse(L: FloatArray, out: FloatArray) -> None:
    """L^{-1} of a lower-triangular n x n L (forward substitution on the identity)."""
    n = L.shape[0]
    out[:, :] = 0.0
    for c in range(n):
        for i in range(c, n):
            s = 1.0 if i == c else 0.0
            for k in range(c, i):
                s -= L[i, k] * out[k, c]
            out[i, c] = s / L[i, i]


@numba.njit(cache=True, nogil=True)
def predicted_stack(J: FloatArray, F: FloatArray, Q: FloatArray) -> tuple[FloatArray, int]:
    """(Q + F J_m^{-1} F^T)^{-1} for N information matrices J ``(N, n, n)``: ``(N, n, n)`` and a
    status: 0, 1 if a J is not positive definite, 2 if a Q + F J^{-1} F^T is not.

    With L L^T = J and X = L^{-1} F^T: F J^{-1} F^T = X^T X; C = Q + X^T X = M M^T and
    C^{-1} = M^{-T} M^{-1}."""
    N, n = J.shape[0], J.shape[1]
    out = np.empty((N, n, n))
    L = np.empty((n, n))
    Li = np.empty((n, n))
    X = np.empty((n, n))
    C = np.empty((n, n))
    for m in range(N):
        if not cholesky_into(J[m], L):
            return out, 1
        _lower_inverse(L, Li)
        for i in range(n):  # X = L^{-1} F^T
            for j in range(n):
                s = 0.0
                for k in range(n):
                    s += Li[i, k] * F[j, k]
                X[i, j] = s
        for i in range(n):  # C = Q + X^T X
            for j in range(n):
                s = 0.0
                for k in range(n):
                    s += X[k, i] * X[k, j]
                C[i, j] = Q[i, j] + s
        if not cholesky_into(C, L):
            return out, 2
        _lower_inverse(L, Li)
        for i in range(n):  # C^{-1} = Li^T Li, symmetric by construction
            for j in range(i + 1):
                s = 0.0
                for k in range(n):
                    s += Li[k, i] * Li[k, j]
                out[m, i, j] = s
                out[m, j, i] = s
    return out, 0


def warm_up() -> None:
    """Compile (or load) the kernels of this module (``activetrack.kernels.warm_up``)."""
    J = np.eye(4)[None].copy()
    rmse_bounds(J)
    predicted_stack(J, np.eye(4), np.eye(4))
