"""The expected GOSPA of a track one epoch ahead, split as the metric splits (the planner's
``planner.targets.objective: gospa``).

GOSPA (Rahmathullah, Garcia-Fernandez & Svensson, FUSION 2017, Definition 1, eq. 1; for
alpha = 2 Proposition 1, eq. 2) adds, to the power p, ``min(d, c)^p`` per target-track pair and
``c^p / alpha`` per missed target and per false track. Of one confirmed track with
probability of existence ``r`` (IPDA, :mod:`activetrack.tracking.management`), at one epoch:

- its target exists and the track holds it (probability ``r h``): localisation
  ``E[min(d, c)^p]`` (:func:`expected_localisation`);
- its target exists but the track has lost it (``r (1 - h)``): one missed target and one false
  track, ``c^p / alpha`` each (for alpha = 2 the same as the capped pair, ``c^p``);
- its target does not exist (``1 - r``): one false track, ``c^p / alpha``.

``h``, the probability that the track still holds its target, starts at 1 and falls at each
epoch by the chance of losing it (:func:`hold_update`): a track is lost at an epoch it passes
without a detection (probability ``1 - q``, q the chance of a hit: Pd times the probability
that the target is inside the sensors' ranges, fields of view and beams) while its predicted
error exceeds the cut-off c (then no gate or beam brings it back: ``P(d > c)``). Only c, p and
alpha weigh the terms against each other: nothing is tuned.

The tracker terminates a confirmed track whose probability of existence falls below its
threshold ``tau`` (``tracker.tracks.existence_terminate``). An epoch without a detection takes
r to ``r (1 - q) / (1 - r q)`` (IPDA's update with no detection in the gate, the looks'
misses multiplied: Musicki, Evans & Stankovic 1994); where that is below tau the track ends
then (:func:`managed_split`): a target that exists is missed (``r (1 - q)``), and a track whose
target has died is no longer a false one. So a look at a track whose target may have died is
worth the false track it ends. Not modelled: the tracker's survival factor per epoch
(``tracker.tracks.existence_survival``, which lowers r a little more) and clutter in the gate
(which lowers it less); the rule of ``delete_misses`` consecutive misses (the planner does
not see the run of misses).
"""

from __future__ import annotations

import numpy as np

from activetrack.arraytypes import ArrayLike
from activetrack.metrics import GospaWeights, beyond_cutoff, expected_localisation, position_spread

__all__ = [
    "GospaWeights",
    "beyond_cutoff",
    "expected_localisation",
    "hit_probability",
    "hold_update",
    "managed_split",
    "miss_existence",
    "position_spread",
    "track_split",
]


def hit_probability(detections: ArrayLike) -> np.ndarray:
    """q = 1 - prod_s (1 - q_s) ``(...)``: the chance of at least one detection of a target
    from the sensors' chances ``(..., S)`` (independent sensors; S = 0: 0)."""
    q = np.asarray(detections, dtype=float)
    if q.shape[-1] == 0:
        return np.zeros(q.shape[:-1])
    return 1.0 - np.prod(1.0 - q, axis=-1)


def hold_update(hold: ArrayLike, q: ArrayLike, m_pred: ArrayLike, c: float) -> np.ndarray:
    """h' = h (1 - (1 - q) P(d > c)): the track keeps its target through an epoch unless it
    passes it without a detection (1 - q) while its predicted error (spread ``m_pred``) lies
    beyond the cut-off (module docstring)."""
    h = np.asarray(hold, dtype=float)
    return h * (1.0 - (1.0 - np.asarray(q, dtype=float)) * beyond_cutoff(m_pred, c))


def track_split(
    existence: ArrayLike, hold: ArrayLike, m: ArrayLike, weights: GospaWeights
) -> np.ndarray:
    """The expected localisation, missed and false terms of GOSPA^p ``(..., 3)`` of tracks of
    probability of existence ``r``, holding their targets with probability ``h`` and spread
    ``m`` after the epoch's update (module docstring): r h E[min(d, c)^p], r (1 - h) c^p /
    alpha, (r (1 - h) + 1 - r) c^p / alpha."""
    r = np.asarray(existence, dtype=float)
    h = np.asarray(hold, dtype=float)
    k = weights.cardinality
    loc = r * h * expected_localisation(m, weights.c, weights.p)
    lost = r * (1.0 - h)
    loc, lost = np.broadcast_arrays(loc, lost)
    return np.stack([loc, lost * k, (lost + (1.0 - r)) * k], axis=-1)


def miss_existence(existence: ArrayLike, q: ArrayLike) -> np.ndarray:
    """r' = r (1 - q) / (1 - r q) ``(...)``: the probability of existence after an epoch whose
    looks (chance ``q`` of a detection if the target exists) brought none (IPDA with no
    gated detection; r = 1 and q = 1: 0)."""
    r = np.asarray(existence, dtype=float)
    q = np.asarray(q, dtype=float)
    num, den = r * (1.0 - q), 1.0 - r * q
    return np.divide(num, den, out=np.zeros(np.broadcast(num, den).shape), where=den > 0.0)


def managed_split(
    existence: ArrayLike,
    q: ArrayLike,
    m_pred: ArrayLike,
    m: ArrayLike,
    weights: GospaWeights,
    terminate: ArrayLike = 0.0,
) -> np.ndarray:
    """The expected split ``(..., 3)`` of a confirmed track at the next epoch with the
    tracker's termination rule (module docstring): :func:`track_split` with the hold after
    :func:`hold_update` where the track survives an epoch without a detection; where such an
    epoch ends it (:func:`miss_existence` below ``terminate``) r q E[min(d, c)^p] (held),
    r (1 - q) c^p / alpha (missed) and no false track. ``q`` the chance of a detection,
    ``m_pred`` and ``m`` the spreads before and after the epoch's update."""
    r = np.asarray(existence, dtype=float)
    q = np.asarray(q, dtype=float)
    kept = track_split(r, hold_update(1.0, q, m_pred, weights.c), m, weights)
    ends = miss_existence(r, q) < np.asarray(terminate, dtype=float)
    if not np.any(ends):
        return kept
    loc = r * q * expected_localisation(m, weights.c, weights.p)
    ended = np.stack(np.broadcast_arrays(loc, r * (1.0 - q) * weights.cardinality, 0.0 * r), -1)
    return np.where(ends[..., None], ended, kept)
