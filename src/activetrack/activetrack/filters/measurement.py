"""Data the filters exchange: a :class:`Measurement` in (a detection ``z``, or ``z is None``
for a look without one: a miss, or a target outside ``[r_min, r_max]``, Hernandez sec. 2.3),
an :class:`UpdateInfo` out; and the :class:`TrackingFilter` protocol both filters follow.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite, require_spd
from activetrack.models.base import SensorModel

__all__ = [
    "AssociatingFilter",
    "Measurement",
    "TrackingFilter",
    "UpdateInfo",
    "check_measurement_times",
    "check_predict_time",
    "check_prior",
    "pda_probabilities",
    "pda_weights",
]

# Slack for comparing measurement stamps with the filter time (float round-off in t0 + k*T).
TIME_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Measurement:
    """One sensor report.

    sensor: a sensor (contract :class:`activetrack.models.base.SensorModel`).
    sensor_state: the platform's pv vector ``(x, xdot, y, ydot)``, shape ``(4,)``.
    z: the measurement, shape ``(sensor.dim_z,)`` (a scalar is accepted for ``dim_z == 1``),
        or ``None`` for "looked, no detection".
    time: measurement time in seconds. The filters treat a measurement as taken at their
        current time (call ``predict(time)`` or ``step`` first); a measurement later than
        the filter's time is rejected.
    sensor_id: free label carried through to :class:`UpdateInfo`.

    ``z`` and ``sensor_state`` are stored as read-only float arrays.
    """

    sensor: SensorModel
    sensor_state: FloatArray
    z: FloatArray | None
    time: float
    sensor_id: str = ""

    def __post_init__(self) -> None:
        s = np.array(self.sensor_state, dtype=float)
        if s.shape != (4,) or not np.isfinite(s).all():
            raise ValueError(
                f"sensor_state must be a finite pv vector (x, xdot, y, ydot) of shape (4,), "
                f"got {self.sensor_state!r}"
            )
        s.flags.writeable = False
        object.__setattr__(self, "sensor_state", s)
        t = float(self.time)
        if not math.isfinite(t):
            raise ValueError(f"time must be finite, got {self.time!r}")
        object.__setattr__(self, "time", t)
        if self.z is not None:
            dim_z = int(self.sensor.dim_z)
            z = np.array(self.z, dtype=float).reshape(-1)
            if z.shape != (dim_z,):
                raise ValueError(
                    f"z must have shape ({dim_z},) for a {self.sensor.kind} sensor, "
                    f"got shape {np.shape(self.z)}"
                )
            if not np.isfinite(z).all():
                raise ValueError(f"z must be finite (no NaN or inf), got {self.z!r}")
            z.flags.writeable = False
            object.__setattr__(self, "z", z)

    @property
    def detected(self) -> bool:
        """True when the sensor reported a detection (``z is not None``)."""
        return self.z is not None


@dataclass(frozen=True)
class UpdateInfo:
    """Summary of one ``update(measurements)`` call.

    time: filter time of the update.
    n_detections, n_missed: measurements with and without ``z``.
    nis: sum of the normalised innovation squared ``nu^T S^-1 nu`` over the detections (EKF;
        chi-square with ``dof`` degrees of freedom for a consistent filter); NaN for the
        particle filter and when nothing was detected.
    dof: sum of ``dim_z`` over the detections.
    nis_per_measurement: NIS of each detection in input order (NaN for a missed one).
    log_likelihood: log p(z_k | Z_{k-1}) of the whole update (Gaussian for the EKF; the
        log mean unnormalised weight for the particle filter).
    ess: effective sample size ``1 / sum w^2`` of the updated weights before any resampling
        (particle filter; NaN for the EKF).
    resampled: whether the particle filter resampled after this update.
    collapsed: the particle weights all vanished and the update was discarded (PF,
        ``on_collapse="reset"``); ``message`` says why.
    """

    time: float
    n_detections: int = 0
    n_missed: int = 0
    nis: float = math.nan
    dof: int = 0
    nis_per_measurement: tuple[float, ...] = ()
    log_likelihood: float = 0.0
    ess: float = math.nan
    resampled: bool = False
    collapsed: bool = False
    sensor_ids: tuple[str, ...] = field(default=())
    message: str = ""


class TrackingFilter(Protocol):
    """The interface both filters share (so the tracker node can switch by a parameter)."""

    @property
    def time(self) -> float: ...

    @property
    def mean(self) -> np.ndarray: ...

    @property
    def cov(self) -> np.ndarray: ...

    def predict(self, t: float) -> None: ...

    def update(self, measurements: Sequence[Measurement]) -> UpdateInfo: ...

    def step(self, t: float, measurements: Sequence[Measurement]) -> UpdateInfo: ...


class AssociatingFilter(TrackingFilter, Protocol):
    """A filter that can also take a scan whose detections' origin is uncertain (clutter,
    other targets): the tracker's JPDA gives it each detection's association probability.
    What a filter needs for a scene of several targets or clutter (docs/extending.md)."""

    def update_pda(self, measurements: Sequence[Measurement], beta: FloatArray) -> UpdateInfo:
        """``beta[0]``: none of the detections is the target's; ``beta[j]``: detection j is
        (the PDA update, Bar-Shalom, Daum & Huang 2009)."""
        ...


def pda_probabilities(beta: object, shape: tuple[int, ...]) -> FloatArray:
    """``beta`` of PDA updates checked: of ``shape`` (``(m + 1,)`` for one track, ``(G, m + 1)``
    for G), finite, in [0, 1] (round-off of 1e-12 clipped: a marginal summed over joint events
    can come out 1 + 1 ulp), each track's row summing to 1."""
    b = np.asarray(beta, dtype=float)
    tol = 1e-12
    if b.shape != shape or not np.isfinite(b).all() or (b < -tol).any() or (b > 1 + tol).any():
        raise ValueError(f"beta must be {shape} probabilities in [0, 1], got {beta!r}")
    b = np.clip(b, 0.0, 1.0)
    total = b.sum(axis=-1)
    if (np.abs(total - 1.0) > 1e-9).any():
        raise ValueError(f"beta must sum to 1, got {float(total) if b.ndim == 1 else total!r}")
    return b


