"""numba kernels of the particle filter step, each equal to a numpy reference in the core.

Each kernel does the arithmetic of its reference in the same order and draws the same random
numbers from the same ``numpy.random.Generator``, so the compiled and the numpy paths give the
same particles up to floating-point round-off, in practice the same bits
(tests/core/test_pf_kernels.py):

- :func:`gaussian_sample`: f(x) + w = x F^T + w L^T, w ~ N(0, I) drawn row by row, the
  sampling of a linear motion model (reference ``rng.standard_normal((N, 4))``, then
  ``models.ncv.cv_rows`` for the zero pattern of the NCV models' F and L, or
  ``models.ncv.rows_times``), without the ``(N, 4)`` array of normals. The normals come from
  numpy's PCG64 stream compiled (``kernels.pcg64``) for ``default_rng`` generators, from
  numba's generator support for other bit generators;
- :func:`bearing_sines` with :func:`bearing_finish` / :func:`range_bearing_finish`: the
  arcsin-wrapped bearing log-likelihood (reference ``models.sensors._abs_bearing_error`` and
  ``BearingSensor.log_likelihood`` / ``RangeBearingSensor.log_likelihood``). The arcsin
  itself stays with numpy between the two passes: numpy's vectorised arcsin is several times
  faster than a scalar one per particle, and it is then the very same function;
- :func:`systematic_indices` and :func:`systematic_resample_rows`: systematic resampling
  (reference ``filters.resampling.systematic_indices``), the second one copying the chosen rows
  straight into the new particle array (no index array, no ``take``).

No ``fastmath``: without it LLVM neither reorders nor fuses the floating-point operations, which
keeps them those of the reference. ``error_model="numpy"``: a division by zero gives inf or NaN
as in numpy (a particle on the sensor) instead of raising. Every kernel is cached on disk
(``cache=True``). numba keys that cache on this file alone: the sampling kernels inline
``pcg64.layer``, so a change there reaches them only once ``kernels/__pycache__`` is cleared,
which ``make setup`` does whenever a kernel source changed (tools/setup.sh).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numba import njit

from activetrack.kernels.pcg64 import (
    BUFFER,
    KI,
    advance,
    layer,
    new_stream,
    pcg64_route,
    refill,
    rejected,
    stream_words,
)

__all__ = [
    "bearing_finish",
    "bearing_sines",
    "gaussian_sample",
    "range_bearing_finish",
    "systematic_indices",
    "systematic_resample_rows",
    "warm_up",
]


@njit(inline="always")
def _cv_row(out, i, X, w0, w1, w2, w3, f, g):  # pragma: no cover - compiled
    """Row i of out = X F^T + w L^T from the non-zero terms of two constant-velocity axes only
    (F, L row-major 16-tuples f, g), the operations of ``models.ncv.cv_rows``; out and X
    flat ``(4 N,)`` (no stride product per row). Returns the sum of X's row: not finite when
    the row holds a NaN or an infinity (:func:`_finiteness`)."""
    k = 4 * i
    x0, x1, x2, x3 = X[k], X[k + 1], X[k + 2], X[k + 3]
    out[k] = (x0 * f[0] + x1 * f[1]) + w0 * g[0]
    out[k + 1] = x1 * f[5] + (w0 * g[4] + w1 * g[5])
    out[k + 2] = (x2 * f[10] + x3 * f[11]) + w2 * g[10]
    out[k + 3] = x3 * f[15] + (w2 * g[14] + w3 * g[15])
    return (x0 + x1) + (x2 + x3)


@njit(inline="always")
def _full_row(out, i, X, w0, w1, w2, w3, f, g):  # pragma: no cover - compiled
    """Row i of out = X F^T + w L^T, full sums over k = 0..3 in order
    (``models.ncv.rows_times``); flat arrays and the return as :func:`_cv_row`."""
    k = 4 * i
    x0, x1, x2, x3 = X[k], X[k + 1], X[k + 2], X[k + 3]
    for r in range(4):
        out[k + r] = (x0 * f[4 * r] + x1 * f[4 * r + 1] + x2 * f[4 * r + 2] + x3 * f[4 * r + 3]) + (
            w0 * g[4 * r] + w1 * g[4 * r + 1] + w2 * g[4 * r + 2] + w3 * g[4 * r + 3]
        )
    return (x0 + x1) + (x2 + x3)


@njit(inline="always")
def _finiteness(total):  # pragma: no cover - compiled
    """Whether X may hold a NaN or an infinity, from the sum of its rows' sums: a non-finite x
    makes the sum non-finite; a finite X whose sum overflows is a false alarm only (the
    caller then checks X itself and goes on). One add per row instead of a test of each x."""
    return not math.isfinite(total)


@njit(inline="always")
def _entries(A):  # pragma: no cover - compiled
    """The 16 entries of a 4 x 4 matrix, row-major, as a tuple (held in registers)."""
    return (
        A[0, 0], A[0, 1], A[0, 2], A[0, 3], A[1, 0], A[1, 1], A[1, 2], A[1, 3],
        A[2, 0], A[2, 1], A[2, 2], A[2, 3], A[3, 0], A[3, 1], A[3, 2], A[3, 3],
    )  # fmt: skip


# ``out = X F^T + W L^T`` with W's normals drawn row by row: from the PCG64 stream of state
# ``words`` (``pcg64``; returning (outputs used or -1, X may be non-finite)), or given
# ``(N, 4)`` (returning whether X may be non-finite); with the constant-velocity zeros or the
# full sums. Separate small kernels with the common case written out, the two PCG64 ones alike
# but for the row: measured, a flag for the arithmetic form or the draws in an inlined helper
# compiled to code two to four times slower, the row function as an argument cost 7 us more
# per call, and a closure factory is recompiled in every process (numba does not cache it:
# about 5 s).


@njit(cache=True, error_model="numpy")
def _cv_rows_pcg64(words, X, F, L, out):  # pragma: no cover - compiled
    f, g = _entries(F), _entries(L)
    Xf, of = X.reshape(X.size), out.reshape(out.size)
    chains, buf = new_stream(words), np.empty(BUFFER, dtype=np.uint64)
    end = refill(chains, buf, 0)
    base, i, j, total = 0, 0, 0, 0.0
    while i < X.shape[0]:
        if j + 4 <= end:  # all four in their layers' rectangles: ~94 % of rows
            i0, a0, w0 = layer(buf[j])
            i1, a1, w1 = layer(buf[j + 1])
            i2, a2, w2 = layer(buf[j + 2])
            i3, a3, w3 = layer(buf[j + 3])
            if a0 < KI[i0] and a1 < KI[i1] and a2 < KI[i2] and a3 < KI[i3]:
                j += 4
                total += _cv_row(of, i, Xf, w0, w1, w2, w3, f, g)
                i += 1
                continue
        j0, k = j, 0  # one output at a time, rejections included
        w0 = w1 = w2 = w3 = 0.0
        while k < 4:
            if j >= end:
                break
            idx, rabs, x = layer(buf[j])
            if rabs < KI[idx]:
                j += 1
            else:
                x, j = rejected(buf, j + 1, end, idx, rabs, x)
                if j < 0:
                    break
            w0, w1, w2, w3 = (
                (x, w1, w2, w3)
                if k == 0
                else (w0, x, w2, w3)
                if k == 1
                else ((w0, w1, x, w3) if k == 2 else (w0, w1, w2, x))
            )
            k += 1
        if k < 4:  # the buffer ran out inside this row: keep its outputs, refill, redo it
            keep = end - j0
            buf[:keep] = buf[j0:end]
            base += j0
            end, j = refill(chains, buf, keep), 0
            if end == keep:  # a row needing more than a buffer (never seen): give up
                return -1, _finiteness(total)
            continue
        total += _cv_row(of, i, Xf, w0, w1, w2, w3, f, g)
        i += 1
    return base + j, _finiteness(total)


@njit(cache=True, error_model="numpy")
def _full_rows_pcg64(words, X, F, L, out):  # pragma: no cover - compiled
    f, g = _entries(F), _entries(L)
    Xf, of = X.reshape(X.size), out.reshape(out.size)
    chains, buf = new_stream(words), np.empty(BUFFER, dtype=np.uint64)
    end = refill(chains, buf, 0)
    base, i, j, total = 0, 0, 0, 0.0
    while i < X.shape[0]:
        if j + 4 <= end:  # as in _cv_rows_pcg64
            i0, a0, w0 = layer(buf[j])
            i1, a1, w1 = layer(buf[j + 1])
            i2, a2, w2 = layer(buf[j + 2])
            i3, a3, w3 = layer(buf[j + 3])
            if a0 < KI[i0] and a1 < KI[i1] and a2 < KI[i2] and a3 < KI[i3]:
                j += 4
                total += _full_row(of, i, Xf, w0, w1, w2, w3, f, g)
                i += 1
                continue
        j0, k = j, 0  # one output at a time, rejections included
        w0 = w1 = w2 = w3 = 0.0
        while k < 4:
            if j >= end:
                break
            idx, rabs, x = layer(buf[j])
            if rabs < KI[idx]:
                j += 1
            else:
                x, j = rejected(buf, j + 1, end, idx, rabs, x)
                if j < 0:
                    break
            w0, w1, w2, w3 = (
                (x, w1, w2, w3)
                if k == 0
                else (w0, x, w2, w3)
                if k == 1
                else ((w0, w1, x, w3) if k == 2 else (w0, w1, w2, x))
            )
            k += 1
        if k < 4:  # the buffer ran out inside this row: keep its outputs, refill, redo it
            keep = end - j0
            buf[:keep] = buf[j0:end]
            base += j0
            end, j = refill(chains, buf, keep), 0
            if end == keep:  # a row needing more than a buffer (never seen): give up
                return -1, _finiteness(total)
            continue
        total += _full_row(of, i, Xf, w0, w1, w2, w3, f, g)
        i += 1
    return base + j, _finiteness(total)


@njit(cache=True, error_model="numpy")
def _cv_rows_from_normals(W, X, F, L, out):  # pragma: no cover - compiled
    f, g, total = _entries(F), _entries(L), 0.0
    Xf, of = X.reshape(X.size), out.reshape(out.size)
    for i in range(X.shape[0]):
        total += _cv_row(of, i, Xf, W[i, 0], W[i, 1], W[i, 2], W[i, 3], f, g)
    return _finiteness(total)


@njit(cache=True, error_model="numpy")
def _full_rows_from_normals(W, X, F, L, out):  # pragma: no cover - compiled
    f, g, total = _entries(F), _entries(L), 0.0
    Xf, of = X.reshape(X.size), out.reshape(out.size)
    for i in range(X.shape[0]):
        total += _full_row(of, i, Xf, W[i, 0], W[i, 1], W[i, 2], W[i, 3], f, g)
    return _finiteness(total)


@njit(cache=True)
def _generator_normals(rng, out):  # pragma: no cover - compiled
    """numba's ``Generator.standard_normal``, one draw per entry (any bit generator)."""
    for i in range(out.shape[0]):
        out[i] = rng.standard_normal()
    return out


