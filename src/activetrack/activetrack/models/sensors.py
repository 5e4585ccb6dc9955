"""Sensor measurement models (contract: ``activetrack.models.base.SensorModel``).

Sensors observe a target pv (x, xdot, y, ydot) from a platform pv (Hernandez eq. 6-7, Ramdaras
eq. 1): dx = x_t - x_s, dy = y_t - y_s (Ramdaras eq. 12), range sqrt(dx^2 + dy^2), bearing
atan2(dy, dx) wrapped to [-pi, pi); the two pvs broadcast, e.g. targets (M, 1, 4) against
sensors (1, C, 4) give (M, C, dim_z). Jacobians are with respect to the target pv
(``state_jacobian`` chains a motion model's); a bearing Jacobian at zero range raises
ValueError. ``in_range`` is I_r of Hernandez eq. 8; detection then succeeds with probability
``pd`` (Ramdaras eq. 14-22).

Each sensor is a :class:`~activetrack.models.base.GaussianSensor` overriding, with the same
numbers, what has a faster form: plain-float EKF linearisations, arcsin-wrapped particle
likelihoods, the closed form of Hernandez eq. 9 and compiled Fisher information.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from types import ModuleType
from typing import ClassVar

import numpy as np

from activetrack.angles import wrap_angle, wrap_half_angle
from activetrack.arraytypes import ArrayLike, BoolArray, FloatArray
from activetrack.checks import require_positive
from activetrack.kernels import particle_kernels
from activetrack.models._common import relative_geometry
from activetrack.models.base import (
    GaussianSensor,
    InformationKernel,
    Linearization,
    MotionModel,
    SensorModel,
    _miss_term,
)
from activetrack.models.fov import FieldOfView

__all__ = [
    "AmbiguousBearingSensor",
    "BearingSensor",
    "RangeBearingSensor",
    "RangeRateBearingSensor",
    "state_jacobian",
]

_TWO_PI = 2.0 * math.pi


def _require_nonzero_range(r2: FloatArray, what: str) -> None:
    if np.any(r2 == 0.0):
        raise ValueError(
            f"target_pv and sensor_pv coincide (range 0): the {what} is undefined; "
            "the range must be > 0"
        )


def _bearing_row(dx: FloatArray, dy: FloatArray, r2: FloatArray) -> FloatArray:
    """d atan2(dy, dx) / d (x, xdot, y, ydot) = (-dy, 0, dx, 0) / r^2.

    Hernandez eq. 9 prints the opposite sign; only H^T H enters his bound, so it is immaterial
    there, but the EKF needs the true derivative used here.
    """
    z = np.zeros_like(dx)
    return np.stack([-dy / r2, z, dx / r2, z], axis=-1)


def _range_row(dx: FloatArray, dy: FloatArray, r: FloatArray) -> FloatArray:
    z = np.zeros_like(dx)
    return np.stack([dx / r, z, dy / r, z], axis=-1)


# --- the inline forms: plain floats for one state, column arithmetic for particle arrays --------


def _wrap(a: float) -> float:
    """Scalar angle wrap to [-pi, pi) (the convention of ``angles.wrap_angle``)."""
    return (a + math.pi) % _TWO_PI - math.pi


def _scalar_geometry(
    target_pv: ArrayLike, sensor_pv: ArrayLike, z: ArrayLike
) -> tuple[float, float, float, list[float]]:
    """dx, dy, r^2 of one pv state ``(4,)`` and the entries of ``z``, as Python floats.

    No validation (inputs are checked where made): the inner loop of every EKF update, where
    numpy scalar indexing would cost more than the maths.
    """
    nd = np.ndarray
    x = target_pv.tolist() if type(target_pv) is nd and target_pv.ndim == 1 else None
    s = sensor_pv.tolist() if type(sensor_pv) is nd and sensor_pv.ndim == 1 else None
    x = _scalar_entries(target_pv) if x is None else x
    s = _scalar_entries(sensor_pv) if s is None else s
    zs = z.tolist() if type(z) is nd and z.ndim == 1 else _scalar_entries(z)
    dx, dy = x[0] - s[0], x[2] - s[2]
    r2 = dx * dx + dy * dy
    if r2 == 0.0:
        raise ValueError("measurements: target and sensor coincide (range 0); range must be > 0")
    return dx, dy, r2, zs


def _scalar_entries(a: ArrayLike) -> list[float]:
    """The entries of an array or nested sequence, flattened, as Python floats."""
    return [float(v) for v in np.asarray(a, dtype=float).reshape(-1)]


# Linearization(...) without the NamedTuple's Python-level __new__ (a third of a microsecond
# per EKF update).
_linearization = partial(tuple.__new__, Linearization)


def _offsets(
    target_pv: ArrayLike, sensor_pv: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Target-minus-sensor position (dx, dy) and range r, each ``(...)``, by column arithmetic
    (particle arrays ``(N, 4)``: no copy, no finiteness pass; a non-finite particle gives a
    non-finite likelihood, which the particle filter counts as zero weight)."""
    pv, s = np.asarray(target_pv, dtype=float), np.asarray(sensor_pv, dtype=float)
    if pv.ndim < 1 or pv.shape[-1] != 4 or s.ndim < 1 or s.shape[-1] != 4:
        raise ValueError(
            f"target_pv and sensor_pv must be pv states (..., 4), got {pv.shape} and {s.shape}"
        )
    dx = pv[..., 0] - s[..., 0]
    dy = pv[..., 2] - s[..., 2]
    return dx, dy, np.sqrt(dx * dx + dy * dy)


