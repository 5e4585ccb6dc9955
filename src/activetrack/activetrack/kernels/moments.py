"""numba kernel of the particle filter's estimate: the weighted mean and covariance of the
particles (``ParticleFilter.mean`` / ``.cov``) in two passes with the sums in registers.

The numpy version makes two particle-sized temporaries (``X - mean`` and its weighted copy)
and sums with BLAS; besides its own time (about 3x this kernel's for 10,000 particles), the
temporaries push the particles out of the cache before the next step. The sums run in
particle order here, so the results agree with numpy's to round-off (tested to 1e-12), not to
the bit: like the EKF kernels, this one runs only with ``ACTIVETRACK_KERNELS=compiled``. The
particles and weights themselves never depend on it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["warm_up", "weighted_moments4"]


@njit(cache=True, error_model="numpy")
def weighted_moments4(X, w):  # pragma: no cover - compiled
    """``(mean, cov)`` of 4-D particles X ``(N, 4)`` with normalised weights w ``(N,)``:
    mean = sum w_i x_i, cov = sum w_i (x_i - mean)(x_i - mean)^T (exactly symmetric)."""
    N = X.shape[0]
    m0 = m1 = m2 = m3 = 0.0
    for i in range(N):
        wi = w[i]
        m0 += wi * X[i, 0]
        m1 += wi * X[i, 1]
        m2 += wi * X[i, 2]
        m3 += wi * X[i, 3]
    p00 = p01 = p02 = p03 = p11 = p12 = p13 = p22 = p23 = p33 = 0.0
    for i in range(N):
        wi = w[i]
        d0, d1, d2, d3 = X[i, 0] - m0, X[i, 1] - m1, X[i, 2] - m2, X[i, 3] - m3
        a0, a1, a2, a3 = wi * d0, wi * d1, wi * d2, wi * d3
        p00 += a0 * d0
        p01 += a0 * d1
        p02 += a0 * d2
        p03 += a0 * d3
        p11 += a1 * d1
        p12 += a1 * d2
        p13 += a1 * d3
        p22 += a2 * d2
        p23 += a2 * d3
        p33 += a3 * d3
    mean = np.array([m0, m1, m2, m3])
    cov = np.array(
        [
            [p00, p01, p02, p03],
            [p01, p11, p12, p13],
            [p02, p12, p22, p23],
            [p03, p13, p23, p33],
        ]
    )
    return mean, cov


def warm_up() -> None:
    """Compile (or load from the disk cache) the kernel for writable and read-only weights
    (the filter's uniform weights after resampling are read-only)."""
    X = np.zeros((2, 4))
    w = np.full(2, 0.5)
    weighted_moments4(X, w)
    w.flags.writeable = False
    weighted_moments4(X, w)
