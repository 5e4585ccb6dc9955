"""Multi-target evaluation metrics: OSPA and GOSPA between finite sets of points.

Both metrics compare a set of true target states ``X`` (shape (m, d)) with a set of estimated
states ``Y`` (shape (n, d)); either set may be empty (m = 0 or n = 0).  Points are compared with
the Euclidean distance cut off at ``c``,

    d^(c)(x, y) = min(c, ||x - y||),

and the best pairing of the two sets is found with the Hungarian algorithm
(``scipy.optimize.linear_sum_assignment``) on the matrix of d^(c)(x_i, y_j)^p.

References. OSPA: D. Schuhmacher, B.-T. Vo and B.-N. Vo, "A consistent metric for performance
evaluation of multi-object filters", IEEE Trans. Signal Processing 56(8), 2008, eq. (3).
GOSPA: A. S. Rahmathullah, A. F. Garcia-Fernandez and L. Svensson, "Generalized optimal
sub-pattern assignment metric", FUSION 2017, Definition 1 (eq. (1)) and, for alpha = 2,
Proposition 1 (eq. (2)): the localisation error plus c^p / 2 per missed and per false target.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite, require_in_range, require_positive

__all__ = [
    "GospaResult",
    "GospaWeights",
    "beyond_cutoff",
    "expected_localisation",
    "gospa",
    "gospa_over_time",
    "gospa_reported",
    "ospa",
    "ospa_over_time",
    "position_spread",
]


@dataclass(frozen=True)
class GospaResult:
    """GOSPA distance of one epoch and its decomposition,
    ``distance**p == localisation + (c**p / alpha) * (missed + false_tracks)``.

    For alpha = 2 (eq. (2)) only pairs closer than ``c`` are kept; for alpha < 2 (eq. (1)) all
    min(m, n) pairs of the optimal assignment are, and ``missed`` / ``false_tracks`` are the
    cardinality surplus of the truths / the estimates. ``localisation``: sum over
    ``assignment`` (pairs (i, j) of truth row i and estimate row j, sorted by i) of
    d^(c)(x_i, y_j)^p (units to the power p); ``missed`` / ``false_tracks``: the truths /
    estimates not in it.
    """

    distance: float
    localisation: float
    missed: int
    false_tracks: int
    assignment: tuple[tuple[int, int], ...]


def _check_order_cutoff(c: float, p: float) -> tuple[float, float]:
    c = require_positive("c", c)
    p = require_in_range("p", p, 1.0, math.inf, hi_inclusive=False)
    return c, p


def _as_point_set(name: str, points: ArrayLike) -> FloatArray:
    """``points`` as a finite float array of shape (k, d); an empty input may have shape (0,)."""
    arr = require_finite(name, points)
    if arr.size == 0 and arr.ndim <= 1:
        return arr.reshape(0, 0)
    if arr.ndim != 2:
        raise ValueError(
            f"{name} must be a set of points of shape (k, d) (k >= 0 points in R^d), "
            f"got an array of shape {arr.shape}"
        )
    return arr


def _point_sets(X: ArrayLike, Y: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Validated (m, d) and (n, d) arrays; the dimensions must agree unless a set is empty."""
    x = _as_point_set("X", X)
    y = _as_point_set("Y", Y)
    if x.shape[0] and y.shape[0] and x.shape[1] != y.shape[1]:
        raise ValueError(
            f"X and Y must hold points of the same dimension d, got X of shape {x.shape} "
            f"and Y of shape {y.shape}"
        )
    return x, y