def _abs_bearing_error(dx: FloatArray, dy: FloatArray, r: FloatArray, zb: float) -> FloatArray:
    """|e| for the wrapped bearing residual e = wrap(zb - atan2(dy, dx)), per state.

    From r sin(e) = dx sin zb - dy cos zb and r cos(e) = dx cos zb + dy sin zb:
    |e| = asin(|r sin e| / r) when cos e >= 0, else pi - asin(...). Only e^2 enters the
    likelihood, and arcsin costs a fraction of arctan2 on large arrays. (|e| near pi/2 loses
    ~1e-8 rad to the arcsin's slope, immaterial for a likelihood that far in the tail.)
    """
    cz, sz = math.cos(zb), math.sin(zb)
    a = dx * sz
    a -= dy * cz
    np.abs(a, out=a)
    a /= r  # |sin e|; NaN for a state on the sensor (weight 0 downstream)
    np.minimum(a, 1.0, out=a)
    np.arcsin(a, out=a)
    behind = dx * cz + dy * sz < 0.0  # cos e < 0: |e| > pi/2
    np.subtract(math.pi, a, out=a, where=behind)
    return a


def _compiled_sines(
    kernels: ModuleType, target_pv: ArrayLike, sensor_pv: ArrayLike, zb: float
) -> tuple[FloatArray, BoolArray, FloatArray] | None:
    """The compiled first pass of the bearing likelihood for a particle array ``(N, 4)``
    (``kernels.bearing_sines``) with the arcsin applied: ``(arcsin |sin e|, behind, r)``, the
    intermediates of :func:`_abs_bearing_error`. None for other shapes and for a strided view
    (the numpy path; the kernel reads the rows flat)."""
    pv, s = target_pv, sensor_pv
    if not (
        type(pv) is np.ndarray
        and pv.ndim == 2
        and pv.shape[1] == 4
        and pv.dtype == np.float64
        and pv.flags.c_contiguous
        and type(s) is np.ndarray
        and s.shape == (4,)
    ):
        return None
    sines, behind, r = kernels.bearing_sines(
        pv, float(s[0]), float(s[2]), math.cos(zb), math.sin(zb)
    )
    np.arcsin(sines, out=sines)
    return sines, behind, r


def _gated(ell: FloatArray, r: FloatArray, sensor: GaussianSensor) -> FloatArray:
    """ell where r_min <= r <= r_max (I_r), -inf elsewhere."""
    return np.where((r >= sensor.r_min) & (r <= sensor.r_max), ell, -math.inf)


def _compiled_information(
    sensor: GaussianSensor, own: type, members: tuple[str, ...], kernel: str, **noise: float
) -> InformationKernel | None:
    """The compiled J_Z ``kernel`` with the sensor's ``noise``, pd, r_min and r_max bound in;
    None when the sensor's class overrides one of ``own``'s ``members`` (the kernel computes
    ``own``'s form). numba is imported on first use."""
    cls = type(sensor)
    if any(getattr(cls, m) is not getattr(own, m) for m in members):
        return None
    from activetrack.models import _fisher_kernels

    return partial(
        getattr(_fisher_kernels, kernel),
        **{k: float(v) for k, v in noise.items()},
        pd=float(sensor.pd),
        r_min=float(sensor.r_min),
        r_max=float(sensor.r_max),
    )


