"""Shared helpers for the motion models and sensors: argument checks and Gaussian sampling."""

import numpy as np

from activetrack.checks import require_finite, require_nonnegative


def check_state(name, x, n):
    """Return ``x`` as a finite float array whose last axis has length ``n``."""
    x = require_finite(name, x)
    if x.ndim < 1 or x.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got {x.shape}")
    return x


def check_dt(dt):
    """Time step: a finite scalar >= 0 (seconds)."""
    if np.ndim(dt) != 0:
        raise ValueError(f"dt must be a scalar >= 0, got shape {np.shape(dt)}")
    return require_nonnegative("dt", dt)


def check_rng(rng):
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def noise_factor(Q):
    """A matrix L with L @ L.T == Q for a symmetric PSD Q (Cholesky, or eigh if singular)."""
    try:
        return np.linalg.cholesky(Q)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(Q)
        return V * np.sqrt(np.clip(w, 0.0, None))


def add_gaussian_noise(mean, Q, rng):
    """``mean + w`` with ``w ~ N(0, Q)`` drawn independently for every leading index of mean."""
    L = noise_factor(Q)
    return mean + rng.standard_normal(mean.shape) @ L.T
