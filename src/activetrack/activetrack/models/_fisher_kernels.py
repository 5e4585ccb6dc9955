"""Compiled Fisher-information kernels of the built-in sensors (Hernandez eq. 8-9), offered
through ``information_kernel()`` (:data:`activetrack.models.base.InformationKernel`).

Each computes the sums of the numpy form, samples in order, so the two agree to round-off
(tested to 1e-12). The loops run over samples outside and sensor states inside (each state
keeps its running sums; the inner loop vectorises). numba compiles on first use and caches
next to this file (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

from activetrack.arraytypes import FloatArray

__all__ = [
    "bearing_information",
    "jacobian_information_sums",
    "range_bearing_information",
    "range_rate_bearing_information",
    "warm_up",
]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _bearing_information(
    X: FloatArray, S: FloatArray, scale: float, r_min2: float, r_max2: float
) -> tuple[FloatArray, bool]:
    """J_Z ``(N, 4, 4)`` of a bearing sensor at the N pv states ``S`` over the samples ``X``:
    scale x the sums over the samples of b^2, a^2 and -a b (a = dx / r^2, b = dy / r^2) in the
    (x, y) block, samples outside [r_min, r_max] left out (eq. 8's I_r); and whether any sample
    sits on a sensor (zero range)."""
    n = S.shape[0]
    sx = np.ascontiguousarray(S[:, 0])
    sy = np.ascontiguousarray(S[:, 2])
    sbb = np.zeros(n)
    saa = np.zeros(n)
    sab = np.zeros(n)
    on_sensor = False
    for m in range(X.shape[0]):
        x, y = X[m, 0], X[m, 2]
        for c in range(n):
            dx = x - sx[c]
            dy = y - sy[c]
            r2 = dx * dx + dy * dy
            on_sensor |= r2 == 0.0
            inv = 1.0 / r2 if (r2 >= r_min2) & (r2 <= r_max2) else 0.0
            a = dx * inv
            b = dy * inv
            sbb[c] += b * b
            saa[c] += a * a
            sab[c] += a * b
    out = np.zeros((n, 4, 4))
    for c in range(n):
        out[c, 0, 0] = scale * sbb[c]
        out[c, 2, 2] = scale * saa[c]
        out[c, 0, 2] = out[c, 2, 0] = -scale * sab[c]
    return out, on_sensor


def bearing_information(
    samples: FloatArray, sensor_pv: FloatArray, sigma: float, pd: float, r_min: float, r_max: float
) -> FloatArray:
    """Hernandez eq. 8-9 for a bearing sensor (noise sigma, rad) at N pv states ``(N, 4)`` over
    pv samples ``(M, 4)``: ``(N, 4, 4)``, the closed form of ``BearingSensor.fisher_information``
    (H^T H / sigma^2 = (dy^2, -dx dy, dx^2) / (sigma^2 r^4) in the (x, y) block)."""
    scale = float(pd) / (sigma**2 * samples.shape[0])  # pd and the MC mean, as the numpy form
    out, on_sensor = _bearing_information(samples, sensor_pv, scale, r_min * r_min, r_max * r_max)
    if on_sensor:
        raise ValueError("sensor_states: a target sample coincides with a sensor (zero range)")
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _range_bearing_information(
    X: FloatArray,
    S: FloatArray,
    scale_r: float,
    scale_b: float,
    r_min: float,
    r_max: float,
) -> tuple[FloatArray, bool]:
    """J_Z ``(N, 4, 4)`` of a range-bearing sensor at the N pv states ``S`` over the samples
    ``X``: in the (x, y) block, scale_r x the sums of (dx^2, dx dy, dy^2) / r^2 (the range row
    (dx, dy) / r) plus scale_b x the sums of (dy^2, -dx dy, dx^2) / r^4 (the bearing row
    (-dy, dx) / r^2), samples outside [r_min, r_max] left out (eq. 8's I_r, on r itself as
    ``in_range`` tests it); and whether any sample sits on a sensor (zero range)."""
    n = S.shape[0]
    sx = np.ascontiguousarray(S[:, 0])
    sy = np.ascontiguousarray(S[:, 2])
    rxx, rxy, ryy = np.zeros(n), np.zeros(n), np.zeros(n)
    bxx, bxy, byy = np.zeros(n), np.zeros(n), np.zeros(n)
    on_sensor = False
    for m in range(X.shape[0]):
        x, y = X[m, 0], X[m, 2]
        for c in range(n):
            dx = x - sx[c]
            dy = y - sy[c]
            r2 = dx * dx + dy * dy
            on_sensor |= r2 == 0.0
            r = np.sqrt(r2)
            inv = 1.0 / r2 if (r >= r_min) & (r <= r_max) else 0.0
            xx, xy, yy = dx * dx * inv, dx * dy * inv, dy * dy * inv
            rxx[c] += xx
            rxy[c] += xy
            ryy[c] += yy
            bxx[c] += yy * inv  # the bearing row's (dy^2, -dx dy, dx^2) / r^4
            bxy[c] += xy * inv
            byy[c] += xx * inv
    out = np.zeros((n, 4, 4))
    for c in range(n):
        out[c, 0, 0] = scale_r * rxx[c] + scale_b * bxx[c]
        out[c, 2, 2] = scale_r * ryy[c] + scale_b * byy[c]
        out[c, 0, 2] = out[c, 2, 0] = scale_r * rxy[c] - scale_b * bxy[c]
    return out, on_sensor


def range_bearing_information(
    samples: FloatArray,
    sensor_pv: FloatArray,
    sigma_r: float,
    sigma_b: float,
    pd: float,
    r_min: float,
    r_max: float,
) -> FloatArray:
    """Eq. 8 for a range-bearing sensor (noise sigma_r, m, and sigma_b, rad; Ramdaras eq. 8-9)
    at N pv states ``(N, 4)`` over pv samples ``(M, 4)``: ``(N, 4, 4)``, the closed form of
    ``GaussianSensor.fisher_information`` for H = ((dx, 0, dy, 0) / r, (-dy, 0, dx, 0) / r^2)
    and R = diag(sigma_r^2, sigma_b^2)."""
    M = samples.shape[0]
    scale_r = float(pd) / (sigma_r**2 * M)
    scale_b = float(pd) / (sigma_b**2 * M)
    out, on_sensor = _range_bearing_information(samples, sensor_pv, scale_r, scale_b, r_min, r_max)
    if on_sensor:
        raise ValueError("sensor_states: a target sample coincides with a sensor (zero range)")
    return out


# Entries (i, j), i <= j, of a symmetric 4 x 4 J in the order _range_rate_bearing_information
# accumulates them.
_UPPER = ((0, 0), (0, 1), (0, 2), (0, 3), (1, 1), (1, 2), (1, 3), (2, 2), (2, 3), (3, 3))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _range_rate_bearing_information(
    X: FloatArray,
    S: FloatArray,
    scales: FloatArray,
    r_min: float,
    r_max: float,
) -> tuple[FloatArray, bool]:
    """J_Z ``(N, 4, 4)`` of a range, range-rate and bearing sensor at the N pv states ``S`` over
    the samples ``X``: the sums of scales[k] h_k^T h_k over its three Jacobian rows (those of
    ``RangeRateBearingSensor.jacobian``: the range rate's row (dy c, dx / r, -dx c, dy / r),
    c = (dvx dy - dvy dx) / r^3, fills every entry), samples outside [r_min, r_max] left out;
    and whether any sample sits on a sensor (zero range)."""
    n = S.shape[0]
    acc = np.zeros((n, 10))
    on_sensor = False
    s_r, s_rr, s_b = scales[0], scales[1], scales[2]
    for m in range(X.shape[0]):
        x, vx, y, vy = X[m, 0], X[m, 1], X[m, 2], X[m, 3]
        for c in range(n):
            dx, dvx = x - S[c, 0], vx - S[c, 1]
            dy, dvy = y - S[c, 2], vy - S[c, 3]
            r2 = dx * dx + dy * dy
            on_sensor |= r2 == 0.0
            r = np.sqrt(r2)
            if not ((r >= r_min) & (r <= r_max)) or r2 == 0.0:
                continue
            ux, uy = dx / r, dy / r  # the range row; the range rate's velocity part
            bx, by = -dy / r2, dx / r2  # the bearing row
            cross = (dvx * dy - dvy * dx) / (r2 * r)
            gx, gy = dy * cross, -dx * cross  # the range rate's position part
            acc[c, 0] += s_r * ux * ux + s_rr * gx * gx + s_b * bx * bx  # (x, x)
            acc[c, 1] += s_rr * gx * ux  # (x, xdot)
            acc[c, 2] += s_r * ux * uy + s_rr * gx * gy + s_b * bx * by  # (x, y)
            acc[c, 3] += s_rr * gx * uy  # (x, ydot)
            acc[c, 4] += s_rr * ux * ux  # (xdot, xdot)
            acc[c, 5] += s_rr * ux * gy  # (xdot, y)
            acc[c, 6] += s_rr * ux * uy  # (xdot, ydot)
            acc[c, 7] += s_r * uy * uy + s_rr * gy * gy + s_b * by * by  # (y, y)
            acc[c, 8] += s_rr * gy * uy  # (y, ydot)
            acc[c, 9] += s_rr * uy * uy  # (ydot, ydot)
    out = np.empty((n, 4, 4))
    for c in range(n):
        for k in range(10):
            i, j = _UPPER[k]
            out[c, i, j] = out[c, j, i] = acc[c, k]
    return out, on_sensor


def range_rate_bearing_information(
    samples: FloatArray,
    sensor_pv: FloatArray,
    sigma_r: float,
    sigma_rr: float,
    sigma_b: float,
    pd: float,
    r_min: float,
    r_max: float,
) -> FloatArray:
    """Eq. 8 for a range, range-rate and bearing sensor (Ramdaras eq. 10-11; noise sigma_r, m,
    sigma_rr, m/s, sigma_b, rad) at N pv states ``(N, 4)`` over pv samples ``(M, 4)``:
    ``(N, 4, 4)``, the closed form of ``GaussianSensor.fisher_information`` for its Jacobian
    and R = diag(sigma_r^2, sigma_rr^2, sigma_b^2)."""
    w = float(pd) / samples.shape[0]
    scales = np.array([w / sigma_r**2, w / sigma_rr**2, w / sigma_b**2])
    out, on_sensor = _range_rate_bearing_information(samples, sensor_pv, scales, r_min, r_max)
    if on_sensor:
        raise ValueError("sensor_states: a target sample coincides with a sensor (zero range)")
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _jacobian_information_sums(G: FloatArray, w: FloatArray) -> FloatArray:
    """``(B, n, n)``: sum over m, then a, of G[b, m, a, i] G[b, m, a, j] w[b, m], products and
    sums in the order of numpy's einsum (no BLAS), the upper triangle mirrored (the products
    commute, so einsum's two halves are equal too)."""
    B, M, A, n = G.shape
    out = np.empty((B, n, n))
    for b in range(B):
        for i in range(n):
            for j in range(i, n):
                acc = 0.0
                for m in range(M):
                    for a in range(A):
                        acc += G[b, m, a, i] * G[b, m, a, j] * w[b, m]
                out[b, i, j] = out[b, j, i] = acc
    return out


def jacobian_information_sums(G: FloatArray, w: FloatArray) -> FloatArray:
    """``np.einsum("...mai,...maj,...m->...ij", G, G, w)`` bit for bit (the sums of
    :func:`activetrack.models.base.jacobian_information`): whitened Jacobians ``G``
    ``(..., M, m, n)``, sample weights ``w`` broadcasting to ``(..., M)``; ``(..., n, n)``."""
    *batch, M, A, n = G.shape
    G4 = np.ascontiguousarray(G, dtype=float).reshape(-1, M, A, n)
    w2 = np.ascontiguousarray(np.broadcast_to(w, (*batch, M)), dtype=float).reshape(-1, M)
    return _jacobian_information_sums(G4, w2).reshape(*batch, n, n)


def warm_up() -> None:
    """Compile (or load) the kernels of this module (``activetrack.kernels.warm_up``)."""
    X = np.array([[1.0, 0.0, 2.0, 0.0], [3.0, 0.0, 1.0, 0.0]])
    bearing_information(X, np.zeros((1, 4)), 0.01, 1.0, 0.0, np.inf)
    range_bearing_information(X, np.zeros((1, 4)), 5.0, 0.01, 1.0, 0.0, np.inf)
    range_rate_bearing_information(X, np.zeros((1, 4)), 5.0, 0.5, 0.01, 1.0, 0.0, np.inf)
    jacobian_information_sums(np.ones((1, 2, 2, 4)), np.ones((1, 2)))
