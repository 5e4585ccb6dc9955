"""Joint probabilistic data association of particle tracks: the Monte Carlo JPDAF.

Vermaak, Godsill & Pérez, "Monte Carlo filtering for multi-target tracking and data
association", IEEE TAES 41(1), 2005 (the MC-JPDAF); the same filter as the sample-based JPDAF of
Schulz, Burgard, Fox & Cremers, "People tracking with mobile robots using sample-based joint
probabilistic data association filters", IJRR 22(2), 2003. It is the JPDA of
:mod:`activetrack.filters.jpda` with each track's Gaussian predicted likelihood ``N(nu; 0, S)``
replaced by its particle estimate. Track ``t`` carries particles ``x_t^i`` with weights
``w_t^i`` (``sum_i w_t^i = 1``); ``g(z | x) = N(z; h(x), R)`` is the sensor's likelihood::

    p_t(z_j) = integral g(z_j | x) p(x_t | Z_k-1) dx  ~=  sum_i w_t^i g(z_j | x_t^i)
    l[t, j]  = Pd_t p_t(z_j) / lambda       inside the gate, 0 outside

The joint events, their probabilities and the marginals ``beta[t, j]`` are the EKF JPDA's
(:func:`activetrack.filters.jpda.jpda_probabilities`, exact, the same for both filters). Each
track's posterior is then the mixture over its association hypotheses, in weights::

    w_t^i  <-  w_t^i [beta_t0 + sum_j beta_tj g(z_j | x_t^i) / p_t(z_j)]

(:meth:`activetrack.filters.particle.ParticleFilter.update_pda`). Summed over ``i`` the bracket
gives ``beta_t0 + sum_j beta_tj = 1``: the update is normalised by construction, and ``p_t(z_j)``
is the same estimate in ``l`` and in the weights. With one track this is the particle PDAF; with a
linear-Gaussian sensor and Gaussian particles ``p_t(z_j) -> N(z_j; H x_t, H P_t H^T + R)``, the
EKF JPDA's likelihood, as the number of particles grows.

The gate stays the chi-square gate on the track's moments (so clustering, track starts and the
existence update see the same detections under both filters); ``Pg`` is its Gaussian value.
Only gated pairs are evaluated, each vectorised over the track's particles (the sensors'
likelihoods take one ``z`` a call), and their per-particle log-likelihoods are kept for the
weight update, so each pair's ``g(z_j | x_t^i)`` is computed once per scan.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import ArrayLike, BoolArray, FloatArray
from activetrack.checks import require_positive
from activetrack.filters.registry import ParticlePosterior
from activetrack.models.base import MotionModel, SensorModel
from activetrack.stats import log_sum_exp

__all__ = ["ParticleLikelihoods", "particle_likelihoods"]


@dataclass(frozen=True)
class ParticleLikelihoods:
    """One scan against ``T`` particle tracks: ``log_p`` ``(T, m)``, each track's particle
    estimate ``log p_t(z_j)`` (module docstring; ``-inf`` outside the gate or where no particle
    explains ``z_j``), and ``ell[t][j]``, the per-particle ``log g(z_j | x_t^i)`` less the
    sensor's constant ``(N_t,)``, for the gated pairs (None for the others)."""

    log_p: FloatArray
    ell: list[list[FloatArray | None]]

    def ratios(self, pd: ArrayLike, clutter_density: float) -> FloatArray:
        """``l[t, j] = Pd_t p_t(z_j) / lambda`` ``(T, m)``, 0 outside the gate: the particle
        counterpart of :func:`activetrack.filters.jpda.likelihood_ratios`, ready for
        :func:`~activetrack.filters.jpda.jpda_probabilities` (``pd`` scalar or ``(T,)``)."""
        lam = require_positive("clutter_density", clutter_density)
        T = self.log_p.shape[0]
        pd_t = np.broadcast_to(np.asarray(pd, dtype=float), (T,))
        if not (np.isfinite(pd_t).all() and (pd_t >= 0.0).all() and (pd_t <= 1.0).all()):
            raise ValueError(f"pd must be in [0, 1], got {pd!r}")
        return np.asarray(pd_t[:, None] * np.exp(self.log_p) / lam, dtype=float)


def particle_likelihoods(
    posteriors: Sequence[ParticlePosterior],
    Z: ArrayLike,
    sensor: SensorModel,
    sensor_state: ArrayLike,
    model: MotionModel,
    *,
    gated: BoolArray,
) -> ParticleLikelihoods:
    """The gated pairs' likelihoods of ``T`` particle tracks (each ``(N_t, n)`` with weights
    ``(N_t,)``; the ``N_t`` may differ) for one scan ``Z`` ``(m, dim_z)`` of ``sensor`` at pv
    ``sensor_state``; ``gated`` ``(T, m)`` the pairs to evaluate (module docstring)."""
    Zm = np.asarray(Z, dtype=float).reshape(-1, int(sensor.dim_z))
    T, m = len(posteriors), Zm.shape[0]
    mask = np.asarray(gated, dtype=bool)
    if mask.shape != (T, m):
        raise ValueError(f"gated must have shape ({T}, {m}) (tracks, detections), got {mask.shape}")
    s = np.asarray(sensor_state, dtype=float)
    log_p = np.full((T, m), -math.inf)
    ell: list[list[FloatArray | None]] = [[None] * m for _ in range(T)]
    with np.errstate(divide="ignore", invalid="ignore"):
        for t in map(int, np.flatnonzero(mask.any(axis=1))):
            X = np.asarray(posteriors[t].particles, dtype=np.float64)
            pv = X if model.state_is_pv else model.kinematics(X)
            log_w = np.log(np.asarray(posteriors[t].weights, dtype=np.float64))
            for j in map(int, np.flatnonzero(mask[t])):
                e, log_norm = sensor.log_likelihood(Zm[j], pv, s)
                e = np.where(np.isnan(e), -math.inf, e)  # a particle on the sensor: no support
                ell[t][j] = e
                log_p[t, j] = float(log_sum_exp(log_w + e)) + log_norm
    return ParticleLikelihoods(log_p, ell)
