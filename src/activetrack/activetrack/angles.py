"""Angle wrapping used by every bearing residual and measurement.

Bearings follow the contract convention: ``atan2(y_t - y_s, x_t - x_s)`` in radians,
counter-clockwise from +x, wrapped to ``[-pi, pi)``.  The infinite-line sensor of
Vander Hook et al. (003, sec. II) only knows the bearing modulo pi, wrapped to
``[-pi/2, pi/2)``.
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray

__all__ = ["angle_diff", "within_angle", "wrap_angle", "wrap_half_angle"]

TWO_PI = 2.0 * np.pi
# |cos(a - c) - cos(half)| below which within_angle takes the wrapped difference: far above the
# rounding of the cosines' products (~1e-16), so no pair the direct test decides otherwise escapes
EDGE_BAND = 1e-9


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


def within_angle(a: ArrayLike, centres: ArrayLike, half: float) -> np.ndarray:
    """``|wrap_angle(a_n - c_j)| <= half`` for angles a ``(N,)`` and centres c ``(J,)``, bool
    ``(J, N)``, as cos(a_n - c_j) >= cos(half): one ``(J, 2)`` by ``(2, N)`` product in place of
    J x N wrapped differences (the planner's search tests every cell for every pointing of
    every candidate). The pairs whose cosine lies within EDGE_BAND of cos(half) take the
    wrapped difference itself, so the result is the direct test's, to the bit."""
    a = np.asarray(a, dtype=float).reshape(-1)
    c = np.asarray(centres, dtype=float).reshape(-1)
    if half >= np.pi or half < 0.0:  # every angle, or none (the direct test's answers)
        return np.full((c.size, a.size), half >= np.pi)
    cos_off = np.stack([np.cos(c), np.sin(c)], axis=1) @ np.stack([np.cos(a), np.sin(a)])
    edge = np.cos(half)
    inside = cos_off >= edge
    near = cos_off > edge - EDGE_BAND
    near &= cos_off < edge + EDGE_BAND  # compared, not subtracted: no J x N float temporaries
    if near.any():
        rows, cols = np.nonzero(near)
        inside[rows, cols] = np.abs(wrap_angle(a[cols] - c[rows])) <= half
    return inside
