"""numba kernels of the EKF step (``filters.ekf.ExtendedKalmanFilter``): the small-matrix
algebra of one prediction and one sequential update, each in one call instead of a dozen numpy
calls on 4 x 4 arrays (the numpy version spends most of its ~20 us in call overhead).

Same equations as the numpy path (Valverde eq. 2-4; Ramdaras eq. 16-22 with the Joseph form),
summed in loop order where numpy's matmul may use BLAS's order or fused multiply-adds: the
results agree to round-off (tests/core/test_pf_kernels.py), not to the bit, which is why these
kernels run only with ``ACTIVETRACK_KERNELS=compiled`` (``activetrack.kernels``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from activetrack.kernels.linalg import cholesky_into

__all__ = ["predict", "update", "warm_up"]


@njit(cache=True, error_model="numpy")
def predict(x, P, F, Q):  # pragma: no cover - compiled
    """``(F x, sym(F P F^T + Q))`` with sym(A) = (A + A^T) / 2."""
    n = x.shape[0]
    xn = np.zeros(n)
    FP = np.zeros((n, n))
    for i in range(n):
        for k in range(n):
            f = F[i, k]
            xn[i] += f * x[k]
            for j in range(n):
                FP[i, j] += f * P[k, j]
    Pn = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += FP[i, k] * F[j, k]
            Pn[i, j] = acc + Q[i, j]
    _symmetrize(Pn)
    return xn, Pn


@njit(cache=True, error_model="numpy")
def _symmetrize(A):  # pragma: no cover - compiled
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (A[i, j] + A[j, i])
            A[i, j] = v
            A[j, i] = v


@njit(cache=True, error_model="numpy")
def _chol_solve(L, b):  # pragma: no cover - compiled
    """S^-1 b for S = L L^T, b ``(m,)``."""
    m = L.shape[0]
    y = np.empty(m)
    for i in range(m):
        v = b[i]
        for k in range(i):
            v -= L[i, k] * y[k]
        y[i] = v / L[i, i]
    out = np.empty(m)
    for i in range(m - 1, -1, -1):
        v = y[i]
        for k in range(i + 1, m):
            v -= L[k, i] * out[k]
        out[i] = v / L[i, i]
    return out


@njit(cache=True, error_model="numpy")
def update(x, P, H, nu, R):  # pragma: no cover - compiled
    """One detection (Ramdaras eq. 16-22): ``(x, P, nis, log det S, ok)``.

    S = H P H^T + R, K = P H^T S^-1 (by Cholesky solves), x + K nu, the Joseph form
    (I - K H) P (I - K H)^T + K R K^T symmetrised, nis = nu^T S^-1 nu. ok is False (and the
    rest meaningless) when S is not positive definite.
    """
    n = x.shape[0]
    m = nu.shape[0]
    PHT = np.zeros((n, m))
    for i in range(n):
        for k in range(n):
            p = P[i, k]
            for a in range(m):
                PHT[i, a] += p * H[a, k]
    S = R.copy()
    for a in range(m):
        for b in range(m):
            for k in range(n):
                S[a, b] += H[a, k] * PHT[k, b]
    K = np.empty((n, m))
    if m == 1:  # scalar innovation: S^-1 is a division (as on the numpy path)
        s11 = S[0, 0]
        if not s11 > 0.0:
            return x, P, 0.0, 0.0, False
        for i in range(n):
            K[i, 0] = PHT[i, 0] / s11
        nis = nu[0] * nu[0] / s11
        log_det = math.log(s11)
    else:
        L = np.empty((m, m))
        if not cholesky_into(S, L):
            return x, P, 0.0, 0.0, False
        for i in range(n):
            K[i] = _chol_solve(L, PHT[i])  # row i of K = P H^T S^-1 (S symmetric)
        s_nu = _chol_solve(L, nu)
        nis = 0.0
        log_det = 0.0
        for a in range(m):
            nis += nu[a] * s_nu[a]
            log_det += 2.0 * math.log(L[a, a])
    xn = x.copy()
    A = np.zeros((n, n))  # I - K H
    for i in range(n):
        A[i, i] = 1.0
        for a in range(m):
            xn[i] += K[i, a] * nu[a]
            for j in range(n):
                A[i, j] -= K[i, a] * H[a, j]
    AP = np.zeros((n, n))
    for i in range(n):
        for k in range(n):
            f = A[i, k]
            for j in range(n):
                AP[i, j] += f * P[k, j]
    KR = np.zeros((n, m))
    for i in range(n):
        for a in range(m):
            for b in range(m):
                KR[i, b] += K[i, a] * R[a, b]
    Pn = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += AP[i, k] * A[j, k]
            for b in range(m):
                acc += KR[i, b] * K[j, b]
            Pn[i, j] = acc
    _symmetrize(Pn)
    return xn, Pn, nis, log_det, True


def warm_up() -> None:
    """Compile (or load from the disk cache) both kernels for float64 arrays."""
    x, P = np.zeros(4), np.eye(4)
    predict(x, P, np.eye(4), np.eye(4))
    for m in (1, 2):
        update(x, P, np.ones((m, 4)), np.ones(m), np.eye(m))
