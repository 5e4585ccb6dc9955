"""Small dense SPD linear algebra for the bounds and the sensors' Fisher information.

Cholesky factors, triangular solves, SPD inverses and PSD square roots of ``(..., n, n)``
stacks, raising ``ValueError`` naming the matrix. A single matrix goes straight to LAPACK
(scipy.linalg.lapack): a few microseconds instead of numpy.linalg's per-call overhead, which
matters in the planner's inner loop.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from activetrack.arraytypes import FloatArray

__all__ = ["cholesky", "lower_solve", "psd_sqrt", "spd_inverse", "whitener"]


def cholesky(name: str, A: FloatArray, check_symmetry: bool = True) -> FloatArray:
    """Lower Cholesky factor of SPD matrices ``(..., n, n)``; ValueError naming ``name``."""
    if not np.isfinite(A).all():
        raise ValueError(f"{name} must be finite (got NaN or inf entries)")
    At = np.swapaxes(A, -1, -2)
    if check_symmetry and not (A == At).all():
        if np.max(np.abs(A - At)) > 1e-9 * np.max(np.abs(A)):
            raise ValueError(f"{name} must be symmetric positive definite (it is not symmetric)")
    if A.ndim == 2:
        L, info = lapack.dpotrf(A, lower=1, clean=1)
        if info == 0:
            return np.asarray(L)
    else:
        try:
            return np.linalg.cholesky(A)
        except np.linalg.LinAlgError:
            pass
    raise ValueError(f"{name} must be symmetric positive definite (all eigenvalues > 0)")


def lower_solve(L: FloatArray, B: FloatArray) -> FloatArray:
    """L^{-1} B for lower-triangular L ``(..., n, n)`` and B ``(n, k)`` or ``(..., n, k)``."""
    if L.ndim == 2 and B.ndim == 2:
        # dtrtri + matmul rather than dtrtrs: OpenBLAS threads the latter, and waking its
        # thread pool costs ~15 us per call on these 4 x 4 systems.
        return np.asarray(lapack.dtrtri(L, lower=1)[0] @ B)
    return np.linalg.solve(L, B)


def spd_inverse(name: str, A: FloatArray, check_symmetry: bool = True) -> FloatArray:
    """Inverse of SPD matrices ``(..., n, n)`` through Cholesky: A^{-1} = L^{-T} L^{-1}."""
    L = cholesky(name, A, check_symmetry)
    if A.ndim == 2:
        # dpotri fills the lower triangle; the strict upper one keeps L's zeros (clean=1).
        lower = np.asarray(lapack.dpotri(L, lower=1)[0])
        inv = lower + lower.T
        inv.flat[:: A.shape[-1] + 1] *= 0.5  # the diagonal was counted twice
        return inv
    Linv = np.linalg.solve(L, np.eye(A.shape[-1]))
    return np.swapaxes(Linv, -1, -2) @ Linv


def psd_sqrt(name: str, Q: FloatArray) -> FloatArray:
    """A square root S with S S^T = Q for a symmetric positive semi-definite Q ``(n, n)``."""
    if not np.isfinite(Q).all():
        raise ValueError(f"{name} must be finite")
    if not np.allclose(Q, Q.T, rtol=1e-9, atol=1e-12 * max(np.max(np.abs(Q)), 1e-300)):
        raise ValueError(f"{name} must be symmetric positive semi-definite")
    try:
        return np.linalg.cholesky(Q)
    except np.linalg.LinAlgError:
        # Singular process noise (e.g. noise on a subset of states): eigen-decomposition.
        lam, V = np.linalg.eigh(Q)
        if lam.min() < -1e-12 * max(lam.max(), 1e-300):
            raise ValueError(f"{name} must be positive semi-definite (eigenvalues >= 0)") from None
        return np.asarray(V * np.sqrt(np.clip(lam, 0.0, None)))


def whitener(R: FloatArray) -> FloatArray:
    """L^{-1} with L L^T = R, so that H^T R^{-1} H = (L^{-1} H)^T (L^{-1} H)."""
    L = cholesky("sensor.R", np.atleast_2d(np.asarray(R, dtype=float)))
    return np.linalg.solve(L, np.eye(L.shape[-1]))
