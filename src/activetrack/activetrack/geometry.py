"""Small geometric helpers shared by plots and visualization markers."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray


def covariance_ellipse(
    centre: ArrayLike, P_xy: ArrayLike, scale: float = 1.0, n_points: int = 60
) -> FloatArray:
    """Outline of the ``scale``-sigma ellipse of a 2x2 position covariance: ``(n_points, 2)``.

    The ellipse {c + scale * V sqrt(L) u : |u| = 1} with P_xy = V L V^T; closed (the last point
    repeats the first).
    """
    P = np.asarray(P_xy, dtype=float)
    if P.shape != (2, 2) or not np.all(np.isfinite(P)):
        raise ValueError(f"P_xy must be a finite (2, 2) covariance, got shape {P.shape}")
    lam, V = np.linalg.eigh(0.5 * (P + P.T))
    pts = V @ (np.sqrt(np.clip(lam, 0.0, None))[:, None] * _unit_circle(n_points))
    return np.asarray(centre, dtype=float)[None, :] + scale * pts.T


@lru_cache(maxsize=8)
def _unit_circle(n_points: int) -> FloatArray:
    """``(2, n_points)`` cos and sin of n_points angles from 0 to 2 pi (read-only: shared)."""
    t = np.linspace(0.0, 2.0 * np.pi, n_points)
    unit = np.stack([np.cos(t), np.sin(t)])
    unit.flags.writeable = False
    return unit
