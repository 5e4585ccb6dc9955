"""Bootstrap SIR particle filter (Hernandez sec. 5.2: importance density = prior, 10,000
particles, sampling importance resampling; Arulampalam et al. 2002, Algorithm 4).

Per step, vectorised over the N particles (no Python loop per particle):

1. predict: x_k^i ~ p(x_k | x_k-1^i), ``model.sample`` (the prior as importance density);
2. update: log w_k^i = log w_k-1^i + sum_j log p(z_j | x_k^i), normalised by log-sum-exp so a
   sharp likelihood cannot underflow all weights to zero;
3. resample (systematic) every update (``resample="always"``, plain SIR) or only when the
   effective sample size drops below ``ess_threshold * N`` (``resample="ess"``), then
   optionally roughen (Gordon et al. 1993).

Detection model (Hernandez sec. 2.3: z = h(x) + v only between r_min and r_max, here also
with probability pd), by ``min_range``:

- ``"ignore"`` (default): a non-detection carries no information and a detection is weighted
  by N(z; h(x), R) alone, the model of Hernandez's PCRLB (eq. 8-9 count detections only);
- ``"negative"``: a detection weighted by pd I_r(x) N(z; h(x), R), a non-detection by
  1 - pd I_r(x) (mass moves towards "inside r_min or outside r_max").

The likelihoods are the sensors' own; the compiled kernels give the numpy path's bits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite, require_in_range
from activetrack.filters.measurement import (
    Measurement,
    UpdateInfo,
    check_measurement_times,
    check_predict_time,
    check_prior,
    pda_weights,
)
from activetrack.filters.resampling import roughen, systematic_resample
from activetrack.kernels import moment_kernels, particle_kernels
from activetrack.models.base import MotionModel
from activetrack.stats import log_sum_exp

__all__ = ["FilterCollapseError", "ParticleFilter"]

DEFAULT_PARTICLES = 10_000
_RESAMPLE_MODES = ("always", "ess")
_MIN_RANGE_MODES = ("ignore", "negative")
_COLLAPSE_MODES = ("reset", "raise")


class FilterCollapseError(RuntimeError):
    """Every particle weight vanished: no particle explains the measurements."""


def _check_modes(resample: str, min_range: str, on_collapse: str) -> None:
    """Raise unless the mode names are known."""
    if resample not in _RESAMPLE_MODES:
        raise ValueError(f"resample must be one of {_RESAMPLE_MODES}, got {resample!r}")
    if min_range not in _MIN_RANGE_MODES:
        raise ValueError(f"min_range must be one of {_MIN_RANGE_MODES}, got {min_range!r}")
    if on_collapse not in _COLLAPSE_MODES:
        raise ValueError(f"on_collapse must be one of {_COLLAPSE_MODES}, got {on_collapse!r}")


def _check_count(n_particles: object) -> int | None:
    """``n_particles`` as an int >= 1, or None."""
    if n_particles is None:
        return None
    if (
        isinstance(n_particles, bool)
        or not isinstance(n_particles, int | np.integer)
        or n_particles < 1
    ):
        raise ValueError(f"n_particles must be an integer >= 1, got {n_particles!r}")
    return int(n_particles)


def _given_particles(
    particles: ArrayLike, x0: object, P0: object, n: int, n_particles: int | None
) -> FloatArray:
    """A copy of a given particle set ``(N, n)``, checked."""
    if x0 is not None or P0 is not None:
        raise ValueError("particles: give either particles or (x0, P0), not both")
    X = require_finite("particles", particles)
    if X.ndim != 2 or X.shape[1] != n or X.shape[0] < 1:
        raise ValueError(f"particles must have shape (N >= 1, {n}), got {X.shape}")
    if n_particles is not None and n_particles != X.shape[0]:
        raise ValueError(f"n_particles must equal len(particles) = {X.shape[0]}, got {n_particles}")
    return X.copy()


def _drawn_particles(
    x0: ArrayLike | None,
    P0: ArrayLike | None,
    weights: object,
    n: int,
    n_particles: int | None,
    rng: np.random.Generator,
) -> FloatArray:
    """N draws from N(x0, P0), ``(N, n)``."""
    if x0 is None or P0 is None:
        raise ValueError("x0 and P0 are required unless particles are given")
    if weights is not None:
        raise ValueError("weights can only be given together with particles")
    mean, cov = check_prior(x0, P0, n)
    N = DEFAULT_PARTICLES if n_particles is None else n_particles
    return mean + rng.standard_normal((N, n)) @ np.linalg.cholesky(cov).T


def _given_likelihoods(
    log_likelihoods: Sequence[FloatArray | None] | None, m: int, N: int
) -> list[FloatArray | None]:
    """``update_pda``'s precomputed log-likelihoods checked: m entries, each None or ``(N,)``."""
    if log_likelihoods is None:
        return [None] * m
    out = list(log_likelihoods)
    if len(out) != m:
        raise ValueError(f"log_likelihoods must have one entry per detection ({m}), got {len(out)}")
    for j, ell in enumerate(out):
        if ell is not None and np.shape(ell) != (N,):
            raise ValueError(f"log_likelihoods[{j}] must have shape ({N},), got {np.shape(ell)}")
    return out


