"""numba kernels of the particle filter step, each equal to a numpy reference in the core.

Each kernel does the arithmetic of its reference in the same order and draws the same random
numbers from the same ``numpy.random.Generator`` (numba runs numpy's own normal sampler on the
generator's bit stream), so the compiled and the numpy paths give the same particles up to
floating-point round-off (tests/core/test_pf_kernels.py):

- :func:`linear_gaussian_sample`: f(x) + w = x F^T + w L^T, w ~ N(0, I) drawn row by row, the
  sampling of a linear motion model (reference ``models._common.add_gaussian_noise`` after
  ``propagate``), without the ``(N, n)`` array of normals; :func:`cv_gaussian_sample` is the
  same for the zero pattern of the NCV models' F and L, summing the non-zero terms only;
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
(``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "bearing_finish",
    "bearing_sines",
    "cv_gaussian_sample",
    "linear_gaussian_sample",
    "range_bearing_finish",
    "systematic_indices",
    "systematic_resample_rows",
    "warm_up",
]


@njit(cache=True, error_model="numpy")
def linear_gaussian_sample(X, F, L, rng):  # pragma: no cover - compiled
    """``(X F^T + W L^T, finite)`` for 4-D states: W ``(N, 4)`` standard normals drawn row by
    row from ``rng`` (the order of ``rng.standard_normal((N, 4))``). X ``(N, 4)``, F and L
    ``(4, 4)``.

    finite is False when X holds a NaN or an infinity (the caller then raises as the
    reference's ``check_state`` does; the draws are spent by then). The draws come first, into
    the output, and the products in a second loop that holds F and L in registers.
    """
    N = X.shape[0]
    out = np.empty((N, 4))
    for i in range(N):
        for k in range(4):
            out[i, k] = rng.standard_normal()
    f00, f01, f02, f03 = F[0, 0], F[0, 1], F[0, 2], F[0, 3]
    f10, f11, f12, f13 = F[1, 0], F[1, 1], F[1, 2], F[1, 3]
    f20, f21, f22, f23 = F[2, 0], F[2, 1], F[2, 2], F[2, 3]
    f30, f31, f32, f33 = F[3, 0], F[3, 1], F[3, 2], F[3, 3]
    l00, l01, l02, l03 = L[0, 0], L[0, 1], L[0, 2], L[0, 3]
    l10, l11, l12, l13 = L[1, 0], L[1, 1], L[1, 2], L[1, 3]
    l20, l21, l22, l23 = L[2, 0], L[2, 1], L[2, 2], L[2, 3]
    l30, l31, l32, l33 = L[3, 0], L[3, 1], L[3, 2], L[3, 3]
    bad = False
    for i in range(N):
        x0, x1, x2, x3 = X[i, 0], X[i, 1], X[i, 2], X[i, 3]
        w0, w1, w2, w3 = out[i, 0], out[i, 1], out[i, 2], out[i, 3]
        out[i, 0] = (x0 * f00 + x1 * f01 + x2 * f02 + x3 * f03) + (
            w0 * l00 + w1 * l01 + w2 * l02 + w3 * l03
        )
        out[i, 1] = (x0 * f10 + x1 * f11 + x2 * f12 + x3 * f13) + (
            w0 * l10 + w1 * l11 + w2 * l12 + w3 * l13
        )
        out[i, 2] = (x0 * f20 + x1 * f21 + x2 * f22 + x3 * f23) + (
            w0 * l20 + w1 * l21 + w2 * l22 + w3 * l23
        )
        out[i, 3] = (x0 * f30 + x1 * f31 + x2 * f32 + x3 * f33) + (
            w0 * l30 + w1 * l31 + w2 * l32 + w3 * l33
        )
        bad |= x0 * 0.0 + x1 * 0.0 + x2 * 0.0 + x3 * 0.0 != 0.0  # NaN for a non-finite x
    return out, not bad


@njit(cache=True, error_model="numpy")
def cv_gaussian_sample(X, F, L, rng):  # pragma: no cover - compiled
    """:func:`linear_gaussian_sample` for F and L with the zeros of two independent
    constant-velocity axes (x, xdot) and (y, ydot): F upper and L lower triangular within each
    2 x 2 block, zero outside the blocks (the NCV models; ``models.ncv.has_cv_zeros``). Only
    the non-zero terms are summed, with the operations of ``models.ncv.cv_rows`` (its numpy
    reference); the full sums of :func:`linear_gaussian_sample` differ at most in the sign of
    an exact zero."""
    N = X.shape[0]
    out = np.empty((N, 4))
    for i in range(N):
        for k in range(4):
            out[i, k] = rng.standard_normal()
    f00, f01, f11, f22, f23, f33 = F[0, 0], F[0, 1], F[1, 1], F[2, 2], F[2, 3], F[3, 3]
    l00, l10, l11, l22, l32, l33 = L[0, 0], L[1, 0], L[1, 1], L[2, 2], L[3, 2], L[3, 3]
    bad = False
    for i in range(N):
        x0, x1, x2, x3 = X[i, 0], X[i, 1], X[i, 2], X[i, 3]
        w0, w1, w2, w3 = out[i, 0], out[i, 1], out[i, 2], out[i, 3]
        out[i, 0] = (x0 * f00 + x1 * f01) + w0 * l00
        out[i, 1] = x1 * f11 + (w0 * l10 + w1 * l11)
        out[i, 2] = (x2 * f22 + x3 * f23) + w2 * l22
        out[i, 3] = x3 * f33 + (w2 * l32 + w3 * l33)
        bad |= x0 * 0.0 + x1 * 0.0 + x2 * 0.0 + x3 * 0.0 != 0.0  # NaN for a non-finite x
    return out, not bad


@njit(cache=True, error_model="numpy")
def bearing_sines(pv, sx, sy, cz, sz):  # pragma: no cover - compiled
    """First pass of the bearing likelihood for the particles' pv ``(N, 4)``, a sensor at
    ``(sx, sy)`` and a measured bearing zb given as ``cz = cos zb``, ``sz = sin zb``:
    ``(s, behind, r)``, each ``(N,)``.

    s = min(|dx sin zb - dy cos zb| / r, 1) = |sin e| for the residual e = zb - atan2(dy, dx);
    behind: dx cos zb + dy sin zb < 0 (cos e < 0, so |e| = pi - arcsin s); r the range.
    """
    N = pv.shape[0]
    s = np.empty(N)
    behind = np.empty(N, dtype=np.bool_)
    r = np.empty(N)
    for i in range(N):
        dx = pv[i, 0] - sx
        dy = pv[i, 2] - sy
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
    linear_gaussian_sample(X, eye, eye, rng)
    cv_gaussian_sample(X, eye, eye, rng)
    s, behind, r = bearing_sines(X, 0.0, 0.0, 0.5, 0.5)
    a = np.arcsin(s)
    bearing_finish(a.copy(), behind, r, -0.5, False, 0.0, math.inf)
    range_bearing_finish(a, behind, r, 1.0, 1.0, 1.0, False, 0.0, math.inf)
    w = np.full(2, 0.5)
    systematic_indices(w, 0.5)
    systematic_resample_rows(X, w, 0.5)
