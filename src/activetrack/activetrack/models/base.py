"""The two contracts of the core's models: a target motion model and a sensor.

``MotionModel`` (``LinearMotionModel``) and ``SensorModel`` are ``typing.Protocol`` classes
(structural typing, checked by mypy): a sensor may be written from scratch, and it owns its
maths (EKF linearisation, particle weights, Fisher information, clutter, track initiation), so
no consumer special-cases by class.

``GaussianSensor`` is the optional base class for z = h(x) + v, v ~ N(0, R): a subclass defines
``kind``, ``components``, ``R``, ``measure`` and ``jacobian`` (and its angle entries) and
inherits vectorised versions of the other members; the built-in sensors override some with
closed forms. Conventions (docs/core-interfaces.md): pv = (x, xdot, y, ydot); a state batch is
``(..., n)``; bad input raises ValueError naming the argument.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from functools import cached_property
from typing import ClassVar, NamedTuple, Protocol, cast

import numpy as np

from activetrack.angles import wrap_angle, wrap_half_angle
from activetrack.arraytypes import ArrayLike, BoolArray, FloatArray
from activetrack.checks import require_in_range, symmetrize
from activetrack.linalg import whitener
from activetrack.models._common import check_rng, relative_geometry
from activetrack.models.fov import FieldOfView

__all__ = [
    "GaussianSensor",
    "InformationKernel",
    "LinearMotionModel",
    "Linearization",
    "MotionModel",
    "SensorModel",
    "as_linear",
    "jacobian_information",
]

_LOG_2PI = math.log(2.0 * math.pi)


class MotionModel(Protocol):
    """A target motion model x_{k+1} = f(x_k) + w_k, w_k ~ N(0, Q) (docs/core-interfaces.md)."""

    @property
    def dim(self) -> int:
        """State dimension n."""
        ...

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the state entries (for messages and plots; never branched on)."""
        ...

    @property
    def is_linear(self) -> bool:
        """True when f(x) = F x with a constant F (then ``transition_matrix`` exists)."""
        ...

    @property
    def state_is_pv(self) -> bool:
        """True when ``kinematics`` is the identity (the state may stand for a pv)."""

        ...

    def propagate(self, x: ArrayLike, dt: float) -> FloatArray:
        """Noise-free f(x), ``(..., n) -> (..., n)``."""
        ...

    def jacobian(self, x: ArrayLike, dt: float) -> FloatArray:
        """df/dx, ``(..., n, n)``."""
        ...

    def process_noise(self, dt: float, x: ArrayLike | None = None) -> FloatArray:
        """Q, ``(n, n)`` (or ``(..., n, n)`` when it depends on x)."""
        ...

    def sample(self, x: ArrayLike, dt: float, rng: np.random.Generator) -> FloatArray:
        """f(x) + w, w ~ N(0, Q), independently for every state of the batch."""
        ...

    def kinematics(self, x: ArrayLike) -> FloatArray:
        """pv of the target, ``(..., 4)``."""
        ...

    def kinematics_jacobian(self, x: ArrayLike) -> FloatArray:
        """d pv / dx, ``(..., 4, n)``."""
        ...


class LinearMotionModel(MotionModel, Protocol):
    """A motion model with ``is_linear`` true: f(x) = F x."""

    def transition_matrix(self, dt: float) -> FloatArray:
        """The constant F, ``(n, n)``."""
        ...


def as_linear(model: MotionModel) -> LinearMotionModel:
    """``model`` as a :class:`LinearMotionModel`; ValueError unless ``model.is_linear``."""
    if not model.is_linear:
        raise ValueError(f"model must have linear dynamics (is_linear), got {type(model).__name__}")
    return cast(LinearMotionModel, model)


class Linearization(NamedTuple):
    """A sensor linearised at one pv state: h(x) ``(dim_z,)``, H = dh/d pv ``(dim_z, 4)`` and
    the residual z - h(x) with angle entries wrapped ``(dim_z,)``."""

    zhat: FloatArray
    H: FloatArray
    nu: FloatArray


