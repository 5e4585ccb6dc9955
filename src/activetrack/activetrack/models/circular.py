"""Circular-motion state model (Valverde sec. IV-A, eq. 15-29).

State (psi, px, py, omega, v): heading psi (rad, from +x, counter-clockwise), position p (m),
turn rate omega (rad/s) and speed v (m/s); the velocity is v (cos psi, sin psi) (eq. 15).
Over a step T with theta = omega T, eq. 24 gives

    psi' = psi + theta
    p'   = p + R(psi) (I - R(theta))/omega [0, v]^T = p + v [A, B]^T
    A    = cos(psi) s1 - sin(psi) c1,   B = sin(psi) s1 + cos(psi) c1
    omega' = omega + sqrt(T) eta_omega,  v' = v + sqrt(T) eta_v

with s1 = sin(theta)/omega and c1 = (1 - cos(theta))/omega (series near omega = 0, see
_turn_terms), and Q = blkdiag(0_3, T diag(sigma_omega^2, sigma_v^2)) (eq. 25).

The Jacobian eq. 26-28 is OCR-damaged in the source, so it is derived here from eq. 24:

    d p'/d psi   = v [-B, A]^T
    d p'/d omega = v [cos(psi) ds1 - sin(psi) dc1,  sin(psi) ds1 + cos(psi) dc1]^T
    d p'/d v     = [A, B]^T,        d psi'/d omega = T

(ds1, dc1 = d s1/d omega, d c1/d omega) and is checked against finite differences in the tests.
The known-omega variant (eq. 29) drops omega from the state: (psi, px, py, v).

psi is not wrapped by ``propagate``: it evolves continuously, so particle means stay valid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite, require_nonnegative
from activetrack.models._common import add_gaussian_noise, check_dt, check_rng, check_state
from activetrack.models._turn_terms import turn_terms


def _circular_step(
    psi: FloatArray, px: FloatArray, py: FloatArray, omega: ArrayLike, v: FloatArray, T: float
) -> tuple[tuple[FloatArray, FloatArray], tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
    """Eq. 24 without noise plus the partial derivatives of (px', py') (module docstring)."""
    s1, c1, _, _, ds1, dc1 = turn_terms(omega, T)
    cos, sin = np.cos(psi), np.sin(psi)
    A = cos * s1 - sin * c1
    B = sin * s1 + cos * c1
    dA_domega = cos * ds1 - sin * dc1
    dB_domega = sin * ds1 + cos * dc1
    return (px + v * A, py + v * B), (A, B, dA_domega, dB_domega)


def _pv_from_heading(psi: FloatArray, px: FloatArray, py: FloatArray, v: FloatArray) -> FloatArray:
    return np.stack([px, v * np.cos(psi), py, v * np.sin(psi)], axis=-1)


def _pv_jacobian_rows(
    psi: FloatArray, v: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """d pv / d (psi, px, py, v) as four (..., 4) rows."""
    z, one = np.zeros_like(psi), np.ones_like(psi)
    cos, sin = np.cos(psi), np.sin(psi)
    return (
        np.stack([z, one, z, z], axis=-1),
        np.stack([-v * sin, z, z, cos], axis=-1),
        np.stack([z, z, one, z], axis=-1),
        np.stack([v * cos, z, z, sin], axis=-1),
    )


@dataclass(frozen=True)
class CircularMotion:
    """Valverde eq. 24-25 with stochastic accelerations on omega and v (std per sqrt(s))."""

    sigma_omega: float
    sigma_v: float

    dim: ClassVar[int] = 5
    state_names: ClassVar[tuple[str, ...]] = ("psi", "px", "py", "omega", "v")
    is_linear: ClassVar[bool] = False
    state_is_pv: ClassVar[bool] = False

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "sigma_omega", require_nonnegative("sigma_omega", self.sigma_omega)
        )
        object.__setattr__(self, "sigma_v", require_nonnegative("sigma_v", self.sigma_v))

    def propagate(self, x: ArrayLike, dt: float) -> FloatArray:
        """Noise-free eq. 24, ``(..., 5) -> (..., 5)``."""
        x = check_state("x", x, 5)
        T = check_dt(dt)
        psi, px, py, omega, v = np.moveaxis(x, -1, 0)
        (px1, py1), _ = _circular_step(psi, px, py, omega, v, T)
        return np.stack([psi + omega * T, px1, py1, omega, v], axis=-1)

    def jacobian(self, x: ArrayLike, dt: float) -> FloatArray:
        """d f / d x of eq. 24 (replaces the damaged eq. 26-28), ``(..., 5, 5)``."""
        x = check_state("x", x, 5)
        T = check_dt(dt)
        psi, px, py, omega, v = np.moveaxis(x, -1, 0)
        _, (A, B, dA, dB) = _circular_step(psi, px, py, omega, v, T)
        F = np.zeros((*x.shape[:-1], 5, 5))
        F[..., range(5), range(5)] = 1.0
        F[..., 0, 3] = T
        F[..., 1, 0], F[..., 1, 3], F[..., 1, 4] = -v * B, v * dA, A
        F[..., 2, 0], F[..., 2, 3], F[..., 2, 4] = v * A, v * dB, B
        return F

    def process_noise(self, dt: float, x: ArrayLike | None = None) -> FloatArray:
        """Q = blkdiag(0_3, T diag(sigma_omega^2, sigma_v^2)) (eq. 25), (5, 5)."""
        T = check_dt(dt)
        return np.diag([0.0, 0.0, 0.0, T * self.sigma_omega**2, T * self.sigma_v**2])

    def sample(self, x: ArrayLike, dt: float, rng: np.random.Generator) -> FloatArray:
        """f(x) + sqrt(T) B eta (eq. 24), batched over ``(..., 5)``."""
        check_rng(rng)
        return add_gaussian_noise(self.propagate(x, dt), self.process_noise(dt), rng)

    def kinematics(self, x: ArrayLike) -> FloatArray:
        """pv = (px, v cos psi, py, v sin psi), ``(..., 4)``."""
        x = check_state("x", x, 5)
        psi, px, py, _, v = np.moveaxis(x, -1, 0)
        return _pv_from_heading(psi, px, py, v)

    def kinematics_jacobian(self, x: ArrayLike) -> FloatArray:
        """d pv / d x, ``(..., 4, 5)`` (zero column for omega)."""
        x = check_state("x", x, 5)
        psi, v = x[..., 0], x[..., 4]
        rows = np.stack(_pv_jacobian_rows(psi, v), axis=-2)  # (..., 4, 4) over psi, px, py, v
        return np.insert(rows, 3, 0.0, axis=-1)


# Eq. 29 is eq. 24 with omega fixed: CircularMotion on (psi, px, py, omega, v), _KNOWN its rows.
_FULL = CircularMotion(0.0, 0.0)
_KNOWN = [0, 1, 2, 4]


@dataclass(frozen=True)
class CircularMotionKnownOmega:
    """Circular motion with a known turn rate ``omega`` (Valverde eq. 29); state (psi, px, py, v):
    eq. 24-28 with omega fixed. The noise covariance is eq. 25 without the omega entry:
    blkdiag(0_3, T sigma_v^2).
    """

    omega: float
    sigma_v: float

    dim: ClassVar[int] = 4
    state_names: ClassVar[tuple[str, ...]] = ("psi", "px", "py", "v")
    is_linear: ClassVar[bool] = False
    state_is_pv: ClassVar[bool] = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "omega", float(require_finite("omega", self.omega)))
        object.__setattr__(self, "sigma_v", require_nonnegative("sigma_v", self.sigma_v))

    def _with_omega(self, x: ArrayLike) -> FloatArray:
        """(psi, px, py, omega, v), ``(..., 5)``."""
        return np.insert(check_state("x", x, 4), 3, self.omega, axis=-1)

    def propagate(self, x: ArrayLike, dt: float) -> FloatArray:
        """Noise-free eq. 29, ``(..., 4) -> (..., 4)``."""
        return _FULL.propagate(self._with_omega(x), dt)[..., _KNOWN]

    def jacobian(self, x: ArrayLike, dt: float) -> FloatArray:
        """Eq. 26-28 with the omega row and column deleted, ``(..., 4, 4)``."""
        return _FULL.jacobian(self._with_omega(x), dt)[..., _KNOWN, :][..., _KNOWN]

    def process_noise(self, dt: float, x: ArrayLike | None = None) -> FloatArray:
        """Q = diag(0, 0, 0, T sigma_v^2), (4, 4)."""
        T = check_dt(dt)
        return np.diag([0.0, 0.0, 0.0, T * self.sigma_v**2])

    def sample(self, x: ArrayLike, dt: float, rng: np.random.Generator) -> FloatArray:
        """f(x) + w, w ~ N(0, Q), batched over ``(..., 4)``."""
        check_rng(rng)
        return add_gaussian_noise(self.propagate(x, dt), self.process_noise(dt), rng)

    def kinematics(self, x: ArrayLike) -> FloatArray:
        """pv = (px, v cos psi, py, v sin psi), ``(..., 4)``."""
        return _FULL.kinematics(self._with_omega(x))

    def kinematics_jacobian(self, x: ArrayLike) -> FloatArray:
        """d pv / d x, ``(..., 4, 4)``."""
        return _FULL.kinematics_jacobian(self._with_omega(x))[..., _KNOWN]
