"""Scalar costs ``(...)`` of covariance batches ``P`` ``(..., n, n)`` (a PCRLB J^{-1} or an MRE
prediction; Hernandez eq. 10, Ramdaras eq. 24-26); positions are pv entries 0 and 2 unless
``position_indices`` says otherwise. The planner criteria built on them:
:mod:`activetrack.planning.criteria`.
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.kernels import kernels_enabled

__all__ = [
    "EQ26_ROWS",
    "criterion_jacobian",
    "criterion_variance",
    "determinant_cost",
    "position_determinant",
    "position_trace",
    "position_trace_of_information",
    "rmse_bound",
    "rmse_bound_of_information",
    "trace_cost",
]

# The rows H^c of Ramdaras eq. 26 (the quantity whose variance eq. 25 takes).
EQ26_ROWS = ("heading", "range", "doppler", "bearing")


def _cov(P: ArrayLike) -> np.ndarray:
    P = np.asarray(P, dtype=float)
    if P.ndim < 2 or P.shape[-1] != P.shape[-2]:
        raise ValueError(f"P must be a batch of square matrices (..., n, n); got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ValueError("P must be finite")
    return P


def rmse_bound(P: ArrayLike, position_indices: tuple[int, int] = (0, 2)) -> np.ndarray:
    """Hernandez eq. 10: b_k = max(sqrt(P[x, x]), sqrt(P[y, y])), ``(..., n, n) -> (...)``.

    P is the bound J_k^{-1}; b_k is the larger of the x and y RMSE bounds.
    """
    P = _cov(P)
    ix, iy = position_indices
    var = np.stack([P[..., ix, ix], P[..., iy, iy]], axis=-1)
    if np.any(var < 0):
        raise ValueError("P must have non-negative position variances")
    return np.sqrt(var.max(axis=-1))


_POSITION_COLUMNS = np.eye(4)[:, [0, 2]]


def rmse_bound_of_information(J: np.ndarray) -> np.ndarray:
    """Hernandez eq. 10 from pv information ``(..., 4, 4) -> (...)``: the position variances of
    J^{-1} from one solve J V = [e_x, e_y]; compiled while kernels are enabled (equal to
    1e-12)."""
    J = np.asarray(J, dtype=float)
    if not kernels_enabled() or J.shape[-2:] != (4, 4):
        return _rmse_bound_of_information_numpy(J)
    from activetrack.bounds._kernels import rmse_bounds

    b, status = rmse_bounds(np.ascontiguousarray(J).reshape(-1, 4, 4))
    if status:
        raise ValueError(_NOT_SPD[status])
    return b.reshape(J.shape[:-2])


_NOT_SPD = {
    1: "J must be symmetric positive definite (it is singular)",
    2: "J must be symmetric positive definite (non-positive variance)",
}


def _position_variances_of_information(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The x and y variances of J^{-1} ``(..., 4, 4) -> (...), (...)`` from one
    ``numpy.linalg.solve`` of J V = [e_x, e_y] (ValueError if J is singular)."""
    try:
        V = np.linalg.solve(J, _POSITION_COLUMNS)  # (..., 4, 2) = columns x, y of J^{-1}
    except np.linalg.LinAlgError:
        raise ValueError(_NOT_SPD[1]) from None
    return V[..., 0, 0], V[..., 2, 1]


def _rmse_bound_of_information_numpy(J: np.ndarray) -> np.ndarray:
    """:func:`rmse_bound_of_information` by ``numpy.linalg.solve`` (the reference)."""
    var = np.maximum(*_position_variances_of_information(J))
    if not np.all(var > 0.0):
        raise ValueError(_NOT_SPD[2])
    return np.sqrt(var)


def position_trace(P: ArrayLike, position_indices: tuple[int, int] = (0, 2)) -> np.ndarray:
    """P(1,1) + P(3,3), ``(..., n, n) -> (...)``: the mean squared position error E|e|^2 of a
    track with error covariance P, what GOSPA's localisation (order p = 2) counts for it."""
    P = _cov(P)
    ix, iy = position_indices
    return P[..., ix, ix] + P[..., iy, iy]


