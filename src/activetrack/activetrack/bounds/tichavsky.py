"""General nonlinear PCRLB by the Tichavsky recursion (Valverde eq. 56-65).

For x_{k+1} = f(x_k) + w_k, w_k ~ N(0, Q) and z = h(x) + v, v ~ N(0, R) (Valverde eq. 1)::

    J_{k+1} = D22_k - D21_k (J_k + D11_k)^{-1} D12_k                        (eq. 56)
    D11_k = E[F_k^T Q^{-1} F_k],   F_k = df/dx at the true x_k              (eq. 62)
    D12_k = -E[F_k^T] Q^{-1} = (D21_k)^T                                     (eq. 63)
    D22_k = Q^{-1} + E[sum_j pd_j I_r H_j^T R_j^{-1} H_j] at x_{k+1}         (eq. 64)

The expectations are over the true state trajectories, estimated by Monte Carlo: n_mc
trajectories drawn from x_0 ~ N(x0, P0) and the model's noisy dynamics (``model.sample``).
J_0 = P0^{-1}. The measurement term reuses the Hernandez eq. 8 machinery of ``pcrlb`` with the
chain rule H_state = H_pv @ d pv / d x (contract ``state_jacobian``), with pd and I_r as there.
"""

from __future__ import annotations

from typing import cast

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.bounds.pcrlb import (
    Sensors,
    check_sensor_paths,
    gaussian_samples,
    measurement_information,
)
from activetrack.checks import require_finite, symmetrize
from activetrack.linalg import cholesky, spd_inverse
from activetrack.models.base import MotionModel

__all__ = ["tichavsky_pcrlb", "tichavsky_step"]


def tichavsky_step(J: ArrayLike, D11: FloatArray, D12: FloatArray, D22: FloatArray) -> FloatArray:
    """Valverde eq. 56: J_{k+1} = D22 - D21 (J_k + D11)^{-1} D12, batched ``(..., n, n)``.

    With L L^T = J_k + D11 and Y = L^{-1} D12, the subtracted term is Y^T Y (symmetric).
    """
    L = cholesky("J + D11", np.asarray(J, dtype=float) + D11)
    Y = np.linalg.solve(L, D12)
    return symmetrize(D22 - np.swapaxes(Y, -1, -2) @ Y)