def _sample_pcg64(X, F, L, cv, rng):
    """The PCG64 route of :func:`gaussian_sample`, or None when a row needs more than a
    buffer of outputs (the generator is then left untouched)."""
    out = np.empty((X.shape[0], 4))
    with rng.bit_generator.lock:
        words, state = stream_words(rng)
        used, bad = (_cv_rows_pcg64 if cv else _full_rows_pcg64)(words, X, F, L, out)
        if used < 0:
            return None
        advance(rng, used, state)
    return out, not bad


def _sample_generic(X, F, L, cv, rng):
    """:func:`gaussian_sample` through numba's generator support (any bit generator)."""
    W = _generator_normals(rng, np.empty(4 * X.shape[0])).reshape(-1, 4)
    out = np.empty((X.shape[0], 4))
    bad = (_cv_rows_from_normals if cv else _full_rows_from_normals)(W, X, F, L, out)
    return out, not bad


def _pcg64_check(cv: bool) -> Callable[[], bool]:
    """The PCG64 route against numpy's ``standard_normal`` and the generic route, on 2,000
    rows (about 100 rejections, a refill inside a row) and a buffered 32-bit half."""

    def check() -> bool:
        ours, ref = np.random.default_rng(2025), np.random.default_rng(2025)
        for g in (ours, ref):
            g.integers(0, 2**32, dtype=np.uint32)
        X = np.linspace(-1.0, 1.0, 8000).reshape(-1, 4)
        F = L = np.eye(4)
        got = _sample_pcg64(X, F, L, cv, ours)
        W = ref.standard_normal((X.shape[0], 4))
        want = np.empty_like(X)
        (_cv_rows_from_normals if cv else _full_rows_from_normals)(W, X, F, L, want)
        same_state = ours.bit_generator.state == ref.bit_generator.state
        return got is not None and np.array_equal(got[0], want) and same_state

    return check