def pda_weights(measurements: Sequence[Measurement], beta: object) -> FloatArray:
    """``beta`` ``(m + 1,)`` of a PDA update checked against its ``m`` detections: finite,
    in [0, 1] (round-off of 1e-12 clipped: a marginal summed over joint events can come out
    1 + 1 ulp), summing to 1; the detections all of one sensor at one platform state, each
    with a ``z``."""
    m = len(measurements)
    b = pda_probabilities(beta, (m + 1,))
    for i, meas in enumerate(measurements):
        if not isinstance(meas, Measurement) or meas.z is None:
            raise ValueError(f"measurements[{i}]: a PDA update takes detections (z given)")
        first = measurements[0]
        if meas.sensor is not first.sensor or not np.array_equal(
            meas.sensor_state, first.sensor_state
        ):
            raise ValueError(
                f"measurements[{i}]: a PDA update takes one scan (one sensor, one platform state)"
            )
    return b


def check_prior(x0: ArrayLike, P0: ArrayLike, n: int) -> tuple[FloatArray, FloatArray]:
    """The prior mean ``(n,)`` and SPD covariance ``(n, n)`` of a model of dimension n."""
    mean = require_finite("x0", x0)
    if mean.shape != (n,):
        raise ValueError(f"x0 must have shape ({n},) for this model, got {mean.shape}")
    cov = require_spd("P0", P0)
    if cov.shape != (n, n):
        raise ValueError(f"P0 must have shape ({n}, {n}) for this model, got {cov.shape}")
    return mean, cov


def check_predict_time(t: float, current: float) -> float:
    """Return ``t`` as a float; raise unless it is finite and not before ``current``."""
    t = float(t)
    if not math.isfinite(t) or t < current - TIME_TOLERANCE * max(1.0, abs(current)):
        raise ValueError(f"t must be finite and >= the filter time {current!r}, got {t!r}")
    return max(t, current)


def check_measurement_times(measurements: Sequence[Measurement], current: float) -> None:
    """Raise if a measurement is stamped after the filter time (predict to it first)."""
    slack = TIME_TOLERANCE * max(1.0, abs(current))
    for m in measurements:
        if not isinstance(m, Measurement):
            raise ValueError(f"measurements must hold Measurement objects, got {type(m)!r}")
        if m.time > current + slack:
            raise ValueError(
                f"measurements: time {m.time!r} is after the filter time {current!r}; "
                "call predict(t) or step(t, measurements) first"
            )