def _check_setup(
    model: MotionModel,
    sensors: Sensors,
    sensor_paths: ArrayLike,
    x0: ArrayLike,
    P0: ArrayLike,
    n_steps: int,
    dt: float,
    q_floor: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Checked ``(x0, J_0 = P0^{-1}, sensor paths)`` of :func:`tichavsky_pcrlb`."""
    x0 = require_finite("x0", x0)
    P0 = np.asarray(P0, dtype=float)
    n = int(model.dim)
    if x0.shape != (n,) or P0.shape != (n, n):
        raise ValueError(f"x0 must be ({n},) and P0 ({n}, {n}); got {x0.shape}, {P0.shape}")
    J0 = spd_inverse("P0", P0)
    if int(n_steps) < 1:
        raise ValueError(f"n_steps must be >= 1 (got {n_steps})")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 (got {dt})")
    if not (np.isfinite(q_floor) and q_floor >= 0):
        raise ValueError(f"q_floor must be finite and >= 0 (got {q_floor})")
    return x0, J0, check_sensor_paths(sensors, sensor_paths, n_steps)


def _noise_information(model: MotionModel, dt: float, q_floor: float) -> FloatArray:
    """Q^{-1} of Valverde eq. 60-64 (with ``q_floor`` added to the diagonal of Q)."""
    n = int(model.dim)
    Q = np.asarray(model.process_noise(dt), dtype=float)
    if Q.shape != (n, n):
        raise ValueError(f"model.process_noise(dt) must be a constant ({n}, {n}) matrix")
    try:
        return spd_inverse("Q", Q + q_floor * np.eye(n))
    except ValueError:
        raise ValueError(
            "q_floor: the model's process noise Q is singular; pass q_floor > 0 "
            "(Valverde eq. 60-64 need Q^{-1})"
        ) from None


def _initial_states(
    x0: FloatArray,
    P0: ArrayLike,
    n_steps: int,
    n_mc: int,
    rng: np.random.Generator | None,
    trajectories: ArrayLike | None,
) -> tuple[FloatArray, FloatArray | None]:
    """The true states at epoch 0 ``(M, n)``, and the checked ``trajectories`` if given."""
    if trajectories is None:
        if int(n_mc) < 1:
            raise ValueError(f"n_mc must be >= 1 (got {n_mc})")
        if rng is None:
            raise ValueError("rng must be a numpy Generator when trajectories is not given")
        return gaussian_samples(x0, P0, int(n_mc), rng), None
    T = np.asarray(trajectories, dtype=float)
    n = x0.shape[0]
    if T.ndim != 3 or T.shape[0] != int(n_steps) + 1:
        raise ValueError(
            f"trajectories must have shape (n_steps + 1 = {int(n_steps) + 1}, M, {n}); "
            f"got {T.shape}"
        )
    require_finite("trajectories", T)
    return T[0], T


def tichavsky_pcrlb(
    model: MotionModel,
    sensors: Sensors,
    sensor_paths: ArrayLike,
    x0: ArrayLike,
    P0: ArrayLike,
    n_steps: int,
    dt: float,
    n_mc: int,
    rng: np.random.Generator | None,
    *,
    q_floor: float = 0.0,
    trajectories: ArrayLike | None = None,
) -> FloatArray:
    """Fisher information J_k, k = 1..n_steps, of a nonlinear model (Valverde eq. 56-64).

    Args:
        model: e.g. ``ConstantTurn`` or ``CircularMotion``; Q must not depend on the state.
        sensor_paths: sensor pv states at epochs 1..n_steps, ``(n_steps, ..., S, 4)``
            (``(n_steps, ..., 4)`` for one sensor); ``...`` are candidate paths.
        x0, P0: Gaussian prior of the model state, ``(n,)`` and ``(n, n)`` SPD; J_0 = P0^{-1}.
        n_steps, dt: number of epochs and the time between them [s].
        n_mc: Monte Carlo trajectories for the expectations (>= 1).
        rng: generator for the trajectories (unused when ``trajectories`` is given).
        q_floor: added to Q's diagonal before inverting it (eq. 60-64); needed > 0 for noise on
            a subset of states (CircularMotion, Valverde eq. 25).
        trajectories: optional true states ``(n_steps + 1, M, n)`` to share between bounds
            (x0 and P0 then only set J_0).

    Returns:
        J ``(n_steps, ..., n, n)``; the bound is ``covariance_bound(J)``.
    """
    x0, J0, paths = _check_setup(model, sensors, sensor_paths, x0, P0, n_steps, dt, q_floor)
    W = _noise_information(model, dt, q_floor)  # Q^{-1} of eq. 60
    X, given = _initial_states(x0, P0, n_steps, n_mc, rng, trajectories)
    J = J0
    out = []
    for k in range(int(n_steps)):
        F = np.asarray(model.jacobian(X, dt), dtype=float)  # (M, n, n) at the true x_k
        FtW = np.swapaxes(F, -1, -2) @ W
        D11 = symmetrize(np.mean(FtW @ F, axis=0))  # eq. 62
        D12 = -np.mean(FtW, axis=0)  # eq. 63
        if given is None:
            X = model.sample(X, dt, cast(np.random.Generator, rng))
        else:
            X = given[k + 1]
        J_Z = measurement_information(
            sensors,
            paths[k],
            model.kinematics(X),
            kinematics_jacobian=model.kinematics_jacobian(X),
        )
        J = tichavsky_step(J, D11, D12, W + J_Z)  # eq. 64 then eq. 56
        out.append(J)
    return np.stack(out)