def _assign(
    x: FloatArray, y: FloatArray, c: float, p: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Optimal assignment of k = min(m, n) pairs on the cut-off costs d^(c)(x_i, y_j)^p: the
    truth rows (k,), estimate rows (k,) and uncut distances (k,) of the pairs."""
    if x.shape[0] == 0 or y.shape[0] == 0:
        empty = np.zeros(0)
        return empty.astype(np.intp), empty.astype(np.intp), empty
    dist = np.sqrt(np.sum((x[:, None, :] - y[None, :, :]) ** 2, axis=-1))  # (m, n)
    # Imported here: scipy.optimize adds process-wide warning filters on import.
    from scipy.optimize import linear_sum_assignment

    rows, cols = linear_sum_assignment(np.minimum(dist, c) ** p)
    return rows, cols, dist[rows, cols]


def ospa(X: ArrayLike, Y: ArrayLike, c: float, p: float) -> float:
    """OSPA distance of order ``p`` and cut-off ``c`` between two finite point sets.

    Schuhmacher, Vo & Vo (2008), eq. (3): for m = |X| <= n = |Y|,

        d_p^(c)(X, Y) = ( (1/n) * ( min_pi sum_{i=1}^m d^(c)(x_i, y_pi(i))^p
                                    + c^p * (n - m) ) )^(1/p),

    with pi over the injections of {1..m} into {1..n}; symmetric in X and Y, 0 if both sets
    are empty, c if exactly one is (the value lies in [0, c]). ``X`` (m, d), ``Y`` (n, d)
    (an empty set may be ``[]``); cut-off c > 0 (units of the points), order 1 <= p < inf.
    """
    c, p = _check_order_cutoff(c, p)
    x, y = _point_sets(X, Y)
    n = max(x.shape[0], y.shape[0])
    if n == 0:
        return 0.0
    _, _, dist = _assign(x, y, c, p)
    cardinality = c**p * (n - dist.size)
    return float(((np.sum(np.minimum(dist, c) ** p) + cardinality) / n) ** (1.0 / p))


def gospa(X: ArrayLike, Y: ArrayLike, c: float, p: float, alpha: float = 2.0) -> GospaResult:
    """GOSPA distance between true states ``X`` and estimates ``Y``, with its decomposition.

    Rahmathullah, Garcia-Fernandez & Svensson (2017), Definition 1, eq. (1): for
    m = |X| <= n = |Y|,

        d_p^(c, alpha)(X, Y) = ( min_pi sum_{i=1}^m d^(c)(x_i, y_pi(i))^p
                                 + (c^p / alpha) * (n - m) )^(1/p),

    symmetric in X and Y.  For alpha = 2 (the recommended choice) Proposition 1, eq. (2), writes
    it as a minimum over partial assignments gamma of pairs closer than c,

        d_p^(c, 2)(X, Y) = ( sum_{(i, j) in gamma} d(x_i, y_j)^p
                             + (c^p / 2) * (|X| + |Y| - 2 |gamma|) )^(1/p),

    i.e. localisation error plus c^p / 2 per missed target and per false track (the split
    :class:`GospaResult` reports). Unlike OSPA it is not normalised by max(m, n). ``X`` (m, d)
    true states, ``Y`` (n, d) estimates (an empty set may be ``[]``); c and p as for
    :func:`ospa`; 0 < alpha <= 2.
    """
    c, p = _check_order_cutoff(c, p)
    alpha = require_in_range("alpha", alpha, 0.0, 2.0, lo_inclusive=False)
    x, y = _point_sets(X, Y)
    rows, cols, dist = _assign(x, y, c, p)
    if alpha == 2.0:
        keep = dist < c  # pairs at or beyond the cut-off count as one missed + one false
        rows, cols, dist = rows[keep], cols[keep], dist[keep]
    localisation = float(np.sum(np.minimum(dist, c) ** p))
    missed = x.shape[0] - rows.size
    false_tracks = y.shape[0] - cols.size
    total = localisation + c**p / alpha * (missed + false_tracks)
    return GospaResult(
        distance=float(total ** (1.0 / p)),
        localisation=localisation,
        missed=int(missed),
        false_tracks=int(false_tracks),
        assignment=tuple((int(i), int(j)) for i, j in zip(rows, cols, strict=True)),
    )


@dataclass(frozen=True)
class GospaWeights:
    """GOSPA's cut-off ``c`` [m], order ``p`` >= 1 and ``alpha`` in (0, 2] (the scenario's
    ``evaluation``): ``cardinality`` = c^p / alpha, the cost of one missed or false target."""

    c: float
    p: float
    alpha: float

    def __post_init__(self) -> None:
        require_positive("c", self.c)
        require_in_range("p", self.p, 1.0, math.inf, hi_inclusive=False)
        require_in_range("alpha", self.alpha, 0.0, 2.0, lo_inclusive=False)

    @property
    def cardinality(self) -> float:
        return float(self.c**self.p / self.alpha)


def position_spread(P: ArrayLike) -> np.ndarray:
    """m = tr of the xy block of pv covariances ``(..., 4, 4)`` ``(...)`` [m^2]: E[d^2] of the
    position error."""
    P = np.asarray(P, dtype=float)
    return np.maximum(P[..., 0, 0] + P[..., 2, 2], 0.0)


def beyond_cutoff(m: ArrayLike, c: float) -> np.ndarray:
    """P(d > c) = exp(-c^2 / m) ``(...)`` for a position error d whose squared length has mean
    ``m`` (exact for an isotropic 2-D Gaussian error: d^2 / (m / 2) is chi-square with 2
    degrees of freedom, i.e. d^2 is exponential with mean m; m = 0: 0)."""
    m = np.asarray(m, dtype=float)
    with np.errstate(divide="ignore", over="ignore"):
        return np.where(m > 0.0, np.exp(-(c * c) / np.where(m > 0.0, m, 1.0)), 0.0)


def expected_localisation(m: ArrayLike, c: float, p: float) -> np.ndarray:
    """E[min(d, c)^p] ``(...)`` for d^2 exponential with mean ``m`` (:func:`beyond_cutoff`).

    With a = p/2 and u = c^2 / m: E[min(d^2, c^2)^a] = m^a gamma(a + 1, u) + c^p e^{-u}, where
    gamma(a + 1, u) = Gamma(a + 1) P(a + 1, u) is the lower incomplete gamma function (split
    the integral of x^a e^{-x/m} / m at c^2). p = 2: m (1 - e^{-u}). It rises like m^a for a
    track well inside the cut-off and saturates at c^p, GOSPA's cost of a pair at or beyond it
    (eq. 2: one missed and one false target)."""
    from scipy.special import gamma, gammainc

    m = np.asarray(m, dtype=float)
    a = 0.5 * p
    safe = np.where(m > 0.0, m, 1.0)
    u = (c * c) / safe
    if p == 2.0:  # m gamma(2, u) + c^2 e^{-u} = m (1 - e^{-u} (1 + u)) + m u e^{-u}
        value = safe * -np.expm1(-u)
    else:
        value = safe**a * gamma(a + 1.0) * gammainc(a + 1.0, u) + c**p * np.exp(-u)
    return np.where(m > 0.0, value, 0.0)


def gospa_reported(existence: ArrayLike, spread: ArrayLike, weights: GospaWeights) -> np.ndarray:
    """Whether to report each track in the estimate ``(...)`` bool: the choice that lowers its
    expected GOSPA^p. A track with probability of existence ``r`` and position spread ``m``
    [m^2] (:func:`position_spread`) costs, reported, r L + (1 - r) k (held if its target
    exists, L = :func:`expected_localisation`; else one false track, k = c^p / alpha) and,
    left out, r k (one missed target if it exists): report where r (2 k - L) > k, i.e. r > 1/2
    for a well localised track and never where L >= k. The rule of the multi-Bernoulli
    estimators that keep the Bernoulli components with r > 1/2 (Garcia-Fernandez, Williams,
    Granstrom & Svensson, "Poisson multi-Bernoulli mixture filter: direct derivation and
    implementation", IEEE Trans. AES 54(4), 2018, sec. VI, estimator 1), with the threshold
    from c, p and alpha and the track's spread."""
    r = np.asarray(existence, dtype=float)
    k = weights.cardinality
    L = expected_localisation(spread, weights.c, weights.p)
    return np.asarray(r * (2.0 * k - L) > k)


def _check_series(truths: Sequence[ArrayLike], estimates: Sequence[ArrayLike]) -> int:
    if len(truths) != len(estimates):
        raise ValueError(
            f"truths and estimates must hold one point set per epoch each (same length K), "
            f"got {len(truths)} truths and {len(estimates)} estimates"
        )
    return len(truths)


def ospa_over_time(
    truths: Sequence[ArrayLike], estimates: Sequence[ArrayLike], c: float, p: float
) -> FloatArray:
    """:func:`ospa` at each of K epochs ``(K,)``: ``truths[k]`` (m_k, d), ``estimates[k]``
    (n_k, d)."""
    K = _check_series(truths, estimates)
    return np.array([ospa(truths[k], estimates[k], c, p) for k in range(K)], dtype=float)


def gospa_over_time(
    truths: Sequence[ArrayLike],
    estimates: Sequence[ArrayLike],
    c: float,
    p: float,
    alpha: float = 2.0,
) -> FloatArray:
    """:func:`gospa`'s distance at each of K epochs ``(K,)`` (its split: :func:`gospa`)."""
    K = _check_series(truths, estimates)
    return np.array(
        [gospa(truths[k], estimates[k], c, p, alpha).distance for k in range(K)], dtype=float
    )
