"""Observability rank test along a trajectory (Valverde sec. IV-C, eq. 38).

The linearised system x_{k+1} = F_k x_k, z_k = H_k x_k is observable over epochs k0..kf-1 when
the observability matrix

    O(k0, kf) = [H_k0; H_{k0+1} Phi(k0+1, k0); ...; H_{kf-1} Phi(kf-1, k0)]        (eq. 38)

has rank n, with Phi(k, k0) = F_{k-1} ... F_{k0} the product of the model Jacobians along the
noise-free trajectory and H_k = state_jacobian(sensor, model, x_k, s_k).

Rank tolerance: a singular value counts when it exceeds ``rtol`` times the largest one
(default 1e-9).  The singular values depend on the units of the state entries, so ``rtol`` is
the knob for "numerically unobservable": Valverde's Table I-II "dt -> 0" rows are this case,
where O tends to stacked copies of H_k0 and all but rank(H) singular values vanish.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_in_range
from activetrack.models._common import check_dt, check_state
from activetrack.models.base import MotionModel, SensorModel
from activetrack.models.sensors import state_jacobian

__all__ = ["ObservabilityResult", "observability_matrix", "observability_rank"]


@dataclass(frozen=True)
class ObservabilityResult:
    """rank of O, its singular values (descending), the absolute tolerance used, O itself
    ``(K * dim_z, n)`` and the noise-free trajectory ``(K, n)``."""

    rank: int
    singular_values: FloatArray
    tol: float
    matrix: FloatArray
    trajectory: FloatArray

    @property
    def observable(self) -> bool:
        return self.rank == self.matrix.shape[1]


def _sensor_track(sensor_pv: ArrayLike, n_steps: int | None) -> FloatArray:
    s = check_state("sensor_pv", sensor_pv, 4)
    if s.ndim == 1:
        if n_steps is None:
            raise ValueError("n_steps is required (>= 1) when sensor_pv is a single (4,) state")
        K = int(require_in_range("n_steps", n_steps, 1, np.inf))
        return np.broadcast_to(s, (K, 4))
    if s.ndim != 2 or s.shape[0] < 1:
        raise ValueError(f"sensor_pv must have shape (4,) or (K >= 1, 4), got {s.shape}")
    if n_steps is not None and n_steps != s.shape[0]:
        raise ValueError(f"n_steps must equal len(sensor_pv) = {s.shape[0]}, got {n_steps}")
    return s


def observability_matrix(
    model: MotionModel,
    sensor: SensorModel,
    x0: ArrayLike,
    sensor_pv: ArrayLike,
    dt: float,
    n_steps: int | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Build eq. 38 along the noise-free trajectory from ``x0`` ``(n,)``.

    ``sensor_pv`` is the sensor pv at each epoch ``(K, 4)``, or one stationary ``(4,)`` state
    together with ``n_steps`` = K.  Returns ``(O, trajectory)`` with O ``(K * dim_z, n)``.
    """
    x = check_state("x0", x0, model.dim)
    if x.ndim != 1:
        raise ValueError(f"x0 must be one state of shape ({model.dim},), got {x.shape}")
    dt = check_dt(dt)
    sensors = _sensor_track(sensor_pv, n_steps)
    Phi = np.eye(model.dim)  # Phi(k, k0)
    blocks, trajectory = [], []
    for k, s in enumerate(sensors):
        if k > 0:
            Phi = model.jacobian(x, dt) @ Phi
            x = model.propagate(x, dt)
        trajectory.append(x)
        blocks.append(state_jacobian(sensor, model, x, s) @ Phi)
    return np.concatenate(blocks, axis=0), np.array(trajectory)


def observability_rank(
    model: MotionModel,
    sensor: SensorModel,
    x0: ArrayLike,
    sensor_pv: ArrayLike,
    dt: float,
    n_steps: int | None = None,
    rtol: float = 1e-9,
) -> ObservabilityResult:
    """Rank of the eq. 38 observability matrix: singular values above ``rtol * s_max``.

    Arguments as for :func:`observability_matrix`; returns an :class:`ObservabilityResult`.
    """
    rtol = require_in_range("rtol", rtol, 0.0, 1.0, lo_inclusive=False, hi_inclusive=False)
    O, trajectory = observability_matrix(model, sensor, x0, sensor_pv, dt, n_steps)
    sv = np.linalg.svd(O, compute_uv=False)
    tol = rtol * sv[0] if sv.size else 0.0
    rank = int(np.count_nonzero(sv > tol)) if sv.size and sv[0] > 0 else 0
    return ObservabilityResult(rank, sv, float(tol), O, trajectory)
