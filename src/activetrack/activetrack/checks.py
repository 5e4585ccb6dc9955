"""Input validation shared by the core library.

Every check raises ``ValueError`` whose message names the offending argument and states the
allowed range, as the interface contract requires.  The checks return the validated value
(as a float or a float array) so callers can write ``q = require_positive("q", q)``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray

__all__ = [
    "require_finite",
    "require_in_range",
    "require_nonnegative",
    "require_positive",
    "require_psd",
    "require_spd",
    "symmetrize",
]


def _as_float(name: str, value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None


def require_finite(name: str, array: ArrayLike) -> FloatArray:
    """Return ``array`` as a float ndarray; raise if any entry is NaN or infinite."""
    try:
        arr = np.asarray(array, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array, got {array!r}") from None
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite (no NaN or inf), got {arr!r}")
    return arr


def require_positive(name: str, value: Any) -> float:
    """Return ``value`` as a float; it must satisfy 0 < value < inf."""
    v = _as_float(name, value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return v


def require_nonnegative(name: str, value: Any) -> float:
    """Return ``value`` as a float; it must satisfy 0 <= value < inf."""
    v = _as_float(name, value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    return v


def require_in_range(
    name: str,
    value: Any,
    lo: float,
    hi: float,
    *,
    lo_inclusive: bool = True,
    hi_inclusive: bool = True,
) -> float:
    """Return ``value`` as a float inside the interval from ``lo`` to ``hi``.

    The bounds are inclusive unless ``lo_inclusive`` / ``hi_inclusive`` is False; ``hi`` may be
    ``inf`` (an infinite value is then allowed only if ``hi_inclusive``).
    """
    v = _as_float(name, value)
    ok_lo = v >= lo if lo_inclusive else v > lo
    ok_hi = v <= hi if hi_inclusive else v < hi
    if math.isnan(v) or not (ok_lo and ok_hi):
        left = "[" if lo_inclusive else "("
        right = "]" if hi_inclusive else ")"
        raise ValueError(f"{name} must be in {left}{lo}, {hi}{right}, got {value!r}")
    return v


def require_int(name: str, value: Any, lo: int, hi: int) -> int:
    """``value`` if it is an int (not a bool) in [lo, hi], else a ValueError naming ``name``
    and the range."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ValueError(f"{name}: must be an integer in [{lo}, {hi}], got {value!r}")
    return value


def symmetrize(P: ArrayLike) -> FloatArray:
    """Return ``(P + P^T) / 2`` over the last two axes (removes round-off asymmetry)."""
    P = np.asarray(P, dtype=float)
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def _require_square_symmetric(name: str, matrix: ArrayLike, rtol: float) -> FloatArray:
    M = require_finite(name, matrix)
    if M.ndim < 2 or M.shape[-1] != M.shape[-2]:
        raise ValueError(f"{name} must be a square matrix (..., n, n), got shape {M.shape}")
    scale = np.max(np.abs(M), axis=(-1, -2), keepdims=True)
    asym = np.abs(M - np.swapaxes(M, -1, -2))
    if np.any(asym > rtol * np.maximum(scale, np.finfo(float).tiny)):
        raise ValueError(f"{name} must be symmetric (relative tolerance {rtol:g})")
    return symmetrize(M)


def require_spd(name: str, matrix: ArrayLike, rtol: float = 1e-9) -> FloatArray:
    """Return the symmetrised ``matrix``; raise unless it is symmetric positive definite.

    Symmetry is checked to ``rtol`` relative to the largest entry; definiteness by a
    Cholesky factorisation (works on stacks ``(..., n, n)`` too).
    """
    M = _require_square_symmetric(name, matrix, rtol)
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise ValueError(f"{name} must be symmetric positive definite") from None
    return M


def require_psd(name: str, matrix: ArrayLike, rtol: float = 1e-9) -> FloatArray:
    """Like :func:`require_spd` but allows zero eigenvalues (down to ``-rtol * max|eig|``)."""
    M = _require_square_symmetric(name, matrix, rtol)
    eig = np.linalg.eigvalsh(M)
    floor = -rtol * np.max(np.abs(eig), axis=-1, keepdims=True)
    if np.any(eig < floor):
        raise ValueError(f"{name} must be symmetric positive semi-definite")
    return M