def _initial_weights(weights: ArrayLike | None, N: int) -> FloatArray:
    """Normalised weights ``(N,)``: uniform, or the given ones checked."""
    if weights is None:
        return np.full(N, 1.0 / N)
    w = require_finite("weights", weights)
    if w.shape != (N,) or np.any(w < 0.0) or not w.sum() > 0.0:
        raise ValueError(
            f"weights must be ({N},), non-negative, with a positive sum; got shape {w.shape}"
        )
    return w / w.sum()


@lru_cache(maxsize=8)
def _uniform_weights(N: int) -> FloatArray:
    """The weights 1/N after resampling, one read-only array per N (the filter never writes
    into its weights; it replaces them)."""
    w = np.full(N, 1.0 / N)
    w.flags.writeable = False
    return w


class ParticleFilter:
    """SIR particle filter over any motion model.

    model: motion model (``activetrack.models.base.MotionModel``).
    x0, P0: Gaussian to draw the initial particles from, ``(n,)`` and ``(n, n)`` SPD; or
        give ``particles`` ``(N, n)`` (and optionally ``weights`` ``(N,)``) instead, e.g. a
        set handed over by a planner.
    n_particles: N >= 1 (default 10,000 as in Hernandez sec. 5.2; taken from ``particles``
        when those are given).
    rng: ``numpy.random.Generator`` or seed.
    resample: ``"always"`` (SIR) or ``"ess"`` (only when ESS < ``ess_threshold * N``).
    ess_threshold: fraction in [0, 1].
    roughening: Gordon's K >= 0; 0 disables.
    min_range: ``"ignore"`` or ``"negative"`` (see module docstring).
    on_collapse: when all weights vanish, ``"reset"`` discards the update's information
        (keeps the predicted particles, reports ``UpdateInfo.collapsed``) or ``"raise"``
        raises :class:`FilterCollapseError`.
    t0: time of the initial particles (s).
    """

    def __init__(
        self,
        model: MotionModel,
        x0: ArrayLike | None = None,
        P0: ArrayLike | None = None,
        n_particles: int | None = None,
        rng: np.random.Generator | int | None = None,
        resample: str = "always",
        ess_threshold: float = 0.5,
        roughening: float = 0.0,
        min_range: str = "ignore",
        t0: float = 0.0,
        particles: ArrayLike | None = None,
        weights: ArrayLike | None = None,
        on_collapse: str = "reset",
    ):
        n = int(model.dim)
        _check_modes(resample, min_range, on_collapse)
        self.ess_threshold = require_in_range("ess_threshold", ess_threshold, 0.0, 1.0)
        self.roughening = require_in_range(
            "roughening", roughening, 0.0, math.inf, hi_inclusive=False
        )
        t0 = float(t0)
        if not math.isfinite(t0):
            raise ValueError(f"t0 must be finite, got {t0!r}")
        count = _check_count(n_particles)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        if particles is not None:
            X = _given_particles(particles, x0, P0, n, count)
        else:
            X = _drawn_particles(x0, P0, weights, n, count, self.rng)
        w = _initial_weights(weights, X.shape[0])
        self.model = model
        self.resample = resample
        self.min_range = min_range
        self.on_collapse = on_collapse
        self._X = X
        self._w = w
        # Log weights; None stands for uniform weights (after resampling) to save a pass.
        self._logw: FloatArray | None = None
        if weights is not None:
            with np.errstate(divide="ignore"):
                self._logw = np.log(w)
        # The pv-state models need no kinematics map (pv = x).
        self._pv_state = bool(model.state_is_pv)
        self._t = t0
        self._moments: tuple[FloatArray, FloatArray] | None = None
        self._mean: FloatArray | None = None  # the mean alone, before a covariance is asked
        self.last_info: UpdateInfo | None = None

    @classmethod
    def from_particles(
        cls,
        model: MotionModel,
        particles: ArrayLike,
        weights: ArrayLike | None = None,
        t0: float = 0.0,
        **options: Any,
    ) -> ParticleFilter:
        """Start from a given particle set ``(N, n)`` and optional weights ``(N,)``."""
        return cls(model, particles=particles, weights=weights, t0=t0, **options)

    @property
    def time(self) -> float:
        """Time of the particles (s)."""
        return self._t

    @property
    def n_particles(self) -> int:
        return self._X.shape[0]

    @property
    def particles(self) -> np.ndarray:
        """Particles ``(N, n)`` (read-only view; the filter replaces, never edits, them)."""
        view = self._X.view()
        view.flags.writeable = False
        return view

    @property
    def weights(self) -> np.ndarray:
        """Normalised weights ``(N,)`` (read-only view)."""
        view = self._w.view()
        view.flags.writeable = False
        return view

    @property
    def ess(self) -> float:
        """Effective sample size ``1 / sum w^2`` of the current weights, in [1, N]."""
        return 1.0 / float(self._w @ self._w)

    def _compute_moments(self) -> tuple[np.ndarray, np.ndarray]:
        if self._moments is None:
            kernels = moment_kernels()  # compiled mode only: round-off agreement
            if kernels is not None and self._X.shape[1] == 4:
                self._moments = kernels.weighted_moments4(self._X, self._w)
                return self._moments
            mean = self._w @ self._X if self._mean is None else self._mean
            D = self._X - mean
            P = (D.T * self._w) @ D
            self._moments = (mean, 0.5 * (P + P.T))
        return self._moments

    def _compute_mean(self) -> np.ndarray:
        """The mean alone where the covariance is not needed (the numpy path: the mean of
        :meth:`_compute_moments`, the same bits, without the 4 x N covariance pass)."""
        if self._moments is not None:
            return self._moments[0]
        if moment_kernels() is not None and self._X.shape[1] == 4:
            return self._compute_moments()[0]
        if self._mean is None:
            self._mean = self._w @ self._X
        return self._mean

    @property
    def mean(self) -> np.ndarray:
        """Weighted mean ``sum w_i x_i``, shape ``(n,)``."""
        return self._compute_mean().copy()

    @property
    def cov(self) -> np.ndarray:
        """Weighted covariance ``sum w_i (x_i - mean)(x_i - mean)^T``, shape ``(n, n)``."""
        return self._compute_moments()[1].copy()

    def predict(self, t: float) -> None:
        """Draw every particle from the transition prior to time ``t`` (>= ``time``)."""
        t = check_predict_time(t, self._t)
        dt = t - self._t
        if dt > 0.0:
            X = np.asarray(self.model.sample(self._X, dt, self.rng), dtype=float)
            if X.shape != self._X.shape:
                raise ValueError(f"model.sample returned shape {X.shape}, expected {self._X.shape}")
            self._X = X
            self._moments = None
            self._mean = None
        self._t = t

    def _log_likelihood(
        self, measurements: Sequence[Measurement]
    ) -> tuple[FloatArray | None, float, int]:
        """Sum over measurements of log p(z_j | x^i) per particle, plus a shared constant.

        Returns ``(ell, const, n_missed)``: ell ``(N,)``, or None when no measurement carries
        information (weights stay unchanged); const is the particle-independent part.
        """
        negative = self.min_range == "negative"
        ell = None
        const = 0.0
        n_missed = 0
        pv = None  # particle kinematics (N, 4), computed once per update
        for m in measurements:
            if m.z is None:
                n_missed += 1
                if not negative:
                    continue  # "ignore": a non-detection tells nothing
            sensor, s = m.sensor, m.sensor_state
            if pv is None:
                pv = self._X if self._pv_state else self.model.kinematics(self._X)
            if m.z is None:
                # P(no detection | x) = 1 - pd I_r(x): 1 outside the detection ranges.
                term = sensor.log_miss_likelihood(pv, s)
            else:
                # "negative": pd I_r(x) N(z; h(x), R), the I_r part in the term.
                term, log_norm = sensor.log_likelihood(m.z, pv, s, gate=negative)
                const += log_norm
                if negative:
                    const += math.log(float(sensor.pd))  # the sensors require pd > 0
            ell = term if ell is None else ell + term
        return ell, const, n_missed

    def update(self, measurements: Sequence[Measurement]) -> UpdateInfo:
        """Weight the particles by the measurements' likelihood, then resample if due.

        ``UpdateInfo.ess`` is the ESS of the updated weights before resampling;
        ``log_likelihood`` is log sum_i w_k-1^i p(z | x^i) (log-sum-exp).
        """
        check_measurement_times(measurements, self._t)
        with np.errstate(divide="ignore", invalid="ignore"):
            ell, const, n_missed = self._log_likelihood(measurements)
        return self._weigh(measurements, ell, const, n_missed)

    def update_pda(
        self,
        measurements: Sequence[Measurement],
        beta: ArrayLike,
        log_likelihoods: Sequence[FloatArray | None] | None = None,
    ) -> UpdateInfo:
        """One scan of uncertain origin with association probabilities ``beta`` ``(m + 1,)``
        (``beta[0]``: none is the target's), the mixture over the hypotheses (the MC-JPDAF of
        Vermaak, Godsill & Perez, IEEE TAES 41(1), 2005; :mod:`.jpda_particle`)::

            w_i  <-  w_i (beta_0 + sum_j beta_j p(z_j | x_i) / p(z_j | Z_{k-1})),
            p(z_j | Z_{k-1}) = sum_i w_i p(z_j | x_i),

        then resampled as :meth:`update`; one sensor at one platform state.
        ``log_likelihoods``: each detection's ``log p(z_j | x_i)`` less the sensor's constant
        ``(N,)`` for the current particles, as the sensor's ``log_likelihood`` gives it
        (computed here when not given; None allowed where ``beta_j`` is 0)."""
        check_measurement_times(measurements, self._t)
        b = pda_weights(measurements, beta)
        given = _given_likelihoods(log_likelihoods, len(measurements), self._X.shape[0])
        if b[0] >= 1.0:  # no detection can be the target's: nothing learnt
            return self._weigh(measurements, None, 0.0, 0)
        N = self._X.shape[0]
        terms = [np.full(N, math.log(b[0]))] if b[0] > 0.0 else []
        pv = None
        logw_prior = self._logw if self._logw is not None else np.log(self._w)
        with np.errstate(divide="ignore", invalid="ignore"):
            for j, (bj, m) in enumerate(zip(b[1:], measurements, strict=True)):
                if bj <= 0.0:
                    continue
                ell = given[j]
                if ell is None:
                    if pv is None:
                        pv = self._X if self._pv_state else self.model.kinematics(self._X)
                    assert m.z is not None  # pda_weights: every measurement is a detection
                    ell = m.sensor.log_likelihood(m.z, pv, m.sensor_state)[0]
                    ell = np.where(np.isnan(ell), -math.inf, ell)
                evidence = float(log_sum_exp(logw_prior + ell))  # log p(z_j | Z_{k-1}) - c
                if not math.isfinite(evidence):  # no particle explains z_j
                    continue
                terms.append(math.log(bj) + ell - evidence)
            if not terms:
                return self._weigh(measurements, None, 0.0, 0)
            mixture = terms[0] if len(terms) == 1 else log_sum_exp(np.stack(terms), axis=0)
        return self._weigh(measurements, mixture, 0.0, 0)

    def _weigh(
        self,
        measurements: Sequence[Measurement],
        ell: FloatArray | None,
        const: float,
        n_missed: int,
    ) -> UpdateInfo:
        """Multiply the weights by ``exp(ell + const)`` ``(N,)`` (None: unchanged), normalise,
        resample if due (:meth:`update`)."""
        ids = tuple([m.sensor_id for m in measurements])
        n_det = len(measurements) - n_missed
        if ell is None:  # nothing informative: weights unchanged, no resampling
            return self._report(ids, n_det, n_missed, ess=self.ess)

        # log w_k = log w_k-1 + log p(z | x), normalised by log-sum-exp (no underflow).
        logw = ell if self._logw is None else ell + self._logw  # None: uniform prior weights
        top = float(np.maximum.reduce(logw))  # logw.max() without its Python wrapper
        if math.isnan(top):  # NaN likelihoods (e.g. a particle on the sensor) count as zero
            logw = np.where(np.isnan(logw), -math.inf, logw)
            top = float(logw.max())
        if not (math.isfinite(top) and math.isfinite(const)):
            message = (
                f"particle weights collapsed at t={self._t}: no particle has a non-zero "
                f"likelihood for the {len(measurements)} measurement(s) {ids}"
            )
            if self.on_collapse == "raise":
                raise FilterCollapseError(message)
            return self._report(
                ids,
                n_det,
                n_missed,
                ess=self.ess,
                collapsed=True,
                log_likelihood=-math.inf,
                message=message + "; update discarded, predicted particles kept",
            )

        # numpy's vectorised exp, sum and dot are at the memory floor here (a compiled pass
        # would be slower: numba's scalar exp costs ~8x numpy's per element).
        w = np.subtract(logw, top)
        np.exp(w, out=w)
        total = float(np.add.reduce(w))  # w.sum() without its Python wrapper
        w /= total
        ess = 1.0 / float(w @ w)
        log_norm = top + math.log(total)
        log_lik = log_norm + const
        if self._logw is None:
            log_lik -= math.log(w.shape[0])  # uniform prior weights 1/N were left out above
        N = w.shape[0]
        kernels = particle_kernels(work=N)  # "auto" counts the work (activetrack.kernels)
        resampled = self.resample == "always" or ess < self.ess_threshold * N
        if resampled:
            if kernels is None:
                self._X = np.take(self._X, systematic_resample(w, self.rng), axis=0)
            else:  # the same draw and rows, copied in one pass
                self._X = kernels.systematic_resample_rows(self._X, w, self.rng.random())
            roughen(self._X, self.roughening, self.rng)
            self._w = _uniform_weights(N)
            self._logw = None
        else:
            self._w = w
            logw -= log_norm
            self._logw = logw
        self._moments = None
        self._mean = None
        return self._report(
            ids, n_det, n_missed, ess=ess, resampled=resampled, log_likelihood=log_lik
        )

    def _report(self, ids: tuple, n_det: int, n_missed: int, **fields: Any) -> UpdateInfo:
        """The update's :class:`UpdateInfo` at the filter's time, kept as ``last_info``."""
        info = UpdateInfo(
            time=self._t, n_detections=n_det, n_missed=n_missed, sensor_ids=ids, **fields
        )
        self.last_info = info
        return info

    def step(self, t: float, measurements: Sequence[Measurement]) -> UpdateInfo:
        """``predict(t)`` then ``update(measurements)``."""
        self.predict(t)
        return self.update(measurements)