_CHECKS = {cv: _pcg64_check(cv) for cv in (True, False)}


def gaussian_sample(X, F, L, cv, rng):
    """``(X F^T + W L^T, finite)`` for 4-D states X ``(N, 4)``, F and L ``(4, 4)``, W the
    ``(N, 4)`` normals of ``rng.standard_normal((N, 4))`` (drawn row by row, the same bits, and
    the generator left where that call leaves it: module ``pcg64`` for ``default_rng``'s
    generators, numba's generator support for others). ``cv``: F and L have the zeros of two
    constant-velocity axes (``models.ncv.has_cv_zeros``) and only the non-zero terms are
    summed, as ``models.ncv.cv_rows`` does; else the full sums of ``rows_times``.

    finite is False when X may hold a NaN or an infinity (:func:`_finiteness`: the caller
    then checks X, raising as the reference's ``check_state`` does; the draws are spent by
    then)."""
    name = "cv_rows" if cv else "full_rows"
    if pcg64_route(rng, name, _CHECKS[cv]):
        result = _sample_pcg64(X, F, L, cv, rng)
        if result is not None:
            return result
    return _sample_generic(X, F, L, cv, rng)


@njit(cache=True, error_model="numpy")
def bearing_sines(pv, sx, sy, cz, sz):  # pragma: no cover - compiled
    """First pass of the bearing likelihood for the particles' pv ``(N, 4)``, a sensor at
    ``(sx, sy)`` and a measured bearing zb given as ``cz = cos zb``, ``sz = sin zb``:
    ``(s, behind, r)``, each ``(N,)``.

    s = min(|dx sin zb - dy cos zb| / r, 1) = |sin e| for the residual e = zb - atan2(dy, dx);
    behind: dx cos zb + dy sin zb < 0 (cos e < 0, so |e| = pi - arcsin s); r the range.
    """
    N = pv.shape[0]
    flat = pv.reshape(pv.size)  # one loop on the flat rows: no stride product per particle
    s = np.empty(N)
    behind = np.empty(N, dtype=np.bool_)
    r = np.empty(N)
    for i in range(N):
        dx, dy = flat[4 * i] - sx, flat[4 * i + 2] - sy
        ri = math.sqrt(dx * dx + dy * dy)
        a = abs(dx * sz - dy * cz) / ri
        if a > 1.0:  # NaN (a particle on the sensor) stays NaN, as with np.minimum
            a = 1.0
        s[i] = a
        behind[i] = dx * cz + dy * sz < 0.0
        r[i] = ri
    return s, behind, r