def position_trace_of_information(J: np.ndarray) -> np.ndarray:
    """:func:`position_trace` of J^{-1} from pv information ``(..., 4, 4) -> (...)``, from one
    solve J V = [e_x, e_y] (as :func:`rmse_bound_of_information`)."""
    var_x, var_y = _position_variances_of_information(np.asarray(J, dtype=float))
    var = var_x + var_y
    if not np.all(var > 0.0):
        raise ValueError(_NOT_SPD[2])
    return var


def trace_cost(P: ArrayLike) -> np.ndarray:
    """Trace criterion tr(P), ``(..., n, n) -> (...)``."""
    return np.trace(_cov(P), axis1=-2, axis2=-1)


def determinant_cost(P: ArrayLike) -> np.ndarray:
    """Determinant criterion det(P), ``(..., n, n) -> (...)``."""
    return np.linalg.det(_cov(P))


def position_determinant(P: ArrayLike, position_indices: tuple[int, int] = (0, 2)) -> np.ndarray:
    """Ramdaras eq. 24: det [[P(1,1), P(1,3)], [P(3,1), P(3,3)]] = s_xx s_yy - s_xy^2."""
    P = _cov(P)
    ix, iy = position_indices
    return P[..., ix, ix] * P[..., iy, iy] - P[..., ix, iy] * P[..., iy, ix]


def criterion_jacobian(
    criterion: str, x: ArrayLike, sensor_state: ArrayLike | None = None
) -> np.ndarray:
    """H^c of Ramdaras eq. 26 at the predicted pv state x ``(..., 4) -> (..., 4)``.

    Geometry is relative to ``sensor_state`` (pv, default the origin as in the paper), with
    r = sqrt(dx^2 + dy^2):

    - heading psi = atan2(ydot, xdot): (0, -ydot/v^2, 0, xdot/v^2)
    - range: (dx/r, 0, dy/r, 0)
    - Doppler rdot = (dx dvx + dy dvy)/r (relative velocity; eq. 11 with a still sensor):
      (dvx/r - dx rdot/r^2, dx/r, dvy/r - dy rdot/r^2, dy/r). The Doppler row of eq. 26 is
      OCR-damaged; this is its derivative, checked against finite differences in the tests.
    - bearing: (-dy/r^2, 0, dx/r^2, 0)
    """
    x = np.asarray(x, dtype=float)
    if x.shape[-1:] != (4,):
        raise ValueError(f"x must be a pv state (..., 4); got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x must be finite")
    rel = x if sensor_state is None else x - np.asarray(sensor_state, dtype=float)
    if not np.all(np.isfinite(rel)):
        raise ValueError("sensor_state must be finite")
    dx, dvx, dy, dvy = (rel[..., i] for i in range(4))
    zero = np.zeros_like(dx)
    if criterion == "heading":
        v2 = x[..., 1] ** 2 + x[..., 3] ** 2
        if np.any(v2 == 0):
            raise ValueError("x: the heading criterion needs a nonzero target speed")
        return np.stack([zero, -x[..., 3] / v2, zero, x[..., 1] / v2], axis=-1)
    if criterion not in EQ26_ROWS:
        raise ValueError(f"criterion must be one of {EQ26_ROWS} (got {criterion!r})")
    r2 = dx * dx + dy * dy
    if np.any(r2 == 0):
        raise ValueError("x: zero range between target and sensor_state")
    r = np.sqrt(r2)
    if criterion == "range":
        return np.stack([dx / r, zero, dy / r, zero], axis=-1)
    if criterion == "bearing":
        return np.stack([-dy / r2, zero, dx / r2, zero], axis=-1)
    rdot = (dx * dvx + dy * dvy) / r
    return np.stack([dvx / r - dx * rdot / r2, dx / r, dvy / r - dy * rdot / r2, dy / r], axis=-1)


def criterion_variance(
    criterion: str, P: ArrayLike, x: ArrayLike, sensor_state: ArrayLike | None = None
) -> np.ndarray:
    """Ramdaras eq. 25: C = H^c(x) P H^c(x)^T for a pv covariance ``(..., 4, 4) -> (...)``."""
    P = _cov(P)
    if P.shape[-1] != 4:
        raise ValueError(f"P must be a pv covariance (..., 4, 4); got {P.shape}")
    h = criterion_jacobian(criterion, x, sensor_state)
    return np.einsum("...i,...ij,...j->...", h, P, h)
