"""CRLB by Taylor's method along a deterministic nominal path (Valverde eq. 44-51).

Without process noise the state is a function of x_0 and (eq. 50-51, Phi_k = df/dx at x_{k-1}
on the nominal path, H_k the measurement Jacobian at x_k, eq. 47)::

    J_k = [Phi_k J_{k-1}^{-1} Phi_k^T]^{-1} + H_k^T R^{-1} H_k
        = Phi_k^{-T} J_{k-1} Phi_k^{-1} + H_k^T R^{-1} H_k

computed in the second form (two solves), so J_{k-1} may be singular (no prior).
``process_noise=True`` includes Q as in eq. 65 (the approximate PCRB along the path). pd and
I_r enter as in Hernandez eq. 8, at the nominal state.
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.bounds.pcrlb import (
    Sensors,
    check_sensor_paths,
    measurement_information,
    pcrlb_step,
)
from activetrack.checks import require_finite, symmetrize
from activetrack.linalg import spd_inverse
from activetrack.models.base import MotionModel

__all__ = ["nominal_path", "taylor_crlb", "taylor_information_initial"]


def nominal_path(model: MotionModel, x0: ArrayLike, n_steps: int, dt: float) -> FloatArray:
    """Noise-free path x_k = f(x_{k-1}) for k = 0..n_steps: ``(n_steps + 1, n)``."""
    x = require_finite("x0", x0)
    if x.shape != (int(model.dim),):
        raise ValueError(f"x0 must have shape ({model.dim},); got {x.shape}")
    if int(n_steps) < 1:
        raise ValueError(f"n_steps must be >= 1 (got {n_steps})")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 (got {dt})")
    path = [x]
    for _ in range(int(n_steps)):
        x = np.asarray(model.propagate(x, dt), dtype=float)
        path.append(x)
    return np.stack(path)


def _nominal_information(
    model: MotionModel, sensors: Sensors, sensor_state: FloatArray, x: FloatArray
) -> FloatArray:
    """pd * I_r * H^T R^{-1} H at one nominal state x ``(n,)``: ``(..., n, n)`` (eq. 47-48)."""
    return measurement_information(
        sensors,
        sensor_state,
        np.asarray(model.kinematics(x), dtype=float)[None, :],
        kinematics_jacobian=np.asarray(model.kinematics_jacobian(x), dtype=float)[None],
    )


def taylor_crlb(
    model: MotionModel,
    sensors: Sensors,
    sensor_paths: ArrayLike,
    x0: ArrayLike,
    n_steps: int,
    dt: float,
    *,
    P0: ArrayLike | None = None,
    process_noise: bool = False,
) -> FloatArray:
    """Fisher information J_k about x_k, k = 1..n_steps, along the nominal path (eq. 50-51).

    Args:
        sensor_paths: sensor pv states at epochs 1..n_steps, ``(n_steps, ..., S, 4)``.
        x0: nominal initial state ``(n,)``.
        P0: optional prior covariance S_0 ``(n, n)`` (eq. 44); without it J_0 = 0.
        process_noise: include Q as in Valverde eq. 65 (requires ``P0``).

    Returns:
        J ``(n_steps, ..., n, n)``; positive definite once the state is observable.
    """
    path = nominal_path(model, x0, n_steps, dt)
    paths = check_sensor_paths(sensors, sensor_paths, n_steps)
    n = path.shape[-1]
    J: FloatArray
    if P0 is None:
        if process_noise:
            raise ValueError("P0 is required when process_noise=True (eq. 65 needs J_0^{-1})")
        J = np.zeros((n, n))
    else:
        J = spd_inverse("P0", np.asarray(P0, dtype=float))
    Q = np.asarray(model.process_noise(dt), dtype=float) if process_noise else None
    out = []
    for k in range(1, int(n_steps) + 1):
        Phi = np.asarray(model.jacobian(path[k - 1], dt), dtype=float)
        J_Z = _nominal_information(model, sensors, paths[k - 1], path[k])
        if Q is not None:
            J = pcrlb_step(J, Phi, Q, J_Z)  # Valverde eq. 65
        else:
            B = np.linalg.solve(Phi.T, J)  # Phi^{-T} J
            J = symmetrize(np.linalg.solve(Phi.T, np.swapaxes(B, -1, -2)) + J_Z)  # eq. 50
        out.append(J)
    return np.stack(out)


def taylor_information_initial(
    model: MotionModel,
    sensors: Sensors,
    sensor_paths: ArrayLike,
    x0: ArrayLike,
    n_steps: int,
    dt: float,
    *,
    P0: ArrayLike | None = None,
) -> FloatArray:
    """Information about the initial state x_0 after epochs 1..k (Valverde eq. 46-48).

    J_k(x_0) = S_0^{-1} + sum_{i<=k} Phi_{i,0}^T H_i^T R^{-1} H_i Phi_{i,0}, with the state
    transition sensitivity Phi_{i,0} = dx_i/dx_0 = Phi_i ... Phi_1 along the nominal path.
    Returns ``(n_steps, ..., n, n)``.
    """
    path = nominal_path(model, x0, n_steps, dt)
    paths = check_sensor_paths(sensors, sensor_paths, n_steps)
    n = path.shape[-1]
    J = np.zeros((n, n)) if P0 is None else spd_inverse("P0", np.asarray(P0, dtype=float))
    Phi_k0 = np.eye(n)
    out = []
    for k in range(1, int(n_steps) + 1):
        Phi_k0 = np.asarray(model.jacobian(path[k - 1], dt), dtype=float) @ Phi_k0
        J_Z = _nominal_information(model, sensors, paths[k - 1], path[k])
        J = symmetrize(J + Phi_k0.T @ J_Z @ Phi_k0)
        out.append(J)
    return np.stack(out)