@njit(cache=True, error_model="numpy")
def bearing_finish(a, behind, r, coef, gate, r_min, r_max):  # pragma: no cover - compiled
    """In place: a = coef * |e|^2 from a = arcsin(s) of :func:`bearing_sines`
    (|e| = pi - a where behind), -inf outside [r_min, r_max] when ``gate``."""
    for i in range(a.shape[0]):
        e = math.pi - a[i] if behind[i] else a[i]
        v = e * e
        v *= coef
        if gate and not (r[i] >= r_min and r[i] <= r_max):
            v = -math.inf
        a[i] = v
    return a


@njit(cache=True, error_model="numpy")
def range_bearing_finish(
    a, behind, r, zr, sigma_r, sigma_b, gate, r_min, r_max
):  # pragma: no cover - compiled
    """In place: a = -0.5 ((|e| / sigma_b)^2 + ((zr - r) / sigma_r)^2) from a = arcsin(s) of
    :func:`bearing_sines`, -inf outside [r_min, r_max] when ``gate``."""
    for i in range(a.shape[0]):
        e = math.pi - a[i] if behind[i] else a[i]
        e /= sigma_b
        e_r = (zr - r[i]) / sigma_r
        v = -0.5 * (e * e + e_r * e_r)
        if gate and not (r[i] >= r_min and r[i] <= r_max):
            v = -math.inf
        a[i] = v
    return a


