"""Sensor measurement models (contract: ``activetrack.models.sensors``).

All sensors observe a target pv state (x, xdot, y, ydot) from a sensor platform pv state
(Hernandez eq. 6-7, Ramdaras eq. 1) with relative geometry dx = x_t - x_s, dy = y_t - y_s
(Ramdaras eq. 12), range r = sqrt(dx^2 + dy^2) and bearing atan2(dy, dx) wrapped to [-pi, pi).
``target_pv`` and ``sensor_pv`` broadcast against each other, e.g. a target batch (M, 1, 4)
against sensors (1, C, 4) gives measurements (M, C, dim_z).

Measurement Jacobians are with respect to the target pv; ``state_jacobian`` chains them with a
motion model's ``kinematics_jacobian``.  A bearing Jacobian at zero range is undefined and
raises ValueError.  ``in_range`` is the I_r indicator of Hernandez eq. 8, r_min <= r <= r_max;
detection then succeeds with probability ``pd`` (Ramdaras eq. 14-22).
"""

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from activetrack.angles import wrap_angle, wrap_half_angle
from activetrack.checks import require_in_range, require_positive
from activetrack.models._common import check_rng, check_state

__all__ = [
    "AmbiguousBearingSensor",
    "BearingSensor",
    "RangeBearingSensor",
    "RangeRateBearingSensor",
    "state_jacobian",
]


def _geometry(target_pv, sensor_pv):
    """Broadcast relative position/velocity (target minus sensor): dx, dvx, dy, dvy, r2."""
    t = check_state("target_pv", target_pv, 4)
    s = check_state("sensor_pv", sensor_pv, 4)
    try:
        d = t - s
    except ValueError:
        raise ValueError(
            f"target_pv {t.shape} and sensor_pv {s.shape} must broadcast together"
        ) from None
    dx, dvx, dy, dvy = np.moveaxis(d, -1, 0)
    return dx, dvx, dy, dvy, dx * dx + dy * dy


def _require_nonzero_range(r2, what):
    if np.any(r2 == 0.0):
        raise ValueError(
            f"target_pv and sensor_pv coincide (range 0): the {what} is undefined; "
            "the range must be > 0"
        )


def _bearing_row(dx, dy, r2):
    """d atan2(dy, dx) / d (x, xdot, y, ydot) = (-dy, 0, dx, 0) / r^2.

    Hernandez eq. 9 prints the opposite sign; only H^T H enters his bound, so it is immaterial
    there, but the EKF needs the true derivative used here.
    """
    z = np.zeros_like(dx)
    return np.stack([-dy / r2, z, dx / r2, z], axis=-1)


def _range_row(dx, dy, r):
    z = np.zeros_like(dx)
    return np.stack([dx / r, z, dy / r, z], axis=-1)


