"""Modified Riccati equation with detection probability (Ramdaras et al. 2010, eq. 23)::

    P_{k+1|k} = F P_{k|k-1} F^T
                - pd F P_{k|k-1} H_k^T (H_k P_{k|k-1} H_k^T + R)^{-1} H_k P_{k|k-1} F^T + Q

H_k (eq. 13) at x_{k|k-1} and the (candidate) sensor position. Computed as the pd-weighted mix
F [(1 - pd) P_{k|k-1} + pd P_{k|k}] F^T + Q with P_{k|k} in Joseph form (eq. 22), which keeps
it SPD. Batched over candidate positions (leading ``...``).
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.bounds.pcrlb import Sensors, _as_sensor_batch, _cholesky
from activetrack.checks import require_finite, symmetrize

__all__ = [
    "joseph_update",
    "mre_mix",
    "mre_predict",
    "mre_recursion",
    "mre_step",
    "mre_update",
]


def mre_update(P: ArrayLike, H: ArrayLike, R: ArrayLike, pd: ArrayLike = 1.0) -> np.ndarray:
    """Expected covariance after one possible detection: (1 - pd) P + pd P_{k|k}.

    ``P`` ``(..., n, n)`` predicted covariance, ``H`` ``(..., m, n)``, ``R`` ``(m, m)``,
    ``pd`` scalar or ``(...)`` in [0, 1]. P_{k|k} is the Joseph form of Ramdaras eq. 20-22.
    """
    P = np.asarray(P, dtype=float)
    pd = _check_pd(pd)
    return _mix(P, joseph_update(P, H, R), pd)


def joseph_update(P: ArrayLike, H: ArrayLike, R: ArrayLike) -> np.ndarray:
    """P_{k|k} of a sure detection, Joseph form (Ramdaras eq. 20-22), ``(..., n, n)``: the
    part of :func:`mre_update` that does not depend on pd (a planner scoring one look with
    several detection factors computes it once)."""
    P = np.asarray(P, dtype=float)
    H = np.asarray(H, dtype=float)
    R = np.atleast_2d(np.asarray(R, dtype=float))
    if H.shape[-2:] != (R.shape[0], P.shape[-1]):
        raise ValueError(
            f"H must have shape (..., m, n) = (..., {R.shape[0]}, {P.shape[-1]}); got {H.shape}"
        )
    if not np.isfinite(H).all():
        raise ValueError("H must be finite")
    Ht = np.swapaxes(H, -1, -2)
    S = H @ P @ Ht + R  # innovation covariance, Ramdaras eq. 17
    _cholesky("S = H P H^T + R", S)
    K = np.swapaxes(np.linalg.solve(S, H @ P), -1, -2)  # gain P H^T S^{-1}, eq. 20
    I_KH = np.eye(P.shape[-1]) - K @ H
    return I_KH @ P @ np.swapaxes(I_KH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)  # eq. 22


def mre_mix(P: ArrayLike, P_upd: ArrayLike, pd: ArrayLike = 1.0) -> np.ndarray:
    """(1 - pd) P + pd P_upd, symmetrized: :func:`mre_update` from its :func:`joseph_update`
    ``P_upd``."""
    return _mix(np.asarray(P, dtype=float), P_upd, _check_pd(pd))


def _mix(P: np.ndarray, P_upd: ArrayLike, pd: np.ndarray) -> np.ndarray:
    pd = pd[..., None, None]
    return symmetrize((1.0 - pd) * P + pd * P_upd)


def _check_pd(pd: ArrayLike) -> np.ndarray:
    pd = np.asarray(pd, dtype=float)
    if not (np.isfinite(pd).all() and np.all((pd >= 0.0) & (pd <= 1.0))):
        raise ValueError(f"pd must lie in [0, 1] (got {pd})")
    return pd


def mre_step(
    P: ArrayLike, F: ArrayLike, Q: ArrayLike, H: ArrayLike, R: ArrayLike, pd: ArrayLike = 1.0
) -> np.ndarray:
    """Ramdaras eq. 23: P_{k+1|k} from P_{k|k-1} ``(..., n, n)``, batched over ``H`` and pd."""
    P = np.asarray(P, dtype=float)
    _cholesky("P", P)
    F, Q = require_finite("F", F), require_finite("Q", Q)
    return symmetrize(F @ mre_update(P, H, R, pd) @ F.T + Q)


def _sensor_update(
    P: np.ndarray,
    sensors: Sensors,
    sensor_states: ArrayLike,
    x_pred: np.ndarray,
    kinematics_jacobian: np.ndarray | None,
) -> np.ndarray:
    """Apply mre_update for each sensor in turn (sequential updates; exact for pd = 1)."""
    sensors, states = _as_sensor_batch(sensors, sensor_states, "sensor_states")
    for j, sensor in enumerate(sensors):
        s = states[..., j, :]
        H = np.asarray(sensor.jacobian(x_pred, s), dtype=float)  # Ramdaras eq. 13
        if kinematics_jacobian is not None:
            H = H @ kinematics_jacobian
        # Inside the minimum range (I_r = 0, Hernandez eq. 8) there is no detection.
        pd = float(getattr(sensor, "pd", 1.0)) * np.asarray(sensor.in_range(x_pred, s), float)
        P = mre_update(P, H, sensor.R, pd)
    return P


def mre_predict(
    P_pred: ArrayLike,
    F: ArrayLike,
    Q: ArrayLike,
    sensors: Sensors,
    x_pred: ArrayLike,
    sensor_states: ArrayLike,
    *,
    kinematics_jacobian: np.ndarray | None = None,
) -> np.ndarray:
    """Ramdaras eq. 23 for sensor(s) at candidate positions: P_{k+1|k} ``(..., n, n)``.

    Args:
        P_pred: P_{k|k-1} ``(n, n)`` or ``(..., n, n)``.
        F, Q: linear(ised) dynamics ``(n, n)``.
        sensors: one sensor (``sensor_states`` ``(..., 4)``) or a sequence of S sensors
            (``(..., S, 4)``), each with its own pd; several sensors are applied sequentially.
        x_pred: predicted target pv x_{k|k-1} ``(4,)`` where H is evaluated.
        kinematics_jacobian: d pv / d x ``(4, n)`` when the state is not pv.
    """
    P_pred = np.asarray(P_pred, dtype=float)
    _cholesky("P_pred", P_pred)
    x_pred = require_finite("x_pred", x_pred)
    F, Q = require_finite("F", F), require_finite("Q", Q)
    P = _sensor_update(P_pred, sensors, sensor_states, x_pred, kinematics_jacobian)
    return symmetrize(F @ P @ F.T + Q)


def mre_recursion(
    P_pred0: ArrayLike,
    F: ArrayLike,
    Q: ArrayLike,
    sensors: Sensors,
    x_pred0: ArrayLike,
    sensor_paths: ArrayLike,
) -> np.ndarray:
    """Iterate eq. 23 along sensor paths ``(K, ..., S, 4)`` for pv states and linear F.

    P_{0|-1} = ``P_pred0``, x_{0|-1} = ``x_pred0``; the expected predicted mean follows
    x_{k+1|k} = F x_{k|k-1} (zero-mean innovations). Returns P_{k+1|k}, k = 0..K-1,
    ``(K, ..., 4, 4)``.
    """
    paths = np.asarray(sensor_paths, dtype=float)
    if paths.ndim < 2:
        raise ValueError(f"sensor_paths must have shape (K, ..., S, 4); got {paths.shape}")
    F = np.asarray(F, dtype=float)
    P = np.asarray(P_pred0, dtype=float)
    x = np.asarray(x_pred0, dtype=float)
    out = []
    for k in range(paths.shape[0]):
        P = mre_predict(P, F, Q, sensors, x, paths[k])
        x = F @ x
        out.append(P)
    return np.stack(out)
