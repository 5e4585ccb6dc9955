"""Posterior Cramér-Rao lower bound for linear target dynamics (Hernandez 2004).

Recursion (Hernandez eq. 3)::

    J_{k+1} = (Q + F J_k^{-1} F^T)^{-1} + J_Z(k+1)

with the measurement contribution of eq. 8-9 evaluated by Monte Carlo over the prior target
distribution propagated to each epoch (Hernandez sec. 3.2)::

    J_Z(k) = sum_j E[ pd_j * I_r(X^j_S; X_k) * H_j(X_k)^T R_j^{-1} H_j(X_k) ]

``I_r`` is the detection-range indicator (``sensor.in_range``: zero inside the minimum detection
range r, Hernandez sec. 2.3) and the detection probability ``pd`` multiplies each sensor's
information (information-reduction factor). Everything is batched over leading dimensions so
that one call scores many candidate sensor positions (the planner's inner loop).

States are kinematic pv vectors ``(x, xdot, y, ydot)`` (Hernandez eq. 6-7).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from activetrack.checks import require_finite, symmetrize

__all__ = [
    "covariance_bound",
    "gaussian_samples",
    "measurement_information",
    "pcrlb_step",
    "pcrlb_trajectory",
    "propagate_samples",
]

# Sensor kinds whose information has the closed form of Hernandez eq. 9.
_BEARING_KINDS = frozenset({"bearing", "ambiguous_bearing"})
_METHODS = ("auto", "closed_form", "jacobian")


def _cholesky(name: str, A: np.ndarray, check_symmetry: bool = True) -> np.ndarray:
    """Lower Cholesky factor of SPD matrices ``(..., n, n)``; ValueError naming ``name``.

    A single matrix goes straight to LAPACK (a few microseconds instead of numpy.linalg's
    per-call overhead), which matters in the planner's inner loop.
    """
    if not np.isfinite(A).all():
        raise ValueError(f"{name} must be finite (got NaN or inf entries)")
    At = np.swapaxes(A, -1, -2)
    if check_symmetry and not (A == At).all():
        if np.max(np.abs(A - At)) > 1e-9 * np.max(np.abs(A)):
            raise ValueError(f"{name} must be symmetric positive definite (it is not symmetric)")
    if A.ndim == 2:
        L, info = lapack.dpotrf(A, lower=1, clean=1)
        if info == 0:
            return L
    else:
        try:
            return np.linalg.cholesky(A)
        except np.linalg.LinAlgError:
            pass
    raise ValueError(f"{name} must be symmetric positive definite (all eigenvalues > 0)")


def _lower_solve(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """L^{-1} B for lower-triangular L ``(..., n, n)`` and B ``(n, k)`` or ``(..., n, k)``."""
    if L.ndim == 2 and B.ndim == 2:
        # dtrtri + matmul rather than dtrtrs: OpenBLAS threads the latter, and waking its
        # thread pool costs ~15 us per call on these 4 x 4 systems.
        return lapack.dtrtri(L, lower=1)[0] @ B
    return np.linalg.solve(L, B)


def _spd_inverse(name: str, A: np.ndarray, check_symmetry: bool = True) -> np.ndarray:
    """Inverse of SPD matrices ``(..., n, n)`` through Cholesky: A^{-1} = L^{-T} L^{-1}."""
    L = _cholesky(name, A, check_symmetry)
    if A.ndim == 2:
        # dpotri fills the lower triangle; the strict upper one keeps L's zeros (clean=1).
        lower = lapack.dpotri(L, lower=1)[0]
        inv = lower + lower.T
        inv.flat[:: A.shape[-1] + 1] *= 0.5  # the diagonal was counted twice
        return inv
    Linv = np.linalg.solve(L, np.eye(A.shape[-1]))
    return np.swapaxes(Linv, -1, -2) @ Linv


def covariance_bound(J: np.ndarray) -> np.ndarray:
    """The PCRLB J^{-1} (Hernandez eq. 1) of Fisher information matrices ``(..., n, n)``."""
    return _spd_inverse("J", np.asarray(J, dtype=float))


def _psd_sqrt(name: str, Q: np.ndarray) -> np.ndarray:
    """A square root S with S S^T = Q for a symmetric positive semi-definite Q ``(n, n)``."""
    if not np.isfinite(Q).all():
        raise ValueError(f"{name} must be finite")
    if not np.allclose(Q, Q.T, rtol=1e-9, atol=1e-12 * max(np.max(np.abs(Q)), 1e-300)):
        raise ValueError(f"{name} must be symmetric positive semi-definite")
    try:
        return np.linalg.cholesky(Q)
    except np.linalg.LinAlgError:
        # Singular process noise (e.g. noise on a subset of states): eigen-decomposition.
        lam, V = np.linalg.eigh(Q)
        if lam.min() < -1e-12 * max(lam.max(), 1e-300):
            raise ValueError(f"{name} must be positive semi-definite (eigenvalues >= 0)") from None
        return V * np.sqrt(np.clip(lam, 0.0, None))


def gaussian_samples(
    mean: np.ndarray, cov: np.ndarray, n_samples: int, rng: np.random.Generator
) -> np.ndarray:
    """Draw ``n_samples`` states from N(mean, cov): ``(n_samples, n)`` (Hernandez sec. 3.2)."""
    mean = np.asarray(mean, dtype=float)
    require_finite("mean", mean)
    if int(n_samples) < 1:
        raise ValueError(f"n_samples must be >= 1 (got {n_samples})")
    cov = np.asarray(cov, dtype=float)
    if mean.ndim != 1 or cov.shape != (mean.size, mean.size):
        raise ValueError(f"cov must be ({mean.size}, {mean.size}) for mean {mean.shape}")
    S = _psd_sqrt("cov", cov)
    return mean + rng.standard_normal((int(n_samples), mean.shape[-1])) @ S.T


def _as_sensor_batch(sensors, sensor_states, name: str) -> tuple[tuple, np.ndarray]:
    """Normalise (sensor or sequence, states) to (tuple of S sensors, states (..., S, 4))."""
    states = np.asarray(sensor_states, dtype=float)
    if hasattr(sensors, "kind"):  # one sensor: states carry no sensor axis
        sensors = (sensors,)
        states = states[..., None, :]
    sensors = tuple(sensors)
    if len(sensors) == 0:
        raise ValueError("sensors must hold at least one sensor")
    if states.ndim < 2 or states.shape[-1] != 4 or states.shape[-2] != len(sensors):
        raise ValueError(
            f"{name} must have shape (..., S, 4) with S = {len(sensors)} sensors "
            f"(or (..., 4) for a single sensor); got {states.shape}"
        )
    if not np.isfinite(states).all():
        raise ValueError(f"{name} must be finite (sensor positions/velocities)")
    return sensors, states


def _check_samples(target_samples, ndim: int = 2) -> np.ndarray:
    X = np.asarray(target_samples, dtype=float)
    if X.ndim != ndim or X.shape[-1] != 4 or X.shape[-2] < 1:
        raise ValueError(
            "target_samples must have shape "
            + ("(M, 4)" if ndim == 2 else "(K, M, 4)")
            + f" with M >= 1 pv samples; got {X.shape}"
        )
    require_finite("target_samples", X)
    return X


def _whitener(R: np.ndarray) -> np.ndarray:
    """L^{-1} with L L^T = R, so that H^T R^{-1} H = (L^{-1} H)^T (L^{-1} H)."""
    L = _cholesky("sensor.R", np.atleast_2d(np.asarray(R, dtype=float)))
    return np.linalg.solve(L, np.eye(L.shape[-1]))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Sum over the last axis of a * b, ``(..., M) -> (...)`` (matmul: fast for small batches)."""
    return (a[..., None, :] @ b[..., :, None])[..., 0, 0]


