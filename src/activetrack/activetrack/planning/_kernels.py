"""Compiled helpers of the planner's inner loop: the bookkeeping of the lockstep quadrant search
(``searches.quadrant_search``) and the candidate legs of the horizon search.

For all problems of a division in one call they store the new costs and payloads, offer each
problem's best point, choose the quadrant with the lowest mean corner cost and halve the
square, operation for operation as the numpy version (first index on ties, NaN first as
``np.argmin``), so the search takes the same decisions. Payloads are ``(..., P)`` rows. numba
compiles on first use and caches next to this file; ``horizons.warm_up`` calls each once.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from activetrack.arraytypes import FloatArray

__all__ = ["candidate_legs", "quadrant_accept", "quadrant_points"]

IntArray = np.ndarray
_TWO_PI = 2.0 * np.pi


@numba.njit(cache=True, nogil=True)
def candidate_legs(
    u: FloatArray,
    rows: IntArray,
    pv: FloatArray,
    heading: FloatArray,
    v_lo: FloatArray,
    v_hi: FloatArray,
    dpsi_max: float,
    dt: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Manoeuvres ``(b, C, 2)``, pv at the next epoch ``(b, C, 4)`` and new headings ``(b, C)`` of
    the unit-square points ``u`` ``(b, C, 2)`` for the problems ``rows`` (pv ``(B, 4)``, heading
    and the reachable speeds [v_lo, v_hi] ``(B,)``): ``unit_to_manoeuvre`` and
    ``step_platform`` operation for operation (the heading wrapped to [-pi, pi) as
    ``angles.wrap_angle``)."""
    b, C = u.shape[0], u.shape[1]
    man = np.empty((b, C, 2))
    nxt = np.empty((b, C, 4))
    psi = np.empty((b, C))
    for i in range(b):
        r = rows[i]
        lo, hi = v_lo[r], v_hi[r]
        for c in range(C):
            dpsi = (2.0 * u[i, c, 0] - 1.0) * dpsi_max
            v = lo + u[i, c, 1] * (hi - lo)
            w = np.mod(heading[r] + dpsi + np.pi, _TWO_PI) - np.pi
            if w >= np.pi:
                w = w - _TWO_PI
            vx = v * np.cos(w)
            vy = v * np.sin(w)
            man[i, c, 0], man[i, c, 1] = dpsi, v
            nxt[i, c, 0], nxt[i, c, 1] = pv[r, 0] + vx * dt, vx
            nxt[i, c, 2], nxt[i, c, 3] = pv[r, 2] + vy * dt, vy
            psi[i, c] = w
    return man, nxt, psi


@numba.njit(cache=True, nogil=True)
def quadrant_points(
    origin: FloatArray, side: FloatArray, rows: IntArray, new: IntArray
) -> FloatArray:
    """Unit-square points ``(b, C, 2)`` of the 3 x 3 grid entries ``new`` ``(C, 2)`` of the
    problems ``rows``: origin + side x (0, 0.5, 1)[index]."""
    out = np.empty((rows.shape[0], new.shape[0], 2))
    for i in range(rows.shape[0]):
        r = rows[i]
        for c in range(new.shape[0]):
            for k in range(2):
                out[i, c, k] = origin[r, k] + side[r] * (0.5 * new[c, k])
    return out


@numba.njit(cache=True, nogil=True)
def _first_argmin(v: FloatArray) -> int:
    """np.argmin of a 1-d array: the first minimum, or the first NaN if there is one."""
    best = 0
    for c in range(v.shape[0]):
        if math.isnan(v[c]):
            return c
        if v[c] < v[best]:
            best = c
    return best


@numba.njit(cache=True, nogil=True)
def _offer(
    i: int,
    r: int,
    u: FloatArray,
    costs: FloatArray,
    aux: FloatArray,
    best_u: FloatArray,
    best_cost: FloatArray,
    best_aux: FloatArray,
) -> bool:
    """Take row i's lowest candidate for problem r if it beats the stored best."""
    k = _first_argmin(costs[i])
    if not costs[i, k] < best_cost[r]:
        return False
    best_cost[r] = costs[i, k]
    best_u[r, 0] = u[i, k, 0]
    best_u[r, 1] = u[i, k, 1]
    best_aux[r, :] = aux[i, k, :]
    return True


@numba.njit(cache=True, nogil=True)
def _split(r: int, values: FloatArray, payload: FloatArray, origin: FloatArray, side: FloatArray):
    """Choose problem r's quadrant (lowest average corner cost) and make it the new square."""
    v = values[r]
    quad = np.empty(4)
    for a in range(2):
        for b in range(2):
            quad[2 * a + b] = 0.25 * (v[a, b] + v[a + 1, b] + v[a, b + 1] + v[a + 1, b + 1])
    q = _first_argmin(quad)
    a, b = q // 2, q % 2
    corners = np.empty((2, 2))
    pcorners = np.empty((2, 2, payload.shape[2]))
    for da in range(2):
        for db in range(2):
            corners[da, db] = v[a + da, b + db]
            pcorners[da, db] = payload[r, 3 * (a + da) + b + db]
    values[r, :, :] = np.nan
    payload[r, :, :] = 0.0
    for da in range(2):
        for db in range(2):
            values[r, 2 * da, 2 * db] = corners[da, db]
            payload[r, 3 * (2 * da) + 2 * db] = pcorners[da, db]
    half = 0.5 * side[r]
    origin[r, 0] = origin[r, 0] + half * a
    origin[r, 1] = origin[r, 1] + half * b
    side[r] = half


@numba.njit(cache=True, nogil=True)
def quadrant_accept(
    values: FloatArray,
    payload: FloatArray,
    origin: FloatArray,
    side: FloatArray,
    stale: IntArray,
    best_u: FloatArray,
    best_cost: FloatArray,
    best_aux: FloatArray,
    rows: IntArray,
    new: IntArray,
    u: FloatArray,
    costs: FloatArray,
    aux: FloatArray,
    last: bool,
    patience: int,
) -> IntArray:
    """Store a division's costs ``(b, C)`` and payloads ``(b, C, P)`` of ``rows`` at the grid
    entries ``new``, offer each row's best point, and (unless ``last``) split the square of
    every row still searching (fewer than ``patience`` divisions without improvement).

    The search's state: values (B, 3, 3), payload (B, 9, P), origin (B, 2), side (B,), stale
    (B,); its best points: u (B, 2), cost (B,), aux (B, P). Returns the rows that search on."""
    for i in range(rows.shape[0]):
        r = rows[i]
        for c in range(new.shape[0]):
            values[r, new[c, 0], new[c, 1]] = costs[i, c]
            payload[r, 3 * new[c, 0] + new[c, 1], :] = aux[i, c, :]
        better = _offer(i, r, u, costs, aux, best_u, best_cost, best_aux)
        stale[r] = 0 if better else stale[r] + 1
    if last:
        return np.empty(0, dtype=rows.dtype)
    keep = rows[stale[rows] < patience]
    for r in keep:
        _split(r, values, payload, origin, side)
    return keep
