"""Shared helpers for the motion models and sensors: argument checks, relative geometry and
Gaussian sampling."""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite, require_nonnegative


def check_state(name: str, x: ArrayLike, n: int) -> FloatArray:
    """Return ``x`` as a finite float array whose last axis has length ``n``."""
    x = require_finite(name, x)
    if x.ndim < 1 or x.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got {x.shape}")
    return x


def check_dt(dt: float) -> float:
    """Time step: a finite scalar >= 0 (seconds)."""
    if np.ndim(dt) != 0:
        raise ValueError(f"dt must be a scalar >= 0, got shape {np.shape(dt)}")
    return require_nonnegative("dt", dt)


def check_rng(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def noise_factor(Q: FloatArray) -> FloatArray:
    """A matrix L with L @ L.T == Q for a symmetric PSD Q (Cholesky, or eigh if singular)."""
    try:
        return np.linalg.cholesky(Q)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(Q)
        return V * np.sqrt(np.clip(w, 0.0, None))


def add_gaussian_noise(mean: FloatArray, Q: FloatArray, rng: np.random.Generator) -> FloatArray:
    """``mean + w`` with ``w ~ N(0, Q)`` drawn independently for every leading index of mean."""
    L = noise_factor(Q)
    return mean + rng.standard_normal(mean.shape) @ L.T


def relative_geometry(
    target_pv: ArrayLike, sensor_pv: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Broadcast relative position/velocity (target minus sensor): dx, dvx, dy, dvy, r^2
    (Ramdaras eq. 12), each ``(...)``; both arguments are checked pv batches ``(..., 4)``."""
    t = check_state("target_pv", target_pv, 4)
    s = check_state("sensor_pv", sensor_pv, 4)
    try:
        d = t - s
    except ValueError:
        raise ValueError(
            f"target_pv {t.shape} and sensor_pv {s.shape} must broadcast together"
        ) from None
    dx, dvx, dy, dvy = d[..., 0], d[..., 1], d[..., 2], d[..., 3]  # views, as moveaxis gave
    return dx, dvx, dy, dvy, dx * dx + dy * dy
