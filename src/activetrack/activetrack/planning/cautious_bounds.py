"""Time bounds of the beta-cautious strategy (Vander Hook, Tokekar, Isler (003), sec. IV), in
metres and seconds at the paper's robot speed of 1 m/s; ``sigma_s`` in radians. Lemma 4, 5
(eq. 4), Theorem 1 (eq. 5) and 2 (eq. 6) as printed, and :func:`cautious_schedule`, which sums
Lemma 5's argument term by term: eq. 4's closed form drops the first term of the geometric
series and is not a bound for large gamma.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.checks import (
    require_finite,
    require_in_range,
    require_nonnegative,
    require_positive,
)
from activetrack.planning.cautious import caution_gamma

__all__ = [
    "CautiousSchedule",
    "alternating_measurements",
    "cautious_schedule",
    "distance_bound",
    "lemma4_measurements",
    "measurement_bound",
    "time_lower_bound",
    "time_upper_bound",
]


def _c_d(c_d: float) -> float:
    return require_in_range("c_d", c_d, 0.0, 1.0, lo_inclusive=False, hi_inclusive=False)


def lemma4_measurements(beta: float, sigma_s: float, c_d: float, tail: str = "two_sided") -> int:
    """N_z = ceil(4 log_gamma(1 / c_d)), gamma = sigma_beta^2 / sigma_s^2 (Lemma 4)."""
    gamma = caution_gamma(beta, sigma_s, tail)
    return math.ceil(4.0 * math.log(1.0 / _c_d(c_d)) / math.log(gamma) - 1e-12)


def alternating_measurements(
    beta: float, sigma_s: float, c_d: float, tail: str = "two_sided"
) -> int:
    """Measurements Algorithm 1 takes from a circular prior: 2 ceil(2 log_gamma(1 / c_d)).

    Each step divides the major variance by gamma (eq. 1 with line 6) and the axes alternate,
    so each axis needs ceil(log_gamma(1 / c_d^2)) steps. Lemma 4 rounds 4 log_gamma(1 / c_d)
    up once for both axes: one short when the fractional part of 2 log_gamma(1 / c_d) exceeds
    1/2 (c_d = 0.25, beta = 0.1, sigma_s = 15 deg: N_z = 3 but 4 are needed).
    """
    gamma = caution_gamma(beta, sigma_s, tail)
    return 2 * math.ceil(2.0 * math.log(1.0 / _c_d(c_d)) / math.log(gamma) - 1e-12)


def measurement_bound(beta: float, sigma_s: float, c_d: float, tail: str = "two_sided") -> int:
    """N_z used in the time bound: the larger of Lemma 4 and the exact alternating count."""
    return max(
        lemma4_measurements(beta, sigma_s, c_d, tail),
        alternating_measurements(beta, sigma_s, c_d, tail),
    )


def distance_bound(
    sigma0: float,
    beta: float,
    sigma_s: float,
    c_d: float,
    d01: ArrayLike,
    tail: str = "two_sided",
) -> np.ndarray:
    """D_A, Lemma 5 eq. 4, for a circular prior with standard deviation sigma0 (m):

    D_A = d(s0, s1) + 2 sigma0 (1 - c_d) / (sqrt(gamma) - 1)
                      * (sqrt(2) + pi (gamma - 1) / gamma) / (sigma_s sqrt(gamma - 1)).

    d01: distance from the start to the first sensing location (m), scalar or array.
    """
    sigma0 = require_positive("sigma0", sigma0)
    c_d = _c_d(c_d)
    d01 = require_finite("d01", d01)
    if np.any(d01 < 0.0):
        raise ValueError("d01 must be >= 0")
    gamma = caution_gamma(beta, sigma_s, tail)
    g = math.sqrt(gamma)
    shape = (math.sqrt(2.0) + math.pi * (gamma - 1.0) / gamma) / (
        float(sigma_s) * math.sqrt(gamma - 1.0)
    )
    return d01 + 2.0 * sigma0 * (1.0 - c_d) / (g - 1.0) * shape


def time_upper_bound(n_measurements: float, t_m: float, D_A: ArrayLike) -> np.ndarray:
    """T_ALG <= N_z t_m + D_A (Theorem 1, eq. 5), seconds at 1 m/s."""
    n = require_nonnegative("n_measurements", n_measurements)
    t_m = require_nonnegative("t_m", t_m)
    return n * t_m + require_finite("D_A", D_A)


def time_lower_bound(
    r0_true: ArrayLike, sigma_max: float, t_m: float, c_d: float, sigma_s: float
) -> np.ndarray:
    """T_LB = max(r0* - sigma_max^2 / (2 t_m (1/c^2 - 1) sigma_s^2) + t_m, t_m) (Theorem 2,
    eq. 6), ``r0_true``'s shape: r0* the range from the start to the true target, sigma_max
    the larger prior standard deviation (m). The subtracted term is the range at which
    repeated measurements from one point (Lemma 7) trade travel against dwell optimally."""
    r0 = require_finite("r0_true", r0_true)
    if np.any(r0 < 0.0):
        raise ValueError("r0_true must be >= 0")
    sigma_max = require_positive("sigma_max", sigma_max)
    t_m = require_positive("t_m", t_m)
    c_d = _c_d(c_d)
    sigma_s = require_positive("sigma_s", sigma_s)
    standoff = sigma_max**2 / (2.0 * t_m * (1.0 / c_d**2 - 1.0) * sigma_s**2)
    return np.maximum(r0 - standoff + t_m, t_m)


@dataclass(frozen=True)
class CautiousSchedule:
    """Algorithm 1 run on the covariance alone: ranges r_i (N,), major_std sigma_{i-1}(1)
    before step i (N,), shift_bound (N,) Lemma 3's bound on ||x_i - x_{i-1}|| (m), final
    variances (2,) (m^2)."""

    ranges: np.ndarray
    major_std: np.ndarray
    shift_bound: np.ndarray
    variances: np.ndarray

    @property
    def n_measurements(self) -> int:
        return len(self.ranges)

    def travel_bound(self, d01: ArrayLike) -> np.ndarray:
        """D <= d(s0, s1) + sum_{i=1}^{N-1} (sqrt(r_i^2 + r_{i+1}^2) + shift_i) (m), Lemma 5's
        argument term by term: s_{i+1} lies on the axis perpendicular to s_i's line of sight
        through x_i (Lemma 1), which moved by at most shift_i (Lemma 3). d01 scalar or array."""
        d01 = require_finite("d01", d01)
        r = self.ranges
        legs = np.sqrt(r[:-1] ** 2 + r[1:] ** 2) + self.shift_bound[:-1]
        return d01 + float(np.sum(legs))


def cautious_schedule(
    P0: ArrayLike,
    beta: float,
    sigma_s: float,
    c_d: float,
    tail: str = "two_sided",
    r_min: float = 0.0,
    max_measurements: int = 1000,
) -> CautiousSchedule:
    """Ranges and covariances of Algorithm 1 from the prior P0 (2, 2) (eq. 1, 3, Lemma 1-3):
    each step measures from r_i = max(sqrt(sigma^2(1) / (sigma_beta^2 - sigma_s^2)), r_min) at
    alpha = pi/2, shrinking only the major variance (Lemma 1): 1/sigma'^2 = 1/sigma^2 +
    1/(r_i^2 sigma_s^2) (eq. 1); the estimate shifts by at most pi sigma^2 / (sigma^2 / r_i +
    r_i sigma_s^2) (Lemma 3)."""
    P0 = np.asarray(P0, dtype=float)
    var = np.sort(np.linalg.eigvalsh(P0))[::-1].copy()
    if P0.shape != (2, 2) or not np.all(var > 0.0):
        raise ValueError("P0 must be a (2, 2) symmetric positive definite matrix")
    c_d = _c_d(c_d)
    gamma = caution_gamma(beta, sigma_s, tail)
    r_min = require_nonnegative("r_min", r_min)
    if math.isinf(gamma) and r_min == 0.0:
        raise ValueError("r_min must be > 0 when sigma_beta is infinite")
    s2 = float(sigma_s) ** 2
    target = c_d**2 * var
    ranges: list[float] = []
    major: list[float] = []
    shifts: list[float] = []
    # The two entries keep their axis; the larger one is reduced at every step.
    while not np.all(var < target):
        if len(ranges) >= max_measurements:
            raise ValueError(f"max_measurements={max_measurements} reached before c_d={c_d}")
        j = int(np.argmax(var))
        v = var[j]
        r = max(math.sqrt(v / (s2 * (gamma - 1.0))), r_min)
        ranges.append(r)
        major.append(math.sqrt(v))
        shifts.append(math.pi * v / (v / r + r * s2))
        var[j] = 1.0 / (1.0 / v + 1.0 / (r * r * s2))
    return CautiousSchedule(
        ranges=np.array(ranges),
        major_std=np.array(major),
        shift_bound=np.array(shifts),
        variances=np.sort(var)[::-1],
    )
