"""Sensor-to-track assignment of steerable beams (one track per beam and epoch).

Given per-pair costs ``C[s, t]`` (track t's cost if sensor s serves it) and ``c0[t]`` (no
beam), one *round* gives each track at most one sensor, exactly:

- ``"weighted_sum"``: the linear assignment of the gains ``w_t (C[s, t] - c0[t])`` (a track
  without a beam keeps its cost), ``scipy.optimize.linear_sum_assignment``;
- ``"worst"``: the smallest threshold theta (one of the costs, binary search) for which every
  track with ``c0[t] > theta`` gets its own sensor with ``C[s, t] <= theta`` (a bipartite
  matching); among those assignments, the largest summed gain.

More sensors than tracks: rounds, each taking in the previous rounds' expected updates (greedy
over rounds, not jointly optimal). Pair costs (:func:`mre_pair_costs`): the criterion of
Ramdaras eq. 23 with the sensor's expected update, so ``C <= c0`` (round-off clipped); or
(:func:`gospa_pair_costs`, :func:`assign_beams_gospa`) the track's expected GOSPA^p at the
next epoch (:mod:`activetrack.planning.expected_gospa`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.arraytypes import ArrayLike
from activetrack.bounds.mre import mre_update
from activetrack.checks import require_in_range
from activetrack.models.fov import sector_coverage
from activetrack.planning.criteria import POSITIONING, SELECTION, get_criterion
from activetrack.planning.expected_gospa import (
    GospaWeights,
    hit_probability,
    managed_split,
    position_spread,
)
from activetrack.planning.objective import aggregate_costs, check_aggregate
from activetrack.planning.selection import TargetPrediction

if TYPE_CHECKING:
    from activetrack.models.base import SensorModel
    from activetrack.models.clutter import ClutteredSensor

__all__ = [
    "NO_MISSES",
    "MissedLooks",
    "assign_beams",
    "assign_beams_gospa",
    "assignment_value",
    "beam_candidates",
    "beam_coverage",
    "coverage_after_misses",
    "footprint_pointing",
    "gospa_pair_costs",
    "joint_coverage",
    "mre_pair_costs",
    "nearest_assignment",
    "random_assignment",
    "round_assignment",
    "search_columns",
]


def _linear_sum_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """scipy's (rows, cols), imported here: importing scipy.optimize installs warning filters."""
    from scipy.optimize import linear_sum_assignment as lsa

    rows, cols = lsa(cost)
    return np.asarray(rows), np.asarray(cols)


def beam_coverage(
    beam_width: float, x: np.ndarray, P: np.ndarray, sensor_pv: np.ndarray
) -> np.ndarray:
    """Probability ``(...)`` that a target N(x, P) (``(4,)``, ``(..., 4, 4)``) lies inside a
    beam ``beam_width`` wide pointed at x from sensor pvs ``(..., 4)``: erf(w / (2 sqrt(2)
    sigma_b)), :func:`sector_coverage` centred on x."""
    return sector_coverage(beam_width, 0.0, x, P, sensor_pv)


def coverage_after_misses(
    coverage: ArrayLike,
    miss_factor: ArrayLike,
    coverage_then: ArrayLike | None = None,
    rho: ArrayLike = 1.0,
) -> np.ndarray:
    """c' = (c - (1 - M) J) / (1 - (1 - M) c_then), M = prod over the looks of (1 - pd_look):
    the probability that the target lies in the beam after unsuccessful looks (Bayes' rule:
    Stone, *Theory of Optimal Search*, 1975; the IPDA existence update has the same form), J
    the chance that it was in the looks' beam (coverage ``coverage_then``, None: ``coverage``)
    and is in this one, :func:`joint_coverage` with correlation ``rho``. The same beam (rho =
    1, c_then = c): c' = c M / (c M + 1 - c); rho = 0: c (the looks say nothing about where
    the target is now). All arguments broadcast, in [0, 1]; without it the beams keep looking
    at a lost track's empty prediction (the tracker does not move a track away from where a
    beam saw nothing)."""
    c = np.asarray(coverage, dtype=float)
    M = np.asarray(miss_factor, dtype=float)
    if not (np.all((c >= 0.0) & (c <= 1.0)) and np.all((M >= 0.0) & (M <= 1.0))):
        raise ValueError(f"coverage and miss_factor must lie in [0, 1], got {c}, {M}")
    if coverage_then is None:
        num = c * M
        den = num + (1.0 - c)
    else:
        c1 = np.asarray(coverage_then, dtype=float)
        num = c - (1.0 - M) * joint_coverage(c1, c, rho)
        den = 1.0 - (1.0 - M) * c1
    out = np.divide(num, den, out=np.zeros(np.broadcast(num, den).shape), where=den > 0.0)
    return np.clip(out, 0.0, 1.0)


