"""Nearly-constant-velocity (NCV) motion in 2-D, state pv = (x, xdot, y, ydot).

Two noise conventions, both with the transition of Ramdaras eq. 4:

    F = blkdiag(F1, F1),  F1 = [[1, T], [0, 1]]

* ``NearlyConstantVelocity(q)``: continuous white-noise acceleration with power spectral
  density q (Hernandez sec. 5.1, where it is called l), which integrates to
  Q = q * blkdiag(Q1, Q1),  Q1 = [[T^3/3, T^2/2], [T^2/2, T]].
* ``NearlyConstantVelocityDiscrete(sigma_x, sigma_y)``: the discrete white-noise form of
  Ramdaras eq. 3-4, x_{k+1} = F x_k + G u with u ~ N(0, I_2), so Q = G G^T with
  G = [[T^2/2 sigma_x, 0], [T sigma_x, 0], [0, T^2/2 sigma_y], [0, T sigma_y]].
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_nonnegative
from activetrack.kernels import particle_kernels
from activetrack.models._common import (
    check_dt,
    check_rng,
    check_state,
    noise_factor,
)

PV_NAMES = ("x", "xdot", "y", "ydot")


def cv_transition(dt: float) -> FloatArray:
    """Ramdaras eq. 4 F for pv states, shape (4, 4)."""
    F = np.eye(4)
    F[0, 1] = F[2, 3] = dt
    return F


def rows_times(X: FloatArray, A: FloatArray) -> FloatArray:
    """X A^T for rows X ``(N, 4)`` and A ``(4, 4)``, summed over k = 0..3 in that order
    (sum_k X[:, k] A[:, k]): the order the compiled kernel follows, so both give the same bits
    (a BLAS matmul may sum in another order or fuse multiply-adds)."""
    out = X[:, 0, None] * A[:, 0]
    for k in range(1, 4):
        out += X[:, k, None] * A[:, k]
    return out


# Entries (row, column) of F and of L that can be non-zero for two independent
# constant-velocity axes (x, xdot) and (y, ydot): F upper, L lower triangular in each block.
_CV_F_ENTRIES = ((0, 0), (0, 1), (1, 1), (2, 2), (2, 3), (3, 3))
_CV_L_ENTRIES = ((0, 0), (1, 0), (1, 1), (2, 2), (3, 2), (3, 3))


def cv_rows(X: FloatArray, W: FloatArray, F: FloatArray, L: FloatArray) -> FloatArray:
    """``rows_times(X, F) + rows_times(W, L)`` for F and L with the zeros of
    :func:`has_cv_zeros`, from the non-zero terms only: x F^T has x0 f00 + x1 f01, x1 f11,
    x2 f22 + x3 f23, x3 f33 and w L^T has w0 l00, w0 l10 + w1 l11, w2 l22, w2 l32 + w3 l33.
    The operations of the compiled ``gaussian_sample`` (a + b = b + a exactly)."""
    mean = X * np.diagonal(F)
    mean[:, 0] += X[:, 1] * F[0, 1]
    mean[:, 2] += X[:, 3] * F[2, 3]
    noise = W * np.diagonal(L)
    noise[:, 1] += W[:, 0] * L[1, 0]
    noise[:, 3] += W[:, 2] * L[3, 2]
    mean += noise
    return mean


def has_cv_zeros(F: FloatArray, L: FloatArray) -> bool:
    """True when F and L are zero outside the entries of two independent constant-velocity
    axes (then the compiled ``gaussian_sample`` applies: it sums the non-zero terms only)."""
    for A, keep in ((F, _CV_F_ENTRIES), (L, _CV_L_ENTRIES)):
        mask = np.ones((4, 4), dtype=bool)
        mask[tuple(zip(*keep, strict=True))] = False
        if A.shape != (4, 4) or np.any(A[mask] != 0.0):
            return False
    return True


@lru_cache(maxsize=64)
def _sample_factors(model: _LinearPV, dt: float) -> tuple[FloatArray, FloatArray, bool]:
    """F, L (L L^T = Q) and :func:`has_cv_zeros` of a model and a time step, read-only and
    kept for the next step (a filter samples with one dt every step; the models are frozen,
    so hashable)."""
    return _read_only_factors(model, dt)


def _read_only_factors(model: _LinearPV, dt: float) -> tuple[FloatArray, FloatArray, bool]:
    F = model.transition_matrix(dt)
    L = noise_factor(model.process_noise(dt))
    F.flags.writeable = False
    L.flags.writeable = False
    return F, L, has_cv_zeros(F, L)


class _LinearPV(ABC):
    """Members shared by the linear models whose state is pv itself (``state_is_pv``)."""

    dim: ClassVar[int] = 4
    state_names: ClassVar[tuple[str, ...]] = PV_NAMES
    is_linear: ClassVar[bool] = True
    state_is_pv: ClassVar[bool] = True

    def transition_matrix(self, dt: float) -> FloatArray:
        """The constant F, (4, 4): Ramdaras eq. 4 unless the model turns."""
        return cv_transition(check_dt(dt))

    @abstractmethod
    def process_noise(self, dt: float, x: ArrayLike | None = None) -> FloatArray:
        """Q, (4, 4)."""

    def propagate(self, x: ArrayLike, dt: float) -> FloatArray:
        """Noise-free f(x) = F x, ``(..., 4) -> (..., 4)``."""
        x = check_state("x", x, 4)
        return x @ self.transition_matrix(dt).T

    def jacobian(self, x: ArrayLike, dt: float) -> FloatArray:
        """df/dx = F broadcast to ``(..., 4, 4)``."""
        x = check_state("x", x, 4)
        return np.broadcast_to(self.transition_matrix(dt), (*x.shape[:-1], 4, 4)).copy()

    def sample(self, x: ArrayLike, dt: float, rng: np.random.Generator) -> FloatArray:
        """f(x) + w, w ~ N(0, Q), independently for each state of the batch ``(..., 4)``.

        A particle array ``(N, 4)`` is x F^T + W L^T (L L^T = Q, W standard normal) by
        :func:`rows_times`, or from the non-zero terms only (:func:`cv_rows`) for two CV axes,
        compiled when enabled: the same normals and operations, the same bits.
        """
        check_rng(rng)
        if not (type(dt) is float and 0.0 <= dt < math.inf):  # a filter's dt: no more checks
            dt = check_dt(dt)
        try:
            F, L, cv = _sample_factors(self, dt)
        except TypeError:  # an unhashable subclass: no cache
            F, L, cv = _read_only_factors(self, dt)
        if not (type(x) is np.ndarray and x.ndim == 2 and x.shape[1] == 4):
            # propagate() and add_gaussian_noise() with the cached F and L (the same numbers)
            mean = check_state("x", x, 4) @ F.T
            return mean + rng.standard_normal(mean.shape) @ L.T
        kernels = particle_kernels()
        if kernels is None:
            X = check_state("x", x, 4)
            W = rng.standard_normal(X.shape)
            return cv_rows(X, W, F, L) if cv else rows_times(X, F) + rows_times(W, L)
        X = np.ascontiguousarray(x, dtype=float)
        # The NCV models' F and L: the zero terms left out (the same numbers, has_cv_zeros).
        out, finite = kernels.gaussian_sample(X, F, L, cv, rng)
        if not finite:
            check_state("x", X, 4)  # raises for a non-finite x, as the numpy path does
        return out

    def kinematics(self, x: ArrayLike) -> FloatArray:
        """The state is already pv: returns a copy, ``(..., 4)``."""
        return np.array(check_state("x", x, 4), dtype=float)

    def kinematics_jacobian(self, x: ArrayLike) -> FloatArray:
        """d pv / dx = I, ``(..., 4, 4)``."""
        x = check_state("x", x, 4)
        return np.broadcast_to(np.eye(4), (*x.shape[:-1], 4, 4)).copy()


@dataclass(frozen=True)
class NearlyConstantVelocity(_LinearPV):
    """NCV with continuous white-noise acceleration of PSD ``q`` (m^2/s^3) on each axis.

    Hernandez sec. 5.1 (there q = l = 1e-8).  ``q = 0`` gives deterministic constant velocity.
    """

    q: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "q", require_nonnegative("q", self.q))

    def process_noise(self, dt: float, x: ArrayLike | None = None) -> FloatArray:
        """Q = q * blkdiag(Q1, Q1), Q1 = [[T^3/3, T^2/2], [T^2/2, T]], shape (4, 4)."""
        T = check_dt(dt)
        Q1 = self.q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
        Q = np.zeros((4, 4))
        Q[:2, :2] = Q[2:, 2:] = Q1
        return Q


@dataclass(frozen=True)
class NearlyConstantVelocityDiscrete(_LinearPV):
    """NCV with the discrete noise gain of Ramdaras eq. 3-4 (sigma in m/s^2 per axis)."""

    sigma_x: float
    sigma_y: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "sigma_x", require_nonnegative("sigma_x", self.sigma_x))
        object.__setattr__(self, "sigma_y", require_nonnegative("sigma_y", self.sigma_y))

    def noise_gain(self, dt: float) -> FloatArray:
        """G of Ramdaras eq. 4, (4, 2): the noise enters as G u with u ~ N(0, I_2)."""
        T = check_dt(dt)
        G = np.zeros((4, 2))
        G[0, 0], G[1, 0] = 0.5 * T**2 * self.sigma_x, T * self.sigma_x
        G[2, 1], G[3, 1] = 0.5 * T**2 * self.sigma_y, T * self.sigma_y
        return G

    def process_noise(self, dt: float, x: ArrayLike | None = None) -> FloatArray:
        """Q = G G^T (Ramdaras eq. 3-4), shape (4, 4)."""
        G = self.noise_gain(dt)
        return G @ G.T
