"""Resampling for the SIR particle filter.

Systematic (Arulampalam et al. 2002, Algorithm 2): one offset u ~ U[0, 1), and for the points
(u + i) / N the particle whose cumulative-weight interval holds it (filterpy's
``systematic_resample``, by ``searchsorted``). Roughening (Gordon, Salmond and Smith 1993,
sec. 4): Gaussian jitter of standard deviation ``K * E_i * N^(-1/d)``, E_i the spread of
component i, d the state dimension, against sample impoverishment.
"""

from __future__ import annotations

import numpy as np

__all__ = ["effective_sample_size", "roughen", "systematic_indices", "systematic_resample"]


def systematic_indices(weights: np.ndarray, u: float) -> np.ndarray:
    """Indices chosen by systematic resampling with offset ``u`` in ``[0, 1)``.

    ``weights`` ``(N,)`` normalised; returns sorted ints ``(N,)``. Particle i takes the points
    (u + k) / N in [c_{i-1}, c_i) (c cumulative); ``ceil(N c - u)`` points lie below c, so one
    ``diff`` and ``repeat`` give the copies (cheaper than a ``searchsorted``).
    """
    n = weights.shape[0]
    below = np.cumsum(weights)
    below *= n
    below -= u
    np.ceil(below, out=below)
    below[-1] = n  # c_N = 1 exactly; round-off must not drop the last points
    np.minimum(below, n, out=below)  # ceil(N c - u) >= 0 already since u < 1
    counts = np.diff(below, prepend=0.0).astype(np.intp)
    return np.repeat(np.arange(n), counts)


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Systematic resampling indices for normalised ``weights`` (N,), one uniform draw."""
    return systematic_indices(weights, rng.random())


def effective_sample_size(weights: np.ndarray) -> float:
    """ESS ``1 / sum w_i^2`` of normalised weights; between 1 and N."""
    return 1.0 / float(weights @ weights)


def roughen(particles: np.ndarray, K: float, rng: np.random.Generator) -> None:
    """Add roughening jitter in place (Gordon et al. 1993): sigma_i = K E_i N^(-1/d).

    particles: ``(N, d)``; K: tuning constant (Gordon et al. use 0.2); 0 does nothing.
    """
    if K <= 0.0:
        return
    n, d = particles.shape
    spread = particles.max(axis=0) - particles.min(axis=0)
    sigma = K * spread * n ** (-1.0 / d)
    particles += rng.standard_normal((n, d)) * sigma