def joint_coverage(coverage_then: ArrayLike, coverage: ArrayLike, rho: ArrayLike) -> np.ndarray:
    """P(|U| < t1, |V| < t2) ``(...)`` for standard normal U, V of correlation ``rho`` in
    [0, 1], t1 and t2 the half-widths whose intervals hold ``coverage_then`` and ``coverage``
    (c = erf(t / sqrt 2)): the chance that a target was inside a beam then and is inside a beam
    now, each pointed at the track's prediction, its offsets from those a random walk (the
    rectangle of the bivariate normal, Owen 1956: Phi_2(h, k; rho) = (Phi(h) + Phi(k)) / 2 -
    T(h, a_h) - T(k, a_k) - beta, a_h = (k - rho h) / (h sqrt(1 - rho^2)), beta = 1/2 if
    hk < 0). rho = 1: min(c_then, c)."""
    from scipy.special import erfinv, ndtr, owens_t

    arrays = (np.asarray(a, dtype=float) for a in (coverage_then, coverage, rho))
    c1, c2, r = np.broadcast_arrays(*arrays)
    if not (np.all((c1 >= 0) & (c1 <= 1)) and np.all((c2 >= 0) & (c2 <= 1))):
        raise ValueError(f"coverage_then and coverage must lie in [0, 1], got {c1}, {c2}")
    if not np.all((r >= 0.0) & (r <= 1.0)):
        raise ValueError(f"rho must lie in [0, 1], got {r}")
    edge = (c1 <= 0) | (c2 <= 0) | (c1 >= 1) | (c2 >= 1) | (r >= 1.0 - 1e-12)
    t1 = math.sqrt(2.0) * erfinv(np.where(edge, 0.5, c1))
    t2 = math.sqrt(2.0) * erfinv(np.where(edge, 0.5, c2))
    s = np.sqrt(np.where(edge, 0.75, 1.0 - r * r))

    def phi2(h: np.ndarray, k: np.ndarray) -> np.ndarray:
        beta = np.where(h * k < 0.0, 0.5, 0.0)
        a_h, a_k = (k - r * h) / (h * s), (h - r * k) / (k * s)
        return 0.5 * (ndtr(h) + ndtr(k)) - owens_t(h, a_h) - owens_t(k, a_k) - beta

    box = phi2(t1, t2) - phi2(-t1, t2) - phi2(t1, -t2) + phi2(-t1, -t2)
    return np.where(edge, np.minimum(c1, c2), np.clip(box, 0.0, np.minimum(c1, c2)))