class _Sensor:
    """Members shared by all sensors; subclasses define kind, components, R, measure, jacobian."""

    # Indices of angle entries in z and the period they are wrapped with.
    angle_indices: ClassVar[tuple[int, ...]] = ()
    angle_period: ClassVar[float] = 2.0 * np.pi

    def _validate_common(self):
        object.__setattr__(
            self, "pd", require_in_range("pd", self.pd, 0.0, 1.0, lo_inclusive=False)
        )
        r_min = require_in_range("r_min", self.r_min, 0.0, math.inf, hi_inclusive=False)
        r_max = require_in_range("r_max", self.r_max, 0.0, math.inf)
        if not r_min < r_max:
            raise ValueError(f"r_max must be > r_min = {r_min}, got {r_max}")
        object.__setattr__(self, "r_min", r_min)
        object.__setattr__(self, "r_max", r_max)

    @property
    def dim_z(self):
        return len(self.components)

    def _wrap(self, a):
        return wrap_angle(a) if self.angle_period == 2.0 * np.pi else wrap_half_angle(a)

    def residual(self, z, zhat):
        """z - zhat, ``(..., dim_z)``, with the angle entries wrapped (period ``angle_period``)."""
        d = np.asarray(z, dtype=float) - np.asarray(zhat, dtype=float)
        if d.ndim == 0 or d.shape[-1] != self.dim_z:
            raise ValueError(f"z and zhat must have shape (..., {self.dim_z}), got {d.shape}")
        d = np.array(d)
        for i in self.angle_indices:
            d[..., i] = self._wrap(d[..., i])
        return d

    def in_range(self, target_pv, sensor_pv):
        """I_r indicator (Hernandez eq. 8): r_min <= range <= r_max, bool ``(...)``."""
        *_, r2 = _geometry(target_pv, sensor_pv)
        r = np.sqrt(r2)
        return (r >= self.r_min) & (r <= self.r_max)

    def sample(self, target_pv, sensor_pv, rng):
        """h + v, v ~ N(0, R), angle entries wrapped, ``(..., dim_z)``."""
        check_rng(rng)
        h = self.measure(target_pv, sensor_pv)
        z = h + rng.standard_normal(h.shape) @ np.linalg.cholesky(self.R).T
        for i in self.angle_indices:
            z[..., i] = self._wrap(z[..., i])
        return z

    def detect(self, target_pv, sensor_pv, rng):
        """Whether a measurement is received: I_r and a Bernoulli(pd) draw, bool ``(...)``."""
        check_rng(rng)
        inside = self.in_range(target_pv, sensor_pv)
        return inside & (rng.random(inside.shape) < self.pd)


@dataclass(frozen=True)
class BearingSensor(_Sensor):
    """Bearing-only sensor, z = atan2(dy, dx) + v, v ~ N(0, sigma^2) (Hernandez eq. 5, 9;
    Ramdaras eq. 6-7).  sigma in radians."""

    sigma: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = "bearing"
    components: ClassVar[tuple[str, ...]] = ("bearing",)
    angle_indices: ClassVar[tuple[int, ...]] = (0,)

    def __post_init__(self):
        object.__setattr__(self, "sigma", require_positive("sigma", self.sigma))
        self._validate_common()

    @property
    def R(self):
        return np.array([[self.sigma**2]])

    def measure(self, target_pv, sensor_pv):
        """Noise-free bearing (eq. 5), ``(..., 1)``."""
        dx, _, dy, _, _ = _geometry(target_pv, sensor_pv)
        return wrap_angle(np.arctan2(dy, dx))[..., None]

    def jacobian(self, target_pv, sensor_pv):
        """d bearing / d target_pv (eq. 9, see ``_bearing_row``), ``(..., 1, 4)``."""
        dx, _, dy, _, r2 = _geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "bearing Jacobian")
        return _bearing_row(dx, dy, r2)[..., None, :]


@dataclass(frozen=True)
class AmbiguousBearingSensor(BearingSensor):
    """Infinite-line bearing sensor of Vander Hook et al. (003, sec. I-II): the bearing is only
    known modulo pi, so z = wrap_half_angle(atan2(dy, dx)) + v in [-pi/2, pi/2) and residuals
    are wrapped modulo pi.  The Jacobian is that of the plain bearing (003, H_i in sec. II)."""

    kind: ClassVar[str] = "ambiguous_bearing"
    angle_period: ClassVar[float] = np.pi

    def measure(self, target_pv, sensor_pv):
        """Noise-free line orientation, ``(..., 1)`` in [-pi/2, pi/2)."""
        dx, _, dy, _, _ = _geometry(target_pv, sensor_pv)
        return wrap_half_angle(np.arctan2(dy, dx))[..., None]


