"""Small distribution helpers shared by the gating, the bounds and the particle filters.

scipy.special is imported on first use, not with the module: importing it adds process-wide
warning filters, and importing the core changes no process-wide setting
(tests/core/test_allocator.py).
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import FloatArray

__all__ = ["chi2_cdf", "chi2_quantile", "log_sum_exp", "t_quantile"]


def chi2_cdf(x: float, dof: float) -> float:
    """P(X <= x) for X ~ chi-square with ``dof`` degrees of freedom: the regularised lower
    incomplete gamma function P(dof / 2, x / 2)."""
    from scipy.special import gammainc

    return float(gammainc(0.5 * dof, 0.5 * x))


def chi2_quantile(q: float, dof: float) -> float:
    """The q quantile of chi-square with ``dof`` degrees of freedom: 2 P^-1(dof / 2, q), the
    inverse of :func:`chi2_cdf`."""
    from scipy.special import gammaincinv

    return float(2.0 * gammaincinv(0.5 * dof, q))


def t_quantile(q: float, dof: float) -> float:
    """The q quantile of Student's t with ``dof`` degrees of freedom."""
    from scipy.special import stdtrit

    return float(stdtrit(dof, q))


def log_sum_exp(a: FloatArray, axis: int = -1) -> FloatArray:
    """``log sum exp(a)`` along ``axis``, shifted by the maximum (the largest term neither
    overflows nor underflows); ``-inf`` where every entry is ``-inf``."""
    top = np.max(a, axis=axis, keepdims=True)
    shift = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - shift), axis=axis, keepdims=True)) + shift
    return np.asarray(np.squeeze(out, axis=axis), dtype=float)
