"""Target-state filters: an EKF and a bootstrap SIR particle filter with one interface.

Both offer ``predict(t)``, ``update(measurements) -> UpdateInfo``, ``step(t, measurements)``,
``mean``, ``cov`` and ``time`` (:class:`TrackingFilter`); :func:`make_filter` picks one by name
so the tracker node can switch with a parameter.
"""

from typing import Any

from activetrack.arraytypes import ArrayLike
from activetrack.filters.ekf import ExtendedKalmanFilter
from activetrack.filters.measurement import Measurement, TrackingFilter, UpdateInfo
from activetrack.filters.particle import FilterCollapseError, ParticleFilter
from activetrack.filters.resampling import (
    effective_sample_size,
    roughen,
    systematic_indices,
    systematic_resample,
)
from activetrack.models.base import MotionModel

__all__ = [
    "FILTER_KINDS",
    "ExtendedKalmanFilter",
    "FilterCollapseError",
    "Measurement",
    "ParticleFilter",
    "TrackingFilter",
    "UpdateInfo",
    "effective_sample_size",
    "make_filter",
    "roughen",
    "systematic_indices",
    "systematic_resample",
]

FILTER_KINDS: dict[str, type[ExtendedKalmanFilter] | type[ParticleFilter]] = {
    "ekf": ExtendedKalmanFilter,
    "pf": ParticleFilter,
}


def make_filter(
    kind: str, model: MotionModel, x0: ArrayLike, P0: ArrayLike, **options: Any
) -> TrackingFilter:
    """Build ``"ekf"`` or ``"pf"`` with ``model``, ``x0``, ``P0`` and filter ``options``.

    Options are passed on: ``t0`` for both; ``n_particles``, ``rng``, ``resample``,
    ``ess_threshold``, ``roughening``, ``min_range``, ``on_collapse`` for the PF. An option the
    chosen filter does not take raises ``TypeError``.
    """
    try:
        cls = FILTER_KINDS[kind]
    except (KeyError, TypeError):
        raise ValueError(f"kind must be one of {tuple(FILTER_KINDS)}, got {kind!r}") from None
    return cls(model, x0, P0, **options)
