"""Posterior Cramér-Rao lower bound for linear target dynamics (Hernandez 2004).

Recursion (Hernandez eq. 3)::

    J_{k+1} = (Q + F J_k^{-1} F^T)^{-1} + J_Z(k+1)

with the measurement contribution of eq. 8-9 evaluated by Monte Carlo over the prior target
distribution propagated to each epoch (Hernandez sec. 3.2)::

    J_Z(k) = sum_j E[ pd_j * I_r(X^j_S; X_k) * H_j(X_k)^T R_j^{-1} H_j(X_k) ]

with ``I_r`` the detection-range indicator (``sensor.in_range``, Hernandez sec. 2.3). States are
pv vectors ``(x, xdot, y, ydot)`` (eq. 6-7), batched over leading dimensions so that one call
scores many candidate sensor positions (the planner's inner loop).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite
from activetrack.kernels import kernels_enabled
from activetrack.linalg import cholesky as _cholesky
from activetrack.linalg import lower_solve as _lower_solve
from activetrack.linalg import psd_sqrt as _psd_sqrt
from activetrack.linalg import spd_inverse as _spd_inverse
from activetrack.models.base import InformationKernel, SensorModel, jacobian_information

__all__ = [
    "check_sensor_paths",
    "covariance_bound",
    "gaussian_samples",
    "information_function",
    "information_kernel",
    "measurement_information",
    "pcrlb_step",
    "pcrlb_trajectory",
    "propagate_samples",
    "propagate_step",
    "sensor_information",
]

_METHODS = ("auto", "numpy", "jacobian")
Sensors = SensorModel | Sequence[SensorModel]


def covariance_bound(J: ArrayLike) -> FloatArray:
    """The PCRLB J^{-1} (Hernandez eq. 1) of Fisher information matrices ``(..., n, n)``."""
    return _spd_inverse("J", np.asarray(J, dtype=float))


def gaussian_samples(
    mean: ArrayLike, cov: ArrayLike, n_samples: int, rng: np.random.Generator
) -> FloatArray:
    """Draw ``n_samples`` states from N(mean, cov): ``(n_samples, n)`` (Hernandez sec. 3.2)."""
    mean = require_finite("mean", mean)
    if int(n_samples) < 1:
        raise ValueError(f"n_samples must be >= 1 (got {n_samples})")
    cov = np.asarray(cov, dtype=float)
    if mean.ndim != 1 or cov.shape != (mean.size, mean.size):
        raise ValueError(f"cov must be ({mean.size}, {mean.size}) for mean {mean.shape}")
    S = _psd_sqrt("cov", cov)
    return mean + rng.standard_normal((int(n_samples), mean.shape[-1])) @ S.T


def _as_sensor_batch(
    sensors: Sensors, sensor_states: ArrayLike, name: str
) -> tuple[tuple[SensorModel, ...], FloatArray]:
    """Normalise (sensor or sequence, states) to (tuple of S sensors, states (..., S, 4))."""
    states = np.asarray(sensor_states, dtype=float)
    if isinstance(sensors, Sequence):
        batch = tuple(sensors)
    else:  # one sensor: states carry no sensor axis
        batch = (sensors,)
        states = states[..., None, :]
    if len(batch) == 0:
        raise ValueError("sensors must hold at least one sensor")
    if states.ndim < 2 or states.shape[-1] != 4 or states.shape[-2] != len(batch):
        raise ValueError(
            f"{name} must have shape (..., S, 4) with S = {len(batch)} sensors "
            f"(or (..., 4) for a single sensor); got {states.shape}"
        )
    if not np.isfinite(states).all():
        raise ValueError(f"{name} must be finite (sensor positions/velocities)")
    return batch, states


def check_sensor_paths(sensors: Sensors, sensor_paths: ArrayLike, n_steps: int) -> FloatArray:
    """Sensor pv states at epochs 1..n_steps ``(n_steps, ..., S, 4)`` as a float array, checked
    (``(n_steps, ..., 4)`` for one sensor)."""
    paths = np.asarray(sensor_paths, dtype=float)
    if paths.ndim < 2 or paths.shape[0] != int(n_steps):
        raise ValueError(
            f"sensor_paths must have shape (n_steps={n_steps}, ..., S, 4); got {paths.shape}"
        )
    _as_sensor_batch(sensors, paths[0], "sensor_paths")
    if not np.isfinite(paths).all():
        raise ValueError("sensor_paths must be finite (sensor positions/velocities)")
    return paths


def _check_samples(target_samples: ArrayLike, ndim: int = 2) -> FloatArray:
    X = np.asarray(target_samples, dtype=float)
    if X.ndim != ndim or X.shape[-1] != 4 or X.shape[-2] < 1:
        raise ValueError(
            "target_samples must have shape "
            + ("(M, 4)" if ndim == 2 else "(K, M, 4)")
            + f" with M >= 1 pv samples; got {X.shape}"
        )
    require_finite("target_samples", X)
    return X


def measurement_information(
    sensors: Sensors,
    sensor_states: ArrayLike,
    target_samples: ArrayLike,
    *,
    kinematics_jacobian: ArrayLike | None = None,
    method: str = "auto",
) -> FloatArray:
    """Monte Carlo J_Z = sum_j (1/M) sum_m pd_j I_r H_j^T R_j^{-1} H_j (Hernandez eq. 8-9), each
    sensor's term its own ``fisher_information``, batched over candidates.

    Args:
        sensors: one sensor, or a sequence of S sensors.
        sensor_states: pv states ``(..., S, 4)`` (``(..., 4)`` when ``sensors`` is one sensor);
            the leading ``...`` are candidate positions scored in one call.
        target_samples: pv samples ``(M, 4)`` of the prior target distribution at this epoch.
        kinematics_jacobian: optional d pv / d x ``(M, 4, n)`` at the samples; the information is
            then with respect to that model state (n x n) instead of pv.
        method: ``"auto"`` (a compiled ``information_kernel`` where the sensor has one and
            no ``kinematics_jacobian``), ``"numpy"`` (``fisher_information``, the kernels'
            reference) or ``"jacobian"`` (``models.base.jacobian_information`` for every
            sensor, a check on closed forms).

    Returns:
        J_Z ``(..., n, n)``, symmetric positive semi-definite (n = 4 in pv).
    """
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS} (got {method!r})")
    batch, states = _as_sensor_batch(sensors, sensor_states, "sensor_states")
    X = _check_samples(target_samples)
    K = None
    if kinematics_jacobian is not None:
        K = np.asarray(kinematics_jacobian, dtype=float)
        if K.ndim != 3 or K.shape[:2] != (X.shape[0], 4):
            raise ValueError(
                f"kinematics_jacobian must have shape (M, 4, n) with M = {X.shape[0]}; "
                f"got {K.shape}"
            )
        require_finite("kinematics_jacobian", K)
    n = 4 if K is None else K.shape[-1]
    J_Z = np.zeros((*states.shape[:-2], n, n))
    for j, sensor in enumerate(batch):  # a handful of sensors; candidates/samples vectorised
        J_Z = J_Z + sensor_information(sensor, X, states[..., j, :], K, method)
    return J_Z


def information_kernel(sensor: SensorModel) -> InformationKernel | None:
    """The sensor's compiled Fisher information (its optional ``information_kernel()``), or
    None without one or while the kernels are off (``activetrack.kernels.kernels_enabled``)."""
    get = getattr(sensor, "information_kernel", None)
    if get is None or not kernels_enabled():
        return None
    return get()


def information_function(sensor: SensorModel) -> InformationKernel:
    """The sensor's J_Z of flat pv batches ``(samples (M, 4), states (N, 4)) -> (N, 4, 4)``:
    its compiled kernel where it has one (:func:`information_kernel`), else its numpy
    ``fisher_information``. Resolve it once where the same sensor is scored many times (the
    planner's searches); inputs are taken as checked."""
    kernel = information_kernel(sensor)
    return sensor.fisher_information if kernel is None else kernel


def sensor_information(
    sensor: SensorModel,
    target_samples: FloatArray,
    sensor_states: FloatArray,
    kinematics_jacobian: FloatArray | None = None,
    method: str = "auto",
) -> FloatArray:
    """One sensor's J_Z (Hernandez eq. 8-9) at pv states ``(..., 4)`` over samples ``(M, 4)``:
    ``(..., n, n)``. Inputs are taken as checked (see :func:`measurement_information`, which
    checks them and explains ``method``)."""
    if method == "jacobian":
        return jacobian_information(sensor, target_samples, sensor_states, kinematics_jacobian)
    if method == "auto" and kinematics_jacobian is None:
        kernel = information_kernel(sensor)
        if kernel is not None:
            flat = sensor_states.reshape(-1, 4)
            return kernel(target_samples, flat).reshape(*sensor_states.shape[:-1], 4, 4)
    return sensor.fisher_information(target_samples, sensor_states, kinematics_jacobian)


def pcrlb_step(J_prev: ArrayLike, F: ArrayLike, Q: ArrayLike, J_Z: ArrayLike) -> FloatArray:
    """One step of Hernandez eq. 3: J_{k+1} = (Q + F J_k^{-1} F^T)^{-1} + J_Z(k+1), with
    ``J_prev`` ``(..., n, n)``, ``F`` and ``Q`` ``(n, n)``, ``J_Z`` ``(..., n, n)`` broadcast."""
    J_prev = np.asarray(J_prev, dtype=float)
    F, Q = check_dynamics(F, Q, J_prev.shape[-1])
    J_Z = np.asarray(J_Z, dtype=float)
    if not np.isfinite(J_Z).all():
        raise ValueError("J_Z must be finite")
    return predicted_information(J_prev, F, Q) + J_Z


def check_dynamics(F: ArrayLike, Q: ArrayLike, n: int) -> tuple[FloatArray, FloatArray]:
    """F and Q of eq. 2 as float arrays, checked: ``(n, n)``, finite, Q symmetric."""
    F = np.asarray(F, dtype=float)
    Q = np.asarray(Q, dtype=float)
    if F.shape != (n, n) or Q.shape != (n, n):
        raise ValueError(f"F and Q must be ({n}, {n}); got F {F.shape}, Q {Q.shape}")
    if not (np.isfinite(F).all() and np.isfinite(Q).all()):
        raise ValueError("F and Q must be finite")
    if not (Q == Q.T).all() and np.max(np.abs(Q - Q.T)) > 1e-9 * np.max(np.abs(Q)):
        raise ValueError("Q must be symmetric positive semi-definite")
    return F, Q


def predicted_information(J_prev: FloatArray, F: FloatArray, Q: FloatArray) -> FloatArray:
    """The prediction part of eq. 3, (Q + F J_k^{-1} F^T)^{-1}, for ``J_prev`` ``(..., n, n)``
    (checked SPD; F, Q ``(n, n)`` taken as valid). A stack ``(N, n, n)`` runs compiled while
    kernels are enabled (equal to 1e-12).
    """
    if J_prev.ndim == 3 and kernels_enabled():
        return _predicted_stack(J_prev, F, Q)
    L = _cholesky("J_prev", J_prev)  # no explicit inverse of J_k: F J_k^{-1} F^T = X^T X
    Xt = _lower_solve(L, F.T)  # (..., n, n) = L^{-1} F^T
    C = Q + np.swapaxes(Xt, -1, -2) @ Xt  # predicted-state bound Q + F J^{-1} F^T
    # C and its inverse L^{-T} L^{-1} are symmetric by construction.
    return _spd_inverse("Q + F J_prev^-1 F^T", C, check_symmetry=False)


def _predicted_stack(J_prev: FloatArray, F: FloatArray, Q: FloatArray) -> FloatArray:
    """:func:`predicted_information` of a stack ``(N, n, n)``, compiled; the checks and messages
    of the numpy form."""
    from activetrack.bounds._kernels import predicted_stack

    J_prev = np.ascontiguousarray(J_prev, dtype=float)
    _check_symmetric("J_prev", J_prev)
    P, status = predicted_stack(J_prev, np.ascontiguousarray(F), np.ascontiguousarray(Q))
    if status == 1:
        raise ValueError("J_prev must be symmetric positive definite (all eigenvalues > 0)")
    if status == 2:
        raise ValueError(
            "Q + F J_prev^-1 F^T must be symmetric positive definite (all eigenvalues > 0)"
        )
    return P


def _check_symmetric(name: str, A: FloatArray) -> None:
    """Finite and symmetric to 1e-9 relative, as ``linalg.cholesky`` checks (ValueError)."""
    if not np.isfinite(A).all():
        raise ValueError(f"{name} must be finite (got NaN or inf entries)")
    At = np.swapaxes(A, -1, -2)
    if not (A == At).all() and np.max(np.abs(A - At)) > 1e-9 * np.max(np.abs(A)):
        raise ValueError(f"{name} must be symmetric positive definite (it is not symmetric)")


def propagate_samples(
    target_samples: ArrayLike,
    F: ArrayLike,
    Q: ArrayLike,
    n_steps: int,
    rng: np.random.Generator | None = None,
) -> FloatArray:
    """Prior target samples at epochs 1..K through X_{k+1} = F X_k + w_k (Hernandez eq. 2).

    ``target_samples`` ``(M, n)`` at epoch 0; returns ``(n_steps, M, n)``. With ``rng=None``
    the samples follow the noise-free dynamics (w_k = 0).
    """
    X = np.asarray(target_samples, dtype=float)
    if X.ndim != 2 or X.shape[0] < 1:
        raise ValueError(f"target_samples must have shape (M, n) with M >= 1; got {X.shape}")
    require_finite("target_samples", X)
    if int(n_steps) < 1:
        raise ValueError(f"n_steps must be >= 1 (got {n_steps})")
    F = require_finite("F", F)
    S = _psd_sqrt("Q", np.asarray(Q, dtype=float)) if rng is not None else None
    out = np.empty((int(n_steps), *X.shape))
    for k in range(int(n_steps)):
        X = X @ F.T if rng is None or S is None else propagate_step(X, F, S, rng)
        out[k] = X
    return out


def propagate_step(
    X: FloatArray, F: FloatArray, S: FloatArray, rng: np.random.Generator
) -> FloatArray:
    """One step of :func:`propagate_samples` (eq. 2, w_k = S times standard normals) for
    samples ``X`` ``(M, n)`` checked finite, F checked, and ``S = psd_sqrt(Q)``: for a caller
    that steps epoch by epoch and takes the root once (the root of a singular Q, an eigh after
    a failed Cholesky, was a third of such a step)."""
    return X @ F.T + rng.standard_normal(X.shape) @ S.T


def pcrlb_trajectory(
    J0: ArrayLike,
    F: ArrayLike,
    Q: ArrayLike,
    target_samples: ArrayLike,
    sensors: Sensors,
    sensor_paths: ArrayLike,
    rng: np.random.Generator | None = None,
    *,
    method: str = "auto",
    active: ArrayLike | None = None,
) -> FloatArray:
    """Fisher information J_k, k = 1..K, along sensor paths (Hernandez eq. 3-4 and 8-9).

    Args:
        J0: initial information ``(4, 4)`` (eq. 4: J_0 = C_0^{-1} for a Gaussian prior).
        F, Q: linear target dynamics (eq. 2), ``(4, 4)``.
        target_samples: prior samples ``(M, 4)`` at k = 0, propagated with ``rng`` (None:
            noise-free; Hernandez sec. 3.2), or propagated ones ``(K, M, 4)`` for epochs 1..K.
        sensor_paths: sensor pv states at epochs 1..K, ``(K, ..., S, 4)``
            (``(K, ..., 4)`` for a single sensor); ``...`` are candidate paths.
        active: optional ``(K, S)`` bool, the sensors that measure at each epoch (None: all).

    Returns:
        J ``(K, ..., 4, 4)``; the bound on the error covariance is ``covariance_bound(J)``.
    """
    J0 = np.asarray(J0, dtype=float)
    _cholesky("J0", J0)
    paths = np.asarray(sensor_paths, dtype=float)
    if paths.ndim < 2:
        raise ValueError(f"sensor_paths must have shape (K, ..., S, 4); got {paths.shape}")
    if not np.isfinite(paths).all():
        raise ValueError("sensor_paths must be finite (sensor positions/velocities)")
    n_steps = paths.shape[0]
    X = np.asarray(target_samples, dtype=float)
    if X.ndim == 3:
        samples = _check_samples(X, ndim=3)
        if samples.shape[0] != n_steps:
            raise ValueError(
                f"target_samples (K, M, 4) must have K = {n_steps} epochs like sensor_paths; "
                f"got {samples.shape[0]}"
            )
    else:
        samples = propagate_samples(_check_samples(X), F, Q, n_steps, rng)
    J = J0
    out = []
    on = None
    if active is not None:
        if not isinstance(sensors, (list, tuple)):
            raise ValueError("active needs sensors as a sequence of S sensors")
        on = np.asarray(active, dtype=bool)
        if on.shape != (n_steps, len(sensors)):
            raise ValueError(f"active must be (K, S) = ({n_steps}, {len(sensors)}), got {on.shape}")
    for k in range(n_steps):
        if on is None or on[k].all():
            J_Z = measurement_information(sensors, paths[k], samples[k], method=method)
        elif on[k].any():
            idx = np.flatnonzero(on[k])
            chosen = [cast(Sequence[SensorModel], sensors)[int(j)] for j in idx]
            J_Z = measurement_information(chosen, paths[k][..., idx, :], samples[k], method=method)
        else:
            J_Z = np.zeros_like(J)
        J = pcrlb_step(J, F, Q, J_Z)
        out.append(J)
    return np.stack(out)
