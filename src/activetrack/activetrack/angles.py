"""Angle wrapping used by every bearing residual and measurement.

Bearings follow the contract convention: ``atan2(y_t - y_s, x_t - x_s)`` in radians,
counter-clockwise from +x, wrapped to ``[-pi, pi)``.  The infinite-line sensor of
Vander Hook et al. (003, sec. II) only knows the bearing modulo pi, wrapped to
``[-pi/2, pi/2)``.
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray

__all__ = ["angle_diff", "wrap_angle", "wrap_half_angle"]

TWO_PI = 2.0 * np.pi


def wrap_angle(a: ArrayLike) -> FloatArray:
    """Wrap angles (any shape) to ``[-pi, pi)``; returns a float array (0-d for a scalar)."""
    a = np.asarray(a, dtype=float)
    wrapped = np.mod(a + np.pi, TWO_PI) - np.pi
    # np.mod can round a value just below 2*pi up to exactly 2*pi; keep the interval half-open.
    return np.where(wrapped >= np.pi, wrapped - TWO_PI, wrapped)


def wrap_half_angle(a: ArrayLike) -> FloatArray:
    """Wrap angles modulo pi to ``[-pi/2, pi/2)`` (an undirected line's orientation)."""
    a = np.asarray(a, dtype=float)
    half = 0.5 * np.pi
    wrapped = np.mod(a + half, np.pi) - half
    return np.where(wrapped >= half, wrapped - np.pi, wrapped)


def angle_diff(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Shortest signed difference ``a - b`` wrapped to ``[-pi, pi)``."""
    return wrap_angle(np.asarray(a, dtype=float) - np.asarray(b, dtype=float))