@dataclass(frozen=True)
class MissedLooks:
    """The unsuccessful beam looks at a track since its last hit: ``factor`` M = prod over
    them of (1 - pd I_r), and the last one's coverage of the track's prediction (before the
    misses) ``coverage`` and the spread of that prediction ``spread`` [m^2]
    (:func:`activetrack.planning.expected_gospa.position_spread`). M = 1: none."""

    factor: float = 1.0
    coverage: float = 0.0
    spread: float = 0.0

    def __post_init__(self) -> None:
        require_in_range("factor", self.factor, 0.0, 1.0)
        require_in_range("coverage", self.coverage, 0.0, 1.0)
        require_in_range("spread", self.spread, 0.0, math.inf, hi_inclusive=False)

    def after(self, coverage: ArrayLike, P: ArrayLike) -> np.ndarray:
        """The chance ``(...)`` that a beam pointed at a prediction of covariance ``P``
        ``(..., 4, 4)`` holds the target, given these misses, from its ``coverage`` ``(...)``
        without them: :func:`coverage_after_misses` with the misses' beam then and the
        correlation sqrt(spread then / spread now) of a random walk's offsets (as the
        prediction widens, the target may have come back into the part those looks emptied;
        a prediction no wider than at the looks: the same beam)."""
        c = np.asarray(coverage, dtype=float)
        if self.factor >= 1.0:
            return c
        m = position_spread(P)
        rho = np.sqrt(np.clip(self.spread / np.where(m > 0.0, m, 1.0), 0.0, 1.0))
        rho = np.where(m > self.spread, rho, 1.0)
        return coverage_after_misses(c, self.factor, self.coverage, rho)


NO_MISSES = MissedLooks()


def _check_round(C: ArrayLike, c0: ArrayLike, weights: ArrayLike) -> tuple[np.ndarray, ...]:
    C = np.asarray(C, dtype=float)
    c0 = np.asarray(c0, dtype=float)
    w = np.asarray(weights, dtype=float)
    if C.ndim != 2 or c0.shape != (C.shape[1],) or w.shape != c0.shape:
        raise ValueError(
            f"C must be (S, T) with c0 and weights (T,), got {C.shape}, {c0.shape}, {w.shape}"
        )
    if not (np.isfinite(C).all() and np.isfinite(c0).all() and np.all(w > 0)):
        raise ValueError("C and c0 must be finite and weights > 0")
    return C, c0, w


def assignment_value(
    tracks_of: ArrayLike, C: ArrayLike, c0: ArrayLike, weights: ArrayLike, aggregate: str
) -> float:
    """The aggregate of one round's assignment ``tracks_of`` ``(S,)`` (track index, -1: none;
    each track at most once): track t costs ``C[s, t]`` if sensor s serves it, else ``c0[t]``."""
    C, c0, w = _check_round(C, c0, weights)
    costs = c0.copy()
    for s, t in enumerate(np.asarray(tracks_of, dtype=int)):
        if t >= 0:
            costs[t] = C[s, t]
    return float(aggregate_costs(costs, w, aggregate))


def round_assignment(C: ArrayLike, c0: ArrayLike, weights: ArrayLike, aggregate: str) -> np.ndarray:
    """One round: the track of each sensor ``(S,)``, each track at most once (-1: the sensor
    waits for the next round, only when S > T), minimising ``aggregate`` (module docstring) of
    ``C`` ``(S, T)``, ``c0`` ``(T,)`` and ``weights`` ``(T,)`` > 0."""
    C, c0, w = _check_round(C, c0, weights)
    if check_aggregate(aggregate) == "worst":
        rows, cols = _minimax(C, c0, C - c0)
    else:
        rows, cols = _linear_sum_assignment(w * (C - c0))
    out = np.full(C.shape[0], -1, dtype=int)
    out[rows] = cols
    return out


def _feasible(C: np.ndarray, c0: np.ndarray, theta: float) -> bool:
    """Whether every track above ``theta`` can get its own sensor that brings it to theta."""
    must = c0 > theta
    if must.sum() > C.shape[0]:
        return False
    if not must.any():
        return True
    blocked = (C[:, must] > theta).astype(float)
    rows, cols = _linear_sum_assignment(blocked)
    return bool(blocked[rows, cols].sum() == 0.0)