@njit(cache=True, error_model="numpy")
def _first_copies(w, u):  # pragma: no cover - compiled
    """``first`` ``(N + 1,)``: first[k] is the particle whose copies start at output k (0
    where none starts), so the running maximum of first[:k + 1] is the particle of output k.

    Particle i gets the outputs b_{i-1} <= k < b_i with b_i = min(ceil(N c_i - u), N) and
    b_{N-1} = N (the rule and the arithmetic of ``filters.resampling.systematic_indices``).
    Of the particles whose copies would start at the same k, all but the last get none, and
    the last one written there wins: the loop has no branch on the counts.
    """
    n = w.shape[0]
    first = np.zeros(n + 1, dtype=np.intp)
    c = 0.0
    start = 0
    for i in range(n - 1):
        c += w[i]
        first[start] = i
        start = min(math.ceil(c * n - u), n)
    first[start] = n - 1
    return first


@njit(cache=True, error_model="numpy")
def systematic_indices(w, u):  # pragma: no cover - compiled
    """Systematic resampling indices ``(N,)`` (sorted) for normalised weights ``w`` and the
    offset ``u`` in [0, 1): those of ``filters.resampling.systematic_indices``."""
    n = w.shape[0]
    first = _first_copies(w, u)
    idx = np.empty(n, dtype=np.intp)
    cur = 0
    for k in range(n):
        cur = max(cur, first[k])
        idx[k] = cur
    return idx


@njit(cache=True, error_model="numpy")
def systematic_resample_rows(X, w, u):  # pragma: no cover - compiled
    """X[systematic_indices(w, u)] for particles X ``(N, d)``, as a new array, copied in the
    same pass that finds the indices."""
    n, d = X.shape
    first = _first_copies(w, u)
    out = np.empty((n, d))
    cur = 0
    if d == 4:  # the pv states: one row of four registers per output
        for k in range(n):
            cur = max(cur, first[k])
            out[k, 0], out[k, 1], out[k, 2], out[k, 3] = X[cur, 0], X[cur, 1], X[cur, 2], X[cur, 3]
        return out
    for k in range(n):
        cur = max(cur, first[k])
        for j in range(d):
            out[k, j] = X[cur, j]
    return out


def warm_up() -> None:
    """Compile (or load from the disk cache) every kernel for the argument types the core
    passes: float64 arrays, a PCG64 generator."""
    rng = np.random.default_rng(0)
    X = np.zeros((2, 4))
    X[:, 0] = 1.0
    eye = np.eye(4)
    eye.flags.writeable = False  # the models pass their cached, read-only F and L
    for cv in (False, True):
        gaussian_sample(X, eye, eye, cv, rng)
        gaussian_sample(X, eye, eye, cv, np.random.Generator(np.random.MT19937(0)))
    s, behind, r = bearing_sines(X, 0.0, 0.0, 0.5, 0.5)
    a = np.arcsin(s)
    bearing_finish(a.copy(), behind, r, -0.5, False, 0.0, math.inf)
    range_bearing_finish(a, behind, r, 1.0, 1.0, 1.0, False, 0.0, math.inf)
    w = np.full(2, 0.5)
    systematic_indices(w, 0.5)
    systematic_resample_rows(X, w, 0.5)