class _PlanarSensor(GaussianSensor):
    """The built-in sensors: detection by planar range alone, so a particle array's miss
    likelihood comes from column arithmetic (``in_range``'s numbers, no validation pass)."""

    def log_miss_likelihood(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """log(1 - pd I_r(x)) per state, ``(...)`` (Hernandez sec. 2.3)."""
        *_, r = _offsets(target_pv, sensor_pv)
        return _miss_term((r >= self.r_min) & (r <= self.r_max), float(self.pd))


# --- the sensors ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class _BearingFamily(_PlanarSensor):
    """Bearing-type sensors with noise sigma (rad): R = sigma^2, the Jacobian of eq. 9 and the
    closed-form Fisher information of Hernandez eq. 8-9."""

    sigma: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    components: ClassVar[tuple[str, ...]] = ("bearing",)
    angle_indices: ClassVar[tuple[int, ...]] = (0,)

    def __post_init__(self) -> None:
        object.__setattr__(self, "sigma", require_positive("sigma", self.sigma))
        self.validate_detection()

    @property
    def R(self) -> FloatArray:
        return np.array([[self.sigma**2]])

    def jacobian(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """d bearing / d target_pv (eq. 9, see ``_bearing_row``), ``(..., 1, 4)``."""
        dx, _, dy, _, r2 = relative_geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "bearing Jacobian")
        return _bearing_row(dx, dy, r2)[..., None, :]

    def fisher_information(
        self,
        target_samples: FloatArray,
        sensor_pv: FloatArray,
        kinematics_jacobian: FloatArray | None = None,
    ) -> FloatArray:
        """Closed form of Hernandez eq. 8-9.

        With dx = x - x_s, dy = y - y_s, r^2 = dx^2 + dy^2, eq. 9 gives H = (-dy, 0, dx, 0) / r^2,
        so H^T H / sigma^2 has entries (dy^2, -dx dy, dx^2) / (sigma^2 r^4) in the (x, y) block.
        Samples ``(M, 4)``, sensor states ``(..., 4)``; returns ``(..., n, n)``.
        """
        X, s, K = target_samples, sensor_pv, kinematics_jacobian
        dx = X[:, 0] - s[..., 0, None]  # (..., M)
        dy = X[:, 2] - s[..., 2, None]
        r2 = dx * dx
        r2 += dy * dy
        r_min, r_max = float(self.r_min), float(self.r_max)
        # Reductions decide whether any sample falls outside the detection ranges (eq. 8's
        # I_r: r_min <= r <= r_max) or sits on a sensor; the mask only if one does.
        lo = float(r2.min(initial=np.inf))
        hi = float(r2.max(initial=0.0)) if r_max < np.inf else 0.0
        if lo == 0.0:
            raise ValueError("sensor_states: a target sample coincides with a sensor (zero range)")
        if lo < r_min * r_min or hi > r_max * r_max:
            detect = (r2 >= r_min * r_min) & (r2 <= r_max * r_max)
            r2 = np.where(detect, r2, np.inf)  # r^2 = inf gives weight 0
        scale = float(self.pd) / (self.sigma**2 * X.shape[0])  # pd and the MC mean
        if K is None:
            # With a = dx / r^2 and b = dy / r^2: H^T H = (b^2, -a b, a^2) in the (x, y) block.
            inv = np.reciprocal(r2, out=r2)
            a = dx
            a *= inv
            b = dy
            b *= inv
            out = np.zeros((*a.shape[:-1], 4, 4))
            out[..., 0, 0] = scale * _dot(b, b)
            out[..., 2, 2] = scale * _dot(a, a)
            out[..., 0, 2] = out[..., 2, 0] = -scale * _dot(a, b)
            return out
        w = 1.0 / (r2 * r2)
        # Chain rule to a model state: H_state = H_pv @ dpv/dx (contract state_jacobian).
        g = dx[..., None] * K[:, 2, :] - dy[..., None] * K[:, 0, :]  # (..., M, n)
        return scale * np.einsum("...mi,...mj,...m->...ij", g, g, w)

    def information_kernel(self) -> InformationKernel | None:
        """The compiled eq. 8-9 (None when a subclass overrides :meth:`fisher_information`)."""
        return _compiled_information(
            self, _BearingFamily, ("fisher_information",), "bearing_information", sigma=self.sigma
        )


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """Sum over the last axis of a * b, ``(..., M) -> (...)`` (matmul: fast for small batches)."""
    return (a[..., None, :] @ b[..., :, None])[..., 0, 0]


def _uniform_bearings(u: FloatArray, fov: FieldOfView) -> FloatArray:
    """Bearings uniform over the field of view's sector from unit draws ``u`` ``(m,)``,
    wrapped to [-pi, pi)."""
    return np.remainder(fov.centre + (u - 0.5) * fov.width + math.pi, _TWO_PI) - math.pi


def _position_fix(
    r: float, b: float, var_r: float, var_b: float, sensor_pv: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Position ``p = s + r (cos b, sin b)`` and ``J diag(var_r, var_b) J^T`` (J = dp / d(r,
    b)) of a range-bearing fix seen from ``sensor_pv``."""
    cb, sb = math.cos(b), math.sin(b)
    J = np.array([[cb, -r * sb], [sb, r * cb]])
    xy = np.array([sensor_pv[0] + r * cb, sensor_pv[2] + r * sb])
    return xy, J @ np.diag([var_r, var_b]) @ J.T


@dataclass(frozen=True)
class BearingSensor(_BearingFamily):
    """Bearing-only sensor, z = atan2(dy, dx) + v, v ~ N(0, sigma^2) (Hernandez eq. 5, 9;
    Ramdaras eq. 6-7).  sigma in radians."""

    kind: ClassVar[str] = "bearing"

    def clutter_volume(self, fov: FieldOfView) -> float:
        """The sector's width [rad]: clutter is uniform in bearing over it."""
        return fov.width

    def uniform_measurements(self, u: FloatArray, fov: FieldOfView) -> FloatArray:
        """Bearings uniform over the sector, ``(m, 1)``."""
        return _uniform_bearings(u[:, -1], fov)[:, None]

    def measure(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """Noise-free bearing (eq. 5), ``(..., 1)``."""
        dx, _, dy, _, _ = relative_geometry(target_pv, sensor_pv)
        return wrap_angle(np.arctan2(dy, dx))[..., None]

    def linearize(self, target_pv: ArrayLike, sensor_pv: ArrayLike, z: ArrayLike) -> Linearization:
        """Eq. 5 and 9 at one pv state in plain floats (a few microseconds per EKF update
        instead of ~100 for the batched, validating methods)."""
        dx, dy, r2, zs = _scalar_geometry(target_pv, sensor_pv, z)
        bearing = _wrap(math.atan2(dy, dx))
        return _linearization(
            (
                np.array([bearing]),
                np.array([[-dy / r2, 0.0, dx / r2, 0.0]]),
                np.array([_wrap(zs[0] - bearing)]),
            )
        )

    def log_likelihood(
        self, z: ArrayLike, target_pv: ArrayLike, sensor_pv: ArrayLike, *, gate: bool = False
    ) -> tuple[FloatArray, float]:
        """-0.5 e^2 / sigma^2 per state with the arcsin-wrapped residual e (``GaussianSensor``
        for the contract)."""
        log_norm = self._likelihood_whitener[1]
        zb = float(z[-1] if type(z) is np.ndarray and z.ndim == 1 else _scalar_entries(z)[-1])
        coef = -0.5 / self.sigma**2
        kernels = particle_kernels()
        if kernels is not None and (pass1 := _compiled_sines(kernels, target_pv, sensor_pv, zb)):
            a, behind, r = pass1
            ell = kernels.bearing_finish(a, behind, r, coef, gate, self.r_min, self.r_max)
            return ell, log_norm
        dx, dy, r = _offsets(target_pv, sensor_pv)
        a = _abs_bearing_error(dx, dy, r, zb)
        a *= a
        a *= coef
        return (_gated(a, r, self) if gate else a), log_norm


@dataclass(frozen=True)
class AmbiguousBearingSensor(_BearingFamily):
    """Infinite-line bearing sensor of Vander Hook et al. (003, sec. I-II): the bearing is only
    known modulo pi, so z = wrap_half_angle(atan2(dy, dx)) + v in [-pi/2, pi/2) and residuals
    are wrapped modulo pi.  The Jacobian, and so the Fisher information, is that of the plain
    bearing (003, H_i in sec. II); the EKF and particle filter use the generic members."""

    kind: ClassVar[str] = "ambiguous_bearing"
    angle_period: ClassVar[float] = np.pi

    def measure(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """Noise-free line orientation, ``(..., 1)`` in [-pi/2, pi/2)."""
        dx, _, dy, _, _ = relative_geometry(target_pv, sensor_pv)
        return wrap_half_angle(np.arctan2(dy, dx))[..., None]


@dataclass(frozen=True)
class RangeBearingSensor(_PlanarSensor):
    """Range and bearing, z = (r, bearing) (Valverde eq. 10-14, Ramdaras eq. 8-9)."""

    sigma_r: float
    sigma_b: float
    pd: float = 1.0
    r_min: float = 0.0
    r_max: float = math.inf

    kind: ClassVar[str] = "range_bearing"
    components: ClassVar[tuple[str, ...]] = ("range", "bearing")
    angle_indices: ClassVar[tuple[int, ...]] = (1,)

    def __post_init__(self) -> None:
        object.__setattr__(self, "sigma_r", require_positive("sigma_r", self.sigma_r))
        object.__setattr__(self, "sigma_b", require_positive("sigma_b", self.sigma_b))
        self.validate_detection()

    def clutter_volume(self, fov: FieldOfView) -> float:
        """Sector width [rad] times the range interval [m] (infinite for an unbounded range:
        clutter needs a finite ``r_max``)."""
        return fov.width * (fov.r_max - fov.r_min)

    def uniform_measurements(self, u: FloatArray, fov: FieldOfView) -> FloatArray:
        """(range, bearing) uniform over the range interval and the sector, ``(m, 2)``."""
        r = fov.r_min + u[:, 0] * (fov.r_max - fov.r_min)
        return np.column_stack([r, _uniform_bearings(u[:, -1], fov)])

    def inverse_position(
        self, z: FloatArray, sensor_pv: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """``p = s + r (cos b, sin b)`` and ``J R J^T`` (J = dp / dz)."""
        return _position_fix(float(z[0]), float(z[1]), self.sigma_r**2, self.sigma_b**2, sensor_pv)

    @property
    def R(self) -> FloatArray:
        """diag(sigma_r^2, sigma_b^2) (Ramdaras eq. 8)."""
        return np.diag([self.sigma_r**2, self.sigma_b**2])

    def measure(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """(r, bearing) of eq. 10 / eq. 9, ``(..., 2)``."""
        dx, _, dy, _, r2 = relative_geometry(target_pv, sensor_pv)
        return np.stack([np.sqrt(r2), wrap_angle(np.arctan2(dy, dx))], axis=-1)

    def jacobian(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """Valverde eq. 13 placed in the pv columns, ``(..., 2, 4)``."""
        dx, _, dy, _, r2 = relative_geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "range-bearing Jacobian")
        return np.stack([_range_row(dx, dy, np.sqrt(r2)), _bearing_row(dx, dy, r2)], axis=-2)

    def linearize(self, target_pv: ArrayLike, sensor_pv: ArrayLike, z: ArrayLike) -> Linearization:
        """Valverde eq. 10-13 at one pv state in plain floats (see ``BearingSensor``)."""
        dx, dy, r2, zs = _scalar_geometry(target_pv, sensor_pv, z)
        bearing = _wrap(math.atan2(dy, dx))
        r = math.sqrt(r2)
        return _linearization(
            (
                np.array([r, bearing]),
                np.array([[dx / r, 0.0, dy / r, 0.0], [-dy / r2, 0.0, dx / r2, 0.0]]),
                np.array([zs[0] - r, _wrap(zs[1] - bearing)]),
            )
        )

    def log_likelihood(
        self, z: ArrayLike, target_pv: ArrayLike, sensor_pv: ArrayLike, *, gate: bool = False
    ) -> tuple[FloatArray, float]:
        """-0.5 (e_r^2 / sigma_r^2 + e_b^2 / sigma_b^2) per state, the bearing residual
        arcsin-wrapped (``GaussianSensor`` for the contract)."""
        log_norm = self._likelihood_whitener[1]
        zr, zb = _scalar_entries(z)[:2]
        kernels = particle_kernels()
        if kernels is not None and (pass1 := _compiled_sines(kernels, target_pv, sensor_pv, zb)):
            a, behind, r = pass1
            ell = kernels.range_bearing_finish(
                a, behind, r, zr, self.sigma_r, self.sigma_b, gate, self.r_min, self.r_max
            )
            return ell, log_norm
        dx, dy, r = _offsets(target_pv, sensor_pv)
        a = _abs_bearing_error(dx, dy, r, zb)
        a /= self.sigma_b
        e_r = (zr - r) / self.sigma_r
        ell = -0.5 * (a * a + e_r * e_r)
        return (_gated(ell, r, self) if gate else ell), log_norm

    def information_kernel(self) -> InformationKernel | None:
        """The compiled eq. 8 of the range and bearing rows (equal to the generic form to
        round-off; None when a subclass overrides its information, Jacobian or R)."""
        return _compiled_information(
            self,
            RangeBearingSensor,
            ("fisher_information", "jacobian", "R"),
            "range_bearing_information",
            sigma_r=self.sigma_r,
            sigma_b=self.sigma_b,
        )


@dataclass(frozen=True)
class RangeRateBearingSensor(_PlanarSensor):
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

    def __post_init__(self) -> None:
        object.__setattr__(self, "sigma_r", require_positive("sigma_r", self.sigma_r))
        object.__setattr__(self, "sigma_rr", require_positive("sigma_rr", self.sigma_rr))
        object.__setattr__(self, "sigma_b", require_positive("sigma_b", self.sigma_b))
        self.validate_detection()

    def inverse_position(
        self, z: FloatArray, sensor_pv: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The range and bearing's position fix ``s + r (cos b, sin b)``, ``J R_rb J^T``."""
        return _position_fix(float(z[0]), float(z[2]), self.sigma_r**2, self.sigma_b**2, sensor_pv)

    @property
    def R(self) -> FloatArray:
        """diag(sigma_r^2, sigma_rr^2, sigma_b^2) (Ramdaras eq. 10)."""
        return np.diag([self.sigma_r**2, self.sigma_rr**2, self.sigma_b**2])

    def measure(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """(r, rdot, bearing) of eq. 11, ``(..., 3)``; zero range raises ValueError."""
        dx, dvx, dy, dvy, r2 = relative_geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "range rate")
        r = np.sqrt(r2)
        return np.stack([r, (dx * dvx + dy * dvy) / r, wrap_angle(np.arctan2(dy, dx))], axis=-1)

    def jacobian(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """d (r, rdot, bearing) / d target_pv, ``(..., 3, 4)``.

        d rdot/dx = dy (dvx dy - dvy dx) / r^3,  d rdot/dy = dx (dvy dx - dvx dy) / r^3,
        d rdot/dxdot = dx / r,                   d rdot/dydot = dy / r.
        """
        dx, dvx, dy, dvy, r2 = relative_geometry(target_pv, sensor_pv)
        _require_nonzero_range(r2, "range-rate-bearing Jacobian")
        r = np.sqrt(r2)
        cross = (dvx * dy - dvy * dx) / (r2 * r)
        rr_row = np.stack([dy * cross, dx / r, -dx * cross, dy / r], axis=-1)
        return np.stack([_range_row(dx, dy, r), rr_row, _bearing_row(dx, dy, r2)], axis=-2)

    def information_kernel(self) -> InformationKernel | None:
        """The compiled eq. 8 of :meth:`jacobian`'s three rows (equal to the generic form to
        round-off; None when a subclass overrides its information, Jacobian or R)."""
        return _compiled_information(
            self,
            RangeRateBearingSensor,
            ("fisher_information", "jacobian", "R"),
            "range_rate_bearing_information",
            sigma_r=self.sigma_r,
            sigma_rr=self.sigma_rr,
            sigma_b=self.sigma_b,
        )


def state_jacobian(
    sensor: SensorModel, model: MotionModel, x: ArrayLike, sensor_pv: ArrayLike
) -> FloatArray:
    """dh/dx for a model state: ``sensor.jacobian(model.kinematics(x), s) @
    model.kinematics_jacobian(x)``, shape ``(..., dim_z, model.dim)`` (broadcasting x, sensor)."""
    return sensor.jacobian(model.kinematics(x), sensor_pv) @ model.kinematics_jacobian(x)
