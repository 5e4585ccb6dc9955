"""Target-state filters with one interface (:class:`TrackingFilter`): an EKF and a bootstrap
SIR particle filter, registered below as ``"ekf"`` and ``"pf"`` like any other filter
(:mod:`activetrack.filters.registry`, docs/extending.md, "A filter").
"""

from typing import Any

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.filters.ekf import ExtendedKalmanFilter
from activetrack.filters.ekf_runs import ekf_over_runs
from activetrack.filters.measurement import Measurement, TrackingFilter, UpdateInfo
from activetrack.filters.particle import FilterCollapseError, ParticleFilter
from activetrack.filters.registry import (
    FilterFactory,
    FilterKind,
    ParticlePosterior,
    _register_built_in,
    filter_kind,
    filter_names,
    make_filter,
    register_filter,
    unregister_filter,
)
from activetrack.filters.resampling import (
    effective_sample_size,
    roughen,
    systematic_indices,
    systematic_resample,
)
from activetrack.models.base import MotionModel

__all__ = [
    "ExtendedKalmanFilter",
    "FilterCollapseError",
    "FilterFactory",
    "FilterKind",
    "Measurement",
    "ParticleFilter",
    "ParticlePosterior",
    "TrackingFilter",
    "UpdateInfo",
    "effective_sample_size",
    "ekf_over_runs",
    "filter_kind",
    "filter_names",
    "make_filter",
    "register_filter",
    "roughen",
    "systematic_indices",
    "systematic_resample",
    "unregister_filter",
]


def _pf(
    model: MotionModel,
    x0: FloatArray,
    P0: FloatArray,
    config: Any,
    rng: np.random.Generator,
    t0: float = 0.0,
) -> TrackingFilter:
    """The particle options of the scenario's tracker block (TrackerConfig)."""
    return ParticleFilter(
        model,
        x0,
        P0,
        n_particles=config.particles,
        rng=rng,
        resample=config.resample,
        ess_threshold=config.ess_threshold,
        roughening=config.roughening,
        min_range=config.min_range,
        t0=t0,
    )


def _ekf(
    model: MotionModel,
    x0: FloatArray,
    P0: FloatArray,
    config: Any,
    rng: np.random.Generator,
    t0: float = 0.0,
) -> TrackingFilter:
    return ExtendedKalmanFilter(model, x0, P0, t0=t0)


def _ekf_many(
    model: MotionModel,
    X0: FloatArray,
    P0: FloatArray,
    config: Any,
    rng: np.random.Generator,
    t0: float = 0.0,
) -> list[ExtendedKalmanFilter]:
    return ExtendedKalmanFilter.many(model, X0, P0, t0)


_register_built_in(
    "ekf",
    _ekf,
    description="extended Kalman filter (ExtendedKalmanFilter)",
    factory_many=_ekf_many,
)
_register_built_in(
    "pf",
    _pf,
    particle_based=True,
    description="bootstrap SIR particle filter (ParticleFilter)",
)