class SensorModel(Protocol):
    """A sensor observing a target pv from a platform pv (docs/core-interfaces.md).

    ``target_pv`` and ``sensor_pv`` broadcast against each other over leading axes.
    """

    @property
    def kind(self) -> str:
        """Registered name of the sensor kind (``activetrack.scenarios.registry``)."""
        ...

    @property
    def components(self) -> tuple[str, ...]:
        """Names of the entries of z, e.g. ``("range", "bearing")``."""
        ...

    @property
    def dim_z(self) -> int: ...

    @property
    def R(self) -> FloatArray:
        """Measurement noise covariance ``(dim_z, dim_z)``."""
        ...

    @property
    def pd(self) -> float:
        """Detection probability inside the detection ranges, in (0, 1]."""
        ...

    @property
    def r_min(self) -> float: ...

    @property
    def r_max(self) -> float: ...

    def measure(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """Noise-free h, ``(..., dim_z)``."""
        ...

    def jacobian(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """dh / d target_pv, ``(..., dim_z, 4)``."""
        ...

    def residual(self, z: ArrayLike, zhat: ArrayLike) -> FloatArray:
        """z - zhat with angle entries wrapped, ``(..., dim_z)``."""
        ...

    def in_range(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> BoolArray:
        """I_r of Hernandez eq. 8: r_min <= range <= r_max, ``(...)``."""
        ...

    def detect(
        self, target_pv: ArrayLike, sensor_pv: ArrayLike, rng: np.random.Generator
    ) -> BoolArray:
        """Whether a measurement is received (I_r and a Bernoulli(pd) draw), ``(...)``."""
        ...

    def sample(
        self, target_pv: ArrayLike, sensor_pv: ArrayLike, rng: np.random.Generator
    ) -> FloatArray:
        """h + v, v ~ N(0, R), angle entries wrapped, ``(..., dim_z)``."""
        ...

    def linearize(self, target_pv: ArrayLike, sensor_pv: ArrayLike, z: ArrayLike) -> Linearization:
        """h, dh/d pv and the wrapped residual at one pv state ``(4,)`` (the EKF's update)."""
        ...

    def log_likelihood(
        self, z: ArrayLike, target_pv: ArrayLike, sensor_pv: ArrayLike, *, gate: bool = False
    ) -> tuple[FloatArray, float]:
        """log N(z; h(x), R) = ell + c per state: ell ``(...)`` (``gate``: -inf where I_r = 0,
        Hernandez sec. 2.3), c independent of the state."""
        ...

    def log_miss_likelihood(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """log P(no detection | x) = log(1 - pd I_r(x)) for every state, ``(...)``."""
        ...

    def fisher_information(
        self,
        target_samples: FloatArray,
        sensor_pv: FloatArray,
        kinematics_jacobian: FloatArray | None = None,
    ) -> FloatArray:
        """Hernandez eq. 8: (1/M) sum_m pd I_r H^T R^-1 H over pv samples ``(M, 4)`` for sensor
        pvs ``(..., 4)`` -> ``(..., 4, 4)``, or ``(..., n, n)`` given d pv / dx ``(M, 4, n)``.
        Inputs are taken as checked (``bounds.pcrlb.measurement_information``)."""
        ...

    def clutter_volume(self, fov: FieldOfView) -> float | None:
        """The field of view's volume in measurement units (what a clutter density is per);
        None without a clutter model."""
        ...

    def uniform_measurements(self, u: FloatArray, fov: FieldOfView) -> FloatArray:
        """False alarms ``(m, dim_z)`` uniform over the field of view from draws ``u`` in [0, 1)."""
        ...

    def inverse_position(
        self, z: FloatArray, sensor_pv: FloatArray
    ) -> tuple[FloatArray, FloatArray] | None:
        """The position ``(2,)`` and covariance ``(2, 2)`` one detection fixes (linearised
        inverse measurement; starts a track); None for, e.g., a bearing."""
        ...


# A sensor's compiled Fisher information (optional ``information_kernel()`` of a sensor):
# (pv samples (M, 4), sensor pv states (N, 4)) -> (N, 4, 4), the numbers of its
# ``fisher_information`` (pv, no kinematics Jacobian) to round-off. Inputs are taken as checked.
InformationKernel = Callable[[FloatArray, FloatArray], FloatArray]


def jacobian_information(
    sensor: SensorModel,
    target_samples: FloatArray,
    sensor_pv: FloatArray,
    kinematics_jacobian: FloatArray | None = None,
) -> FloatArray:
    """Hernandez eq. 8 through ``sensor.jacobian``: (1/M) sum_m pd I_r H^T R^-1 H as G^T G,
    G = R^{-1/2} H (times d pv / dx if given). Samples ``(M, 4)``, sensor pvs ``(..., 4)`` ->
    ``(..., n, n)``."""
    X, K = target_samples, kinematics_jacobian
    sp = sensor_pv[..., None, :]  # (..., 1, 4) broadcasts against the M samples
    H = np.asarray(sensor.jacobian(X, sp), dtype=float)  # (..., M, m, 4)
    detect = np.asarray(sensor.in_range(X, sp), dtype=bool)  # (..., M)
    w = np.where(detect, float(sensor.pd) / X.shape[0], 0.0)
    G = whitener(sensor.R) @ H  # R^{-1/2} H
    if K is not None:
        G = G @ K
    sums = _compiled_sums(G.size // (G.shape[-1] * G.shape[-2]))
    if sums is not None:  # the einsum's bits, compiled
        return symmetrize(sums(G, w))
    # einsum round-off can leave a tiny asymmetry.
    return symmetrize(np.einsum("...mai,...maj,...m->...ij", G, G, w))


def _compiled_sums(work: int) -> Callable[[FloatArray, FloatArray], FloatArray] | None:
    """The compiled sums of :func:`jacobian_information` when the compiled kernels run: they
    give the einsum's bits, so, like the particle kernels, they may switch on mid-process
    (``work``, the sample-state pairs, counts towards ``activetrack.kernels.AUTO_WORK``)."""
    from activetrack.kernels import particle_kernels

    if particle_kernels(work=work) is None:
        return None
    from activetrack.models._fisher_kernels import jacobian_information_sums

    return jacobian_information_sums


def _log_gauss_whitener(R: FloatArray) -> tuple[FloatArray, float]:
    """``(L^-1)^T`` and ``-0.5 log det(2 pi R)`` for R = L L^T."""
    L = np.linalg.cholesky(R)
    dim_z = R.shape[0]
    Linv_T = np.linalg.solve(L, np.eye(dim_z)).T
    return Linv_T, -float(np.sum(np.log(np.diag(L)))) - 0.5 * dim_z * _LOG_2PI


class GaussianSensor(ABC):
    """Base of sensors z = h(x) + v, v ~ N(0, R): frozen dataclasses with ``pd``, ``r_min``,
    ``r_max`` (``__post_init__`` calls :meth:`validate_detection`) defining ``kind``,
    ``components``, ``R``, ``measure``, ``jacobian`` and the wrapped ``angle_indices``."""

    kind: ClassVar[str]
    components: ClassVar[tuple[str, ...]]
    # Indices of angle entries in z and the period they are wrapped with.
    angle_indices: ClassVar[tuple[int, ...]] = ()
    angle_period: ClassVar[float] = 2.0 * np.pi
    pd: float
    r_min: float
    r_max: float

    @property
    @abstractmethod
    def R(self) -> FloatArray:
        """Measurement noise covariance ``(dim_z, dim_z)``."""

    @abstractmethod
    def measure(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """Noise-free h, ``(..., dim_z)``."""

    @abstractmethod
    def jacobian(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """dh / d target_pv, ``(..., dim_z, 4)``."""

    def validate_detection(self) -> None:
        """Check and store pd in (0, 1] and 0 <= r_min < r_max <= inf (from __post_init__)."""
        pd = require_in_range("pd", self.pd, 0.0, 1.0, lo_inclusive=False)
        r_min = require_in_range("r_min", self.r_min, 0.0, math.inf, hi_inclusive=False)
        r_max = require_in_range("r_max", self.r_max, 0.0, math.inf)
        if not r_min < r_max:
            raise ValueError(f"r_max must be > r_min = {r_min}, got {r_max}")
        for name, value in (("pd", pd), ("r_min", r_min), ("r_max", r_max)):
            object.__setattr__(self, name, value)

    @property
    def dim_z(self) -> int:
        return len(self.components)

    def _wrapped(self, z: FloatArray) -> FloatArray:
        """``z`` with its angle entries wrapped in place (period ``angle_period``)."""
        wrap = wrap_angle if self.angle_period == 2.0 * np.pi else wrap_half_angle
        for i in self.angle_indices:
            z[..., i] = wrap(z[..., i])
        return z

    def residual(self, z: ArrayLike, zhat: ArrayLike) -> FloatArray:
        """z - zhat, ``(..., dim_z)``, with the angle entries wrapped (period ``angle_period``)."""
        d = np.asarray(z, dtype=float) - np.asarray(zhat, dtype=float)
        if d.ndim == 0 or d.shape[-1] != self.dim_z:
            raise ValueError(f"z and zhat must have shape (..., {self.dim_z}), got {d.shape}")
        return self._wrapped(np.array(d))

    def in_range(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> BoolArray:
        """I_r indicator (Hernandez eq. 8): r_min <= range <= r_max, bool ``(...)``."""
        *_, r2 = relative_geometry(target_pv, sensor_pv)
        r = np.sqrt(r2)
        return (r >= self.r_min) & (r <= self.r_max)

    def sample(
        self, target_pv: ArrayLike, sensor_pv: ArrayLike, rng: np.random.Generator
    ) -> FloatArray:
        """h + v, v ~ N(0, R), angle entries wrapped, ``(..., dim_z)``."""
        check_rng(rng)
        h = self.measure(target_pv, sensor_pv)
        return self._wrapped(h + rng.standard_normal(h.shape) @ self._noise_factor.T)

    def detect(
        self, target_pv: ArrayLike, sensor_pv: ArrayLike, rng: np.random.Generator
    ) -> BoolArray:
        """Whether a measurement is received: I_r and a Bernoulli(pd) draw, bool ``(...)``."""
        check_rng(rng)
        inside = self.in_range(target_pv, sensor_pv)
        return inside & (rng.random(inside.shape) < self.pd)

    def linearize(self, target_pv: ArrayLike, sensor_pv: ArrayLike, z: ArrayLike) -> Linearization:
        """h(x), H = dh/d pv and nu = z - h(x) wrapped (Valverde eq. 5-9, Ramdaras eq. 13, 18)
        at one pv state ``(4,)``: ``(dim_z,)``, ``(dim_z, 4)``, ``(dim_z,)``."""
        zhat = self.measure(target_pv, sensor_pv)
        nu = np.asarray(self.residual(z, zhat), dtype=float).reshape(-1)
        H = np.asarray(self.jacobian(target_pv, sensor_pv), dtype=float)
        return Linearization(zhat, H, nu)

    # Cached: sensors are frozen, and factorising R cost more than one simulated draw.
    @cached_property
    def _noise_factor(self) -> FloatArray:
        return np.linalg.cholesky(self.R)

    @cached_property
    def _likelihood_whitener(self) -> tuple[FloatArray, float]:
        return _log_gauss_whitener(np.asarray(self.R, dtype=float))

    def log_likelihood(
        self, z: ArrayLike, target_pv: ArrayLike, sensor_pv: ArrayLike, *, gate: bool = False
    ) -> tuple[FloatArray, float]:
        """``(ell, c)`` with ell = -0.5 nu^T R^-1 nu ``(...)`` (-inf outside [r_min, r_max] with
        ``gate``; pd is the caller's) and c = -0.5 log det(2 pi R): a particle filter normalises
        without c, so its weights do not depend on how c rounds."""
        Linv_T, log_norm = self._likelihood_whitener
        e = self.residual(z, self.measure(target_pv, sensor_pv)) @ Linv_T  # (..., dim_z)
        flat = e.reshape(-1, e.shape[-1])
        ell = (-0.5 * np.einsum("ij,ij->i", flat, flat)).reshape(e.shape[:-1])
        if gate:
            ell = np.where(self.in_range(target_pv, sensor_pv), ell, -math.inf)
        return ell, log_norm

    def log_miss_likelihood(self, target_pv: ArrayLike, sensor_pv: ArrayLike) -> FloatArray:
        """log(1 - pd I_r(x)) per state ``(...)`` (-inf inside for pd = 1)."""
        return _miss_term(self.in_range(target_pv, sensor_pv), float(self.pd))

    def fisher_information(
        self,
        target_samples: FloatArray,
        sensor_pv: FloatArray,
        kinematics_jacobian: FloatArray | None = None,
    ) -> FloatArray:
        """Hernandez eq. 8 through the Jacobian (:func:`jacobian_information`)."""
        return jacobian_information(self, target_samples, sensor_pv, kinematics_jacobian)

    # The generic sensor has no compiled information, no clutter model and fixes no position.
    def information_kernel(self) -> InformationKernel | None:
        return None

    def clutter_volume(self, fov: FieldOfView) -> float | None:
        return None

    def uniform_measurements(self, u: FloatArray, fov: FieldOfView) -> FloatArray:
        raise NotImplementedError(f"sensor kind {self.kind!r} has no clutter model")

    def inverse_position(
        self, z: FloatArray, sensor_pv: FloatArray
    ) -> tuple[FloatArray, FloatArray] | None:
        return None


def _miss_term(inside: BoolArray, pd: float) -> FloatArray:
    """log(1 - pd I_r): ``where(inside, log(1 - pd), 0)``."""
    return np.where(inside, math.log(1.0 - pd) if pd < 1.0 else -math.inf, 0.0)