def _bearing_information(sensor, s: np.ndarray, X: np.ndarray, K: np.ndarray | None) -> np.ndarray:
    """Closed form of Hernandez eq. 8-9 for one bearing sensor.

    With dx = x - x_s, dy = y - y_s, r^2 = dx^2 + dy^2, eq. 9 gives H = (-dy, 0, dx, 0) / r^2, so
    H^T H / sigma^2 has entries (dy^2, -dx dy, dx^2) / (sigma^2 r^4) in the (x, y) block.
    ``s`` is ``(..., 4)``, ``X`` is ``(M, 4)``; returns ``(..., n, n)``.
    """
    dx = X[:, 0] - s[..., 0, None]  # (..., M)
    dy = X[:, 2] - s[..., 2, None]
    r2 = dx * dx
    r2 += dy * dy
    r_min = float(getattr(sensor, "r_min", 0.0))
    r_max = float(getattr(sensor, "r_max", np.inf))
    # Reductions decide whether any sample falls outside the detection ranges (eq. 8's I_r,
    # contract in_range: r_min <= r <= r_max) or sits on a sensor; the mask only if one does.
    lo = float(r2.min(initial=np.inf))
    hi = float(r2.max(initial=0.0)) if r_max < np.inf else 0.0
    if lo == 0.0:
        raise ValueError("sensor_states: a target sample coincides with a sensor (zero range)")
    if lo < r_min * r_min or hi > r_max * r_max:
        detect = (r2 >= r_min * r_min) & (r2 <= r_max * r_max)
        r2 = np.where(detect, r2, np.inf)  # r^2 = inf gives weight 0
    sigma2 = float(np.asarray(sensor.R, dtype=float).reshape(-1)[0])
    scale = float(getattr(sensor, "pd", 1.0)) / (sigma2 * X.shape[0])  # pd and the MC mean
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


