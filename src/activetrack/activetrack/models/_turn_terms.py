"""The coordinated-turn coefficients, evaluated without dividing by zero as omega -> 0.

With theta = omega*T these are the entries of the constant-turn transition (Valverde eq. 35),
of its exact process noise (eq. 37) and of the circular-motion Jacobian (eq. 24, 26-28):

    s1 = sin(theta)/omega             c1 = (1 - cos(theta))/omega
    c2 = (1 - cos(theta))/omega^2     d3 = (theta - sin(theta))/omega^3
    ds1 = d s1/d omega                dc1 = d c1/d omega

For |theta| < SMALL the Taylor series (truncation error below 1e-16 relative) replaces the
closed forms, whose cancellation would otherwise lose digits or divide by zero.
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray

SMALL = 0.05


def turn_terms(
    omega: ArrayLike, T: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Return ``(s1, c1, c2, d3, ds1, dc1)`` for array ``omega`` and scalar ``T``."""
    omega = np.asarray(omega, dtype=float)
    theta = omega * T
    small = np.abs(theta) < SMALL
    # A safe omega for the closed forms (its value is discarded where the series is used).
    w = np.where(small, 1.0, omega)
    th = w * T
    sin, cos = np.sin(th), np.cos(th)
    t2 = theta * theta
    s1 = np.where(
        small,
        T * (1 - t2 / 6 * (1 - t2 / 20 * (1 - t2 / 42 * (1 - t2 / 72)))),
        sin / w,
    )
    c2 = np.where(
        small,
        T * T * (0.5 - t2 / 24 * (1 - t2 / 30 * (1 - t2 / 56 * (1 - t2 / 90)))),
        (1 - cos) / w**2,
    )
    c1 = omega * c2  # exact identity, smooth through omega = 0
    d3 = np.where(
        small,
        T**3 * (1 / 6 - t2 / 120 * (1 - t2 / 42 * (1 - t2 / 72 * (1 - t2 / 110)))),
        (th - sin) / w**3,
    )
    ds1 = np.where(
        small,
        T * T * theta * (-1 / 3 + t2 / 30 - t2 * t2 / 840 + t2**3 / 45360),
        (th * cos - sin) / w**2,
    )
    dc1 = np.where(
        small,
        T * T * (0.5 - t2 / 8 + t2 * t2 / 144 - t2**3 / 5760 + t2**4 / 403200),
        (th * sin - 1 + cos) / w**2,
    )
    return s1, c1, c2, d3, ds1, dc1
