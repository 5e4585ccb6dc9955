"""Small distribution helpers shared by the gating and the bounds.

scipy.special is imported on first use, not with the module: importing it adds process-wide
warning filters, and importing the core changes no process-wide setting
(tests/core/test_allocator.py).
"""

from __future__ import annotations

__all__ = ["chi2_cdf", "t_quantile"]


def chi2_cdf(x: float, dof: float) -> float:
    """P(X <= x) for X ~ chi-square with ``dof`` degrees of freedom: the regularised lower
    incomplete gamma function P(dof / 2, x / 2)."""
    from scipy.special import gammainc

    return float(gammainc(0.5 * dof, 0.5 * x))


def t_quantile(q: float, dof: float) -> float:
    """The q quantile of Student's t with ``dof`` degrees of freedom."""
    from scipy.special import stdtrit

    return float(stdtrit(dof, q))