def _jacobian_information(sensor, s: np.ndarray, X: np.ndarray, K: np.ndarray | None) -> np.ndarray:
    """Generic Hernandez eq. 8 for any sensor through ``sensor.jacobian`` and ``sensor.R``."""
    sp = s[..., None, :]  # (..., 1, 4) broadcasts against the M samples
    H = np.asarray(sensor.jacobian(X, sp), dtype=float)  # (..., M, m, 4)
    detect = np.asarray(sensor.in_range(X, sp), dtype=bool)  # (..., M)
    pd = float(getattr(sensor, "pd", 1.0))
    w = np.where(detect, pd / X.shape[0], 0.0)
    G = _whitener(sensor.R) @ H  # R^{-1/2} H
    if K is not None:
        G = G @ K
    return np.einsum("...mai,...maj,...m->...ij", G, G, w)


def measurement_information(
    sensors,
    sensor_states: np.ndarray,
    target_samples: np.ndarray,
    *,
    kinematics_jacobian: np.ndarray | None = None,
    method: str = "auto",
) -> np.ndarray:
    """Monte Carlo measurement contribution J_Z (Hernandez eq. 8-9), batched over candidates.

    J_Z = sum_j (1/M) sum_m pd_j I_r(s_j, X_m) H_j(X_m)^T R_j^{-1} H_j(X_m).

    Args:
        sensors: one sensor, or a sequence of S sensors (contract ``activetrack.models.sensors``).
        sensor_states: pv states ``(..., S, 4)`` (``(..., 4)`` when ``sensors`` is one sensor);
            the leading ``...`` are candidate positions scored in one call.
        target_samples: pv samples ``(M, 4)`` of the prior target distribution at this epoch.
        kinematics_jacobian: optional d pv / d x ``(M, 4, n)`` at the samples; the information is
            then with respect to that model state (n x n) instead of pv.
        method: ``"auto"`` (closed form for bearing sensors, Jacobian path otherwise),
            ``"closed_form"`` (bearing sensors only) or ``"jacobian"`` (``sensor.jacobian``).

    Returns:
        J_Z ``(..., n, n)``, symmetric positive semi-definite (n = 4 in pv).
    """
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS} (got {method!r})")
    sensors, states = _as_sensor_batch(sensors, sensor_states, "sensor_states")
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
    for j, sensor in enumerate(sensors):  # a handful of sensors; candidates/samples vectorised
        bearing = getattr(sensor, "kind", "") in _BEARING_KINDS and np.size(sensor.R) == 1
        if method == "closed_form" and not bearing:
            raise ValueError(
                f"method='closed_form' needs bearing sensors (sensor {j} kind={sensor.kind!r})"
            )
        if bearing and method != "jacobian":
            J_Z = J_Z + _bearing_information(sensor, states[..., j, :], X, K)
        else:
            # einsum round-off can leave a tiny asymmetry on this path.
            J_Z = J_Z + symmetrize(_jacobian_information(sensor, states[..., j, :], X, K))
    return J_Z