def _minimax(C: np.ndarray, c0: np.ndarray, gain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact bottleneck round: the smallest feasible threshold, then the largest summed gain
    with every track above it served by an allowed sensor (a -big bonus forces those pairs,
    a +big penalty forbids pairs that would leave a track above it)."""
    values = np.unique(np.concatenate([c0, C.ravel()]))
    lo, hi = 0, len(values) - 1  # values[hi] (the largest cost) is always feasible
    while lo < hi:
        mid = (lo + hi) // 2
        if _feasible(C, c0, float(values[mid])):
            hi = mid
        else:
            lo = mid + 1
    theta = values[lo]
    big = 4.0 * (C.shape[0] + 1) * (float(np.max(np.abs(gain))) + 1.0)
    allowed = C <= theta
    must = c0 > theta
    D = gain + np.where(allowed, 0.0, big) - np.where(allowed & must[None, :], big, 0.0)
    return _linear_sum_assignment(D)


def mre_pair_costs(
    predictions: Sequence[TargetPrediction],
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    detection: ArrayLike,
    criterion: str,
) -> tuple[np.ndarray, np.ndarray]:
    """``C`` ``(S, T)`` and ``c0`` ``(T,)``: ``criterion`` of eq. 23 for each track (its
    prediction x_{k+1|k}, P_{k+1|k}, F, Q) with sensor s's expected update at its pv ``(S, 4)``
    with detection factor ``detection[s, t]`` (``(S, T)``), or with none."""
    crit = get_criterion(criterion, POSITIONING, SELECTION, what="criterion")
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    d = np.asarray(detection, dtype=float)
    S, T = len(sensors), len(predictions)
    if pvs.shape[0] != S or d.shape != (S, T):
        raise ValueError(f"sensor_pvs must be ({S}, 4) and detection ({S}, {T})")
    C, c0 = np.empty((S, T)), np.empty(T)
    if T == 0:
        return C, c0
    # Every track at once, sensor by sensor: the operations of TargetPrediction.after_look
    # on each track's rows (the same numbers as pair by pair).
    x = np.stack([p.x for p in predictions])
    P = np.stack([p.P for p in predictions])
    F = np.stack([p.F for p in predictions])
    Q = np.stack([p.Q for p in predictions])
    Ft = np.swapaxes(F, -1, -2)

    def cost(P_next: np.ndarray) -> np.ndarray:
        if not crit.needs_state:
            return np.asarray(crit.of_covariance(P_next, None), dtype=float)
        return np.array([float(crit.of_covariance(P_next[t], x[t])) for t in range(T)])

    c0[:] = cost(F @ P @ Ft + Q)
    for s, sensor in enumerate(sensors):
        pd = d[s] * np.asarray(sensor.in_range(x, pvs[s]), dtype=float)
        P_upd = mre_update(P, sensor.jacobian(x, pvs[s]), sensor.R, pd)
        C[s] = cost(F @ P_upd @ Ft + Q)
    return np.minimum(C, c0), c0


def assign_beams(
    predictions: Sequence[TargetPrediction],
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    detection: ArrayLike,
    criterion: str,
    weights: ArrayLike,
    aggregate: str,
) -> np.ndarray:
    """The track index ``(S,)`` of each steerable sensor: :func:`round_assignment` of the
    :func:`mre_pair_costs`, in rounds while sensors are left (module docstring)."""
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    d = np.asarray(detection, dtype=float)
    preds = list(predictions)
    out = np.full(len(sensors), -1, dtype=int)
    remaining = list(range(len(sensors)))
    while remaining and preds:
        C, c0 = mre_pair_costs(
            preds, [sensors[i] for i in remaining], pvs[remaining], d[remaining], criterion
        )
        picks = round_assignment(C, c0, weights, aggregate)
        for i, t in zip(remaining, picks, strict=True):
            if t >= 0:
                out[i] = t
                preds[t] = preds[t].after_look(sensors[i], pvs[i], float(d[i, t]))
        remaining = [i for i, t in zip(remaining, picks, strict=True) if t < 0]
    return out


def beam_candidates(bearings: ArrayLike, width: float) -> np.ndarray:
    """Beam centres ``(J,)`` [rad] worth trying for targets at ``bearings`` ``(T,)``: each
    target's bearing (the beam on it alone) and, for each target, the middle of the group of
    targets from it up to ``width`` counter-clockwise. A set of targets one beam can hold
    spans at most ``width`` from its first member, so one of these centres holds it."""
    b = np.asarray(bearings, dtype=float).reshape(-1)
    if not (np.isfinite(b).all() and width > 0.0):
        raise ValueError(f"bearings must be finite and width > 0, got {b}, {width}")
    ahead = np.mod(b[None, :] - b[:, None], 2.0 * math.pi)  # [i, j]: j counter-clockwise of i
    reach = np.max(np.where(ahead <= width, ahead, 0.0), axis=1)
    return np.unique(np.round(wrap_angle(np.concatenate([b, b + 0.5 * reach])), 12))


def footprint_pointing(
    predictions: Sequence[TargetPrediction],
    sensors: Sequence[ClutteredSensor],
    sensor_pvs: ArrayLike,
    detection: ArrayLike,
    missed: Sequence[MissedLooks],
    criterion: str,
    weights: ArrayLike,
) -> tuple[np.ndarray, np.ndarray]:
    """Beam bearings ``(S,)`` [rad] for steerable ``sensors`` at pvs ``(S, 4)`` that credit
    every track a beam holds, not only the one it is pointed at (the tracker updates every
    track whose predicted position lies inside a scan's sector); and which tracks each beam
    holds ``(S, T)``.

    Track t's cost is ``criterion`` of eq. 23 (its prediction with the updates counted so far,
    as :func:`mre_pair_costs`); a beam centred at bearing b updates every track with detection
    factor ``detection[s, t]`` (q I_range I_fov) times the chance that the target lies in the
    beam (:func:`~activetrack.models.fov.sector_coverage` off its centre, after the track's
    unsuccessful looks ``missed`` ``(T,)``: :meth:`MissedLooks.after`). Greedy in turn:
    of every remaining sensor and centre (:func:`beam_candidates`) the largest summed
    ``weights`` ``(T,)`` times the drop in cost goes first, with the updates it brings."""
    crit = get_criterion(criterion, POSITIONING, SELECTION, what="criterion")
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    d = np.asarray(detection, dtype=float)
    w = np.asarray(weights, dtype=float)
    S, T = len(sensors), len(predictions)
    if pvs.shape[0] != S or d.shape != (S, T) or len(missed) != T or w.shape != (T,):
        raise ValueError(
            f"sensor_pvs must be ({S}, 4), detection ({S}, {T}), missed and weights ({T},)"
        )
    if any(s.beam_width is None for s in sensors):
        raise ValueError("sensors: every sensor pointed here needs a beam_width")
    x = np.stack([p.x for p in predictions])
    P0 = np.stack([p.P for p in predictions])  # where the targets may be: before any update
    preds = list(predictions)

    def cost(p: TargetPrediction) -> float:
        return float(crit.of_covariance(p.F @ p.P @ p.F.T + p.Q, p.x))

    costs = np.array([cost(p) for p in preds])
    bearings, holds = np.full(S, np.nan), np.zeros((S, T), dtype=bool)
    remaining = list(range(S))
    while remaining:
        best: tuple[float, int, float, np.ndarray, list[TargetPrediction], np.ndarray] | None
        best = None
        # (s, t) -> the update of preds[t] by a sure look of s, shared by s's beam centres
        looks: dict[tuple[int, int], tuple[np.ndarray, float]] = {}
        for s in remaining:
            width = float(cast(float, sensors[s].beam_width))
            theta = np.arctan2(x[:, 2] - pvs[s, 2], x[:, 0] - pvs[s, 0])
            for b in beam_candidates(theta, width):
                off = wrap_angle(b - theta)
                inside = np.abs(off) <= 0.5 * width
                seen = sector_coverage(width, off, x, P0, pvs[s])
                c = np.array([m.after(seen[t], P0[t]) for t, m in enumerate(missed)])
                factor = d[s] * c
                new, after = list(preds), costs.copy()
                for t in np.flatnonzero(inside & (factor > 0.0)):
                    p = preds[t]
                    key = (s, int(t))
                    if key not in looks:
                        looks[key] = p.sure_look(sensors[s], pvs[s])
                    new[t] = p.after_sure_look(looks[key], float(factor[t]))
                    after[t] = cost(new[t])
                gain = float(w @ (costs - after))
                if best is None or gain > best[0]:
                    best = (gain, s, float(b), inside, new, after)
        assert best is not None
        _, s, b, inside, preds, costs = best
        bearings[s], holds[s] = b, inside
        remaining.remove(s)
    return bearings, holds


def gospa_pair_costs(
    predictions: Sequence[TargetPrediction],
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    detection: ArrayLike,
    hits: ArrayLike,
    base: tuple[ArrayLike, ArrayLike, ArrayLike],
    weights: GospaWeights,
    terminate: ArrayLike = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """``C`` ``(S, T)`` and ``c0`` ``(T,)``: each track's expected GOSPA^p at the next epoch
    (:func:`activetrack.planning.expected_gospa.managed_split`, summed) with sensor s's expected
    update (eq. 23, detection factor ``detection[s, t]``) and chance of a hit ``hits[s, t]``,
    or with none. ``predictions`` carry P_{k+1|k} with the updates already counted; ``base``
    = (their chance of a hit ``(T,)``, the spread of the predicted position before any update
    ``(T,)``, the probability of existence ``(T,)``); ``terminate`` ``(T,)`` or one: the
    tracker's threshold of existence below which it ends each track
    (:func:`~activetrack.planning.expected_gospa.managed_split`; 0: never)."""
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    d = np.asarray(detection, dtype=float)
    q = np.asarray(hits, dtype=float)
    q0, m_pred, existence = (np.asarray(a, dtype=float) for a in base)
    tau = np.broadcast_to(np.asarray(terminate, dtype=float), existence.shape)
    S, T = len(sensors), len(predictions)
    if pvs.shape[0] != S or d.shape != (S, T) or q.shape != (S, T):
        raise ValueError(f"sensor_pvs must be ({S}, 4), detection and hits ({S}, {T})")
    if not (q0.shape == m_pred.shape == existence.shape == (T,)):
        raise ValueError(f"base: hit chances, spreads and existence must be ({T},)")

    def cost(t: int, P: np.ndarray, hit: float) -> float:
        split = managed_split(existence[t], hit, m_pred[t], position_spread(P), weights, tau[t])
        return float(split.sum())

    C, c0 = np.empty((S, T)), np.empty(T)
    for t, p in enumerate(predictions):
        c0[t] = cost(t, p.P, float(q0[t]))
        for s, sensor in enumerate(sensors):
            P_upd = p.after_look(sensor, pvs[s], float(d[s, t])).P
            C[s, t] = cost(t, P_upd, float(hit_probability([q0[t], q[s, t]])))
    return np.minimum(C, c0), c0


def assign_beams_gospa(
    predictions: Sequence[TargetPrediction],
    sensors: Sequence[SensorModel],
    sensor_pvs: ArrayLike,
    detection: ArrayLike,
    hits: ArrayLike,
    base: tuple[ArrayLike, ArrayLike, ArrayLike],
    weights: GospaWeights,
    priorities: ArrayLike,
    search: ArrayLike | None = None,
    terminate: ArrayLike = 0.0,
) -> np.ndarray:
    """The track index ``(S,)`` of each steerable sensor: the weighted-sum
    :func:`round_assignment` (``priorities`` ``(T,)``) of the :func:`gospa_pair_costs`, in
    rounds while sensors are left, each round taking in the previous rounds' updates and hits.
    Optimal within a round: keeping every beam on its track is one of the assignments scored.

    ``search`` ``(S, J)``: search pointings as J more columns, entry [s, j] the GOSPA^p that
    sensor s saves by pointing at j (:func:`search_columns`; NaN: j is not one of s's), so
    one assignment weighs serving tracks against searching; a pick ``T + j`` is pointing j.
    Every sensor then has a column of its own and is assigned in the first round.
    ``terminate``: the tracker's thresholds of existence (:func:`gospa_pair_costs`)."""
    if search is not None:  # one round over tracks and pointings
        C, c0 = gospa_pair_costs(
            predictions, sensors, sensor_pvs, detection, hits, base, weights, terminate
        )
        w = np.asarray(priorities, dtype=float)
        C, c0, w = search_columns(C, c0, w, np.asarray(search, dtype=float))
        return round_assignment(C, c0, w, "weighted_sum")
    pvs = np.asarray(sensor_pvs, dtype=float).reshape(-1, 4)
    d = np.asarray(detection, dtype=float)
    q = np.asarray(hits, dtype=float)
    q0, m_pred, existence = (np.array(a, dtype=float) for a in base)
    preds = list(predictions)
    out = np.full(len(sensors), -1, dtype=int)
    remaining = list(range(len(sensors)))
    while remaining and preds:
        C, c0 = gospa_pair_costs(
            preds,
            [sensors[i] for i in remaining],
            pvs[remaining],
            d[remaining],
            q[remaining],
            (q0, m_pred, existence),
            weights,
            terminate,
        )
        picks = round_assignment(C, c0, priorities, "weighted_sum")
        for i, t in zip(remaining, picks, strict=True):
            if t >= 0:
                out[i] = t
                preds[t] = preds[t].after_look(sensors[i], pvs[i], float(d[i, t]))
                q0[t] = hit_probability([q0[t], q[i, t]])
        remaining = [i for i, t in zip(remaining, picks, strict=True) if t < 0]
    return out


def search_columns(
    C: np.ndarray, c0: np.ndarray, priorities: np.ndarray, search: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The round's ``C`` ``(S, T + J)``, ``c0`` and priorities ``(T + J,)`` with the search
    pointings ``search`` ``(S, J)`` appended: ``C = -value`` against ``c0 = 0`` (priority 1:
    the value is already GOSPA^p), a sensor's pair with another's pointing (NaN) a cost no
    optimal assignment takes (every sensor has pointings of its own)."""
    S = C.shape[0]
    if search.ndim != 2 or search.shape[0] != S:
        raise ValueError(f"search must be ({S}, J), got {search.shape}")
    own = np.isfinite(search)
    if not own.any(axis=1).all():
        raise ValueError("search: every sensor needs at least one pointing of its own")
    if np.any(search[own] < 0.0):
        raise ValueError("search: a pointing's value must be >= 0")
    gains = np.concatenate([(c0 - C).ravel(), search[own]])
    big = 4.0 * (S + 1) * (float(np.max(np.abs(gains), initial=0.0)) + 1.0)
    C_search = np.where(own, -np.where(own, search, 0.0), big)
    return (
        np.concatenate([C, C_search], axis=1),
        np.concatenate([c0, np.zeros(search.shape[1])]),
        np.concatenate([priorities, np.ones(search.shape[1])]),
    )


def random_assignment(n_sensors: int, n_tracks: int, rng: np.random.Generator) -> np.ndarray:
    """The random baseline: uniform over the balanced assignments the rounds make (each track
    once before any twice): ``ceil(S / T)`` permutations of the tracks from ``rng``."""
    if n_tracks < 1 or n_sensors < 0:
        raise ValueError(f"n_tracks must be >= 1 and n_sensors >= 0, got {n_tracks}, {n_sensors}")
    rounds = [rng.permutation(n_tracks) for _ in range(math.ceil(n_sensors / n_tracks))]
    return np.concatenate(rounds)[:n_sensors].astype(int) if rounds else np.zeros(0, dtype=int)


def nearest_assignment(sensor_xy: ArrayLike, track_xy: ArrayLike) -> np.ndarray:
    """Each sensor's closest track ``(S,)`` (positions ``(S, 2)`` and ``(T, 2)``; shared)."""
    a = np.asarray(sensor_xy, dtype=float).reshape(-1, 2)
    b = np.asarray(track_xy, dtype=float).reshape(-1, 2)
    if b.shape[0] < 1:
        raise ValueError("track_xy must hold at least one track position")
    return np.argmin(np.hypot(*np.moveaxis(a[:, None] - b[None], -1, 0)), axis=1).astype(int)