@dataclass(frozen=True)
class RangeBearingSensor(_Sensor):
    """Range and bearing, z = (r, bearing) (Valverde eq. 10-14, Ramdaras eq. 8-9)."""

    sigma_r: float
    sigma_b: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = "range_bearing"
    components: ClassVar[tuple[str, ...]] = ("range", "bearing")
    angle_indices: ClassVar[tuple[int, ...]] = (1,)

    def __post_init__(self):
        object.__setattr__(self, "sigma_r", require_positive("sigma_r", self.sigma_r))
        object.__setattr__(self, "sigma_b", require_positive("sigma_b", self.sigma_b))
        self._validate_common()

    @property
    def R(self):
        """diag(sigma_r^2, sigma_b^2) (Ramdaras eq. 8)."""
        return np.diag([self.sigma_r**2, self.sigma_b**2])

    def measure(self, target_pv, sensor_pv):
        """(r, bearing) of eq. 10 / eq. 9, ``(..., 2)``."""
        dx, _, dy, _, r2 = _geometry(target_pv, sensor_pv)
        return np.stack([np.sqrt(r2), wrap_angle(np.arctan2(dy, dx))], axis=-1)

    def jacobian(self, target_pv, sensor_pv):
        """Valverde eq. 13 placed in the pv columns, ``(..., 2, 4)``."""
        dx, _, dy, _, r2 = _geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "range-bearing Jacobian")
        return np.stack([_range_row(dx, dy, np.sqrt(r2)), _bearing_row(dx, dy, r2)], axis=-2)


@dataclass(frozen=True)
class RangeRateBearingSensor(_Sensor):
    """Range, range rate (Doppler) and bearing: z = (r, rdot, bearing), the entry order of
    Ramdaras eq. 10-11.

    rdot is the relative radial velocity ((dx, dy) . (dvx, dvy)) / r with (dvx, dvy) the target
    velocity minus the sensor velocity.  (Ramdaras eq. 11 prints the target velocity alone,
    which equals this for a stationary sensor.)
    """

    sigma_r: float
    sigma_rr: float
    sigma_b: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = "range_rate_bearing"
    components: ClassVar[tuple[str, ...]] = ("range", "range_rate", "bearing")
    angle_indices: ClassVar[tuple[int, ...]] = (2,)

    def __post_init__(self):
        object.__setattr__(self, "sigma_r", require_positive("sigma_r", self.sigma_r))
        object.__setattr__(self, "sigma_rr", require_positive("sigma_rr", self.sigma_rr))
        object.__setattr__(self, "sigma_b", require_positive("sigma_b", self.sigma_b))
        self._validate_common()

    @property
    def R(self):
        """diag(sigma_r^2, sigma_rr^2, sigma_b^2) (Ramdaras eq. 10)."""
        return np.diag([self.sigma_r**2, self.sigma_rr**2, self.sigma_b**2])

    def measure(self, target_pv, sensor_pv):
        """(r, rdot, bearing) of eq. 11, ``(..., 3)``; zero range raises ValueError."""
        dx, dvx, dy, dvy, r2 = _geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "range rate")
        r = np.sqrt(r2)
        return np.stack([r, (dx * dvx + dy * dvy) / r, wrap_angle(np.arctan2(dy, dx))], axis=-1)

    def jacobian(self, target_pv, sensor_pv):
        """d (r, rdot, bearing) / d target_pv, ``(..., 3, 4)``.

        d rdot/dx = dy (dvx dy - dvy dx) / r^3,  d rdot/dy = dx (dvy dx - dvx dy) / r^3,
        d rdot/dxdot = dx / r,                   d rdot/dydot = dy / r.
        """
        dx, dvx, dy, dvy, r2 = _geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "range-rate-bearing Jacobian")
        r = np.sqrt(r2)
        cross = (dvx * dy - dvy * dx) / (r2 * r)
        rr_row = np.stack([dy * cross, dx / r, -dx * cross, dy / r], axis=-1)
        return np.stack([_range_row(dx, dy, r), rr_row, _bearing_row(dx, dy, r2)], axis=-2)


def state_jacobian(sensor, model, x, sensor_pv):
    """dh/dx for a model state: ``sensor.jacobian(model.kinematics(x), s) @
    model.kinematics_jacobian(x)``, shape ``(..., dim_z, model.dim)`` (broadcasting x, sensor)."""
    return sensor.jacobian(model.kinematics(x), sensor_pv) @ model.kinematics_jacobian(x)