def pcrlb_step(J_prev: np.ndarray, F: np.ndarray, Q: np.ndarray, J_Z: np.ndarray) -> np.ndarray:
    """One step of Hernandez eq. 3: J_{k+1} = (Q + F J_k^{-1} F^T)^{-1} + J_Z(k+1).

    Batched: ``J_prev`` ``(..., n, n)``, ``F`` and ``Q`` ``(n, n)``, ``J_Z`` ``(..., n, n)``
    broadcast together. Uses Cholesky solves (no explicit inverse of J_k):
    with L L^T = J_k and X = L^{-1} F^T, F J_k^{-1} F^T = X^T X.
    """
    J_prev = np.asarray(J_prev, dtype=float)
    F, Q = check_dynamics(F, Q, J_prev.shape[-1])
    J_Z = np.asarray(J_Z, dtype=float)
    if not np.isfinite(J_Z).all():
        raise ValueError("J_Z must be finite")
    return predicted_information(J_prev, F, Q) + J_Z


def check_dynamics(F: np.ndarray, Q: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
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


def predicted_information(J_prev: np.ndarray, F: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """The prediction part of eq. 3, (Q + F J_k^{-1} F^T)^{-1}, for ``J_prev`` ``(..., n, n)``.

    F and Q ``(n, n)`` are taken as valid (the planner checks them once per decision, through
    :func:`pcrlb_step`); J_prev is still checked to be SPD.
    """
    L = _cholesky("J_prev", J_prev)
    Xt = _lower_solve(L, F.T)  # (..., n, n) = L^{-1} F^T
    C = Q + np.swapaxes(Xt, -1, -2) @ Xt  # predicted-state bound Q + F J^{-1} F^T
    # C and its inverse L^{-T} L^{-1} are symmetric by construction.
    return _spd_inverse("Q + F J_prev^-1 F^T", C, check_symmetry=False)


def propagate_samples(
    target_samples: np.ndarray,
    F: np.ndarray,
    Q: np.ndarray,
    n_steps: int,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
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
    F = np.asarray(F, dtype=float)
    require_finite("F", F)
    S = _psd_sqrt("Q", np.asarray(Q, dtype=float)) if rng is not None else None
    out = np.empty((int(n_steps), *X.shape))
    for k in range(int(n_steps)):
        X = X @ F.T
        if S is not None:
            X = X + rng.standard_normal(X.shape) @ S.T
        out[k] = X
    return out


def pcrlb_trajectory(
    J0: np.ndarray,
    F: np.ndarray,
    Q: np.ndarray,
    target_samples: np.ndarray,
    sensors,
    sensor_paths: np.ndarray,
    rng: np.random.Generator | None = None,
    *,
    method: str = "auto",
    active: np.ndarray | None = None,
) -> np.ndarray:
    """Fisher information J_k, k = 1..K, along sensor paths (Hernandez eq. 3-4 and 8-9).

    Args:
        J0: initial information ``(4, 4)`` (eq. 4: J_0 = C_0^{-1} for a Gaussian prior).
        F, Q: linear target dynamics (eq. 2), ``(4, 4)``.
        target_samples: prior samples ``(M, 4)`` at k = 0, propagated to each epoch through the
            noisy dynamics with ``rng`` (noise-free if ``rng`` is None) as in Hernandez sec. 3.2;
            or already-propagated samples ``(K, M, 4)`` for epochs 1..K (then ``rng`` is unused).
        sensors: one sensor or a sequence of S sensors.
        sensor_paths: sensor pv states at epochs 1..K, ``(K, ..., S, 4)``
            (``(K, ..., 4)`` for a single sensor); ``...`` are candidate paths.
        active: optional ``(K, S)`` bool, the sensors that measure at each epoch (sensor
            selection, stop-and-measure); the others add no information there. None: all.

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
    if active is not None:
        if not isinstance(sensors, (list, tuple)):
            raise ValueError("active needs sensors as a sequence of S sensors")
        active = np.asarray(active, dtype=bool)
        if active.shape != (n_steps, len(sensors)):
            raise ValueError(
                f"active must be (K, S) = ({n_steps}, {len(sensors)}), got {active.shape}"
            )
    for k in range(n_steps):
        if active is None or active[k].all():
            J_Z = measurement_information(sensors, paths[k], samples[k], method=method)
        elif active[k].any():
            idx = np.flatnonzero(active[k])
            J_Z = measurement_information(
                [sensors[j] for j in idx], paths[k][..., idx, :], samples[k], method=method
            )
        else:
            J_Z = np.zeros_like(J)
        J = pcrlb_step(J, F, Q, J_Z)
        out.append(J)
    return np.stack(out)
