"""Evaluation of a multi-target run: GOSPA / OSPA over time, track breaks and swaps, and each
target's RMSE against its PCRLB.

At each epoch k = 1..K the confirmed tracks' positions (x, y of their means) are compared with
the alive targets' true positions (:mod:`activetrack.metrics`; cut-off ``c``, order ``p`` and
alpha from ``scenario.evaluation``): GOSPA (Rahmathullah, Garcia-Fernandez & Svensson 2017,
eq. 1) with its alpha = 2 split (eq. 2) into localisation, missed targets and false tracks, and
OSPA (Schuhmacher, Vo & Vo 2008, eq. 3).

Association. Target n is *held* at epoch k by track ``a`` when the pair (n, a) is in that
epoch's optimal GOSPA assignment with alpha = 2, i.e. the optimal partial assignment of targets
to confirmed tracks among the pairs closer than ``c`` (Rahmathullah et al. 2017, Proposition 1);
a target without a partner is not held. Over consecutive epochs k-1, k (k = 2..K):

- a **swap**: target n held by track a at k-1 and by a different track b at k. An exchange of
  two targets between two tracks counts two swaps, one per target: the identity switches of
  the CLEAR MOT metrics (Bernardin & Stiefelhagen 2008, sec. 2.1.1, counted here between
  consecutive epochs only) and the track-number changes of the SIAP metrics (Votruba et al.
  2001; Stone Soup's "rate of track number change");
- a **break**: target n held at k-1, alive and not held at k (its track was deleted, lost
  confirmation or drifted beyond the cut-off): the fragmentations of the MOT literature (Li,
  Huang & Nevatia 2009). A target that dies is not broken; one held again later is not a swap.

Per target, over the epochs 1..K it was held: ``target_rmse`` the root mean square position
error of its track, ``target_bound`` the root of the mean PCRLB on the position MSE,
``B[0, 0] + B[2, 2]`` of :func:`activetrack.multitarget.bounds.target_bounds` (the error of a
held track is the estimate's error once association is right, cf. the per-target bound of
Hernandez, Farina & Ristic 2006); NaN for a target never held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import FloatArray
from activetrack.metrics import GospaResult, gospa, ospa
from activetrack.multitarget.bounds import BOUND_SAMPLES, alive_mask, target_bounds
from activetrack.multitarget.data import MultiRunRecord
from activetrack.scenarios.schema import Scenario

__all__ = ["NOT_HELD", "RunEvaluation", "count_breaks_swaps", "evaluate_run", "held_tracks"]

NOT_HELD = -1  # in held_tracks: the target has no track (BeamCommand's "no track" too)


@dataclass(frozen=True)
class RunEvaluation:
    """The evaluation of one run at epochs 1..K (K epochs, N targets in scenario order).

    ``gospa`` uses the scenario's alpha; ``localisation`` (sum of d^p over the assigned pairs,
    units m^p), ``missed`` and ``false`` are the alpha = 2 split, so that with alpha = 2
    ``gospa**p == localisation + c**p / 2 * (missed + false)``. Breaks, swaps and the per-target
    figures as defined in the module docstring; ``held_fraction`` is the fraction of a target's
    alive epochs in 1..K at which it was held (NaN if it was never alive there)."""

    time: np.ndarray  # (K,) [s]
    gospa: np.ndarray  # (K,) [m]
    localisation: np.ndarray  # (K,) [m^p]
    missed: np.ndarray  # (K,) int
    false: np.ndarray  # (K,) int
    ospa: np.ndarray  # (K,) [m]
    breaks: int
    swaps: int
    target_rmse: np.ndarray  # (N,) [m]
    target_bound: np.ndarray  # (N,) [m]
    held_fraction: np.ndarray  # (N,)

    @property
    def mean_gospa(self) -> float:
        """GOSPA averaged over epochs 1..K [m]."""
        return float(np.mean(self.gospa))


def _epoch_sets(
    record: MultiRunRecord, alive: np.ndarray, k: int
) -> tuple[FloatArray, np.ndarray, FloatArray, np.ndarray]:
    """Truth positions ``(m, 2)`` and their target indices ``(m,)``, confirmed tracks' positions
    ``(n, 2)`` and their ids ``(n,)`` at epoch k."""
    targets = np.flatnonzero(alive[k])
    X = np.asarray(record.truth, dtype=float)[k][targets][:, [0, 2]]
    confirmed = record.tracks[k].confirmed
    Y = np.array([np.asarray(t.mean)[[0, 2]] for t in confirmed], dtype=float).reshape(-1, 2)
    ids = np.array([t.track_id for t in confirmed], dtype=int)
    if not np.isfinite(Y).all():
        raise ValueError(f"record.tracks[{k}]: a confirmed track's mean must be finite")
    return X, targets, Y, ids


def _epoch_gospa(scenario: Scenario, X: FloatArray, Y: FloatArray) -> tuple[GospaResult, float]:
    """The alpha = 2 GOSPA result (split and association) and GOSPA with the scenario's
    alpha."""
    ev = scenario.evaluation
    split = gospa(X, Y, ev.cutoff, ev.order, 2.0)
    if ev.alpha == 2.0:
        return split, split.distance
    return split, gospa(X, Y, ev.cutoff, ev.order, ev.alpha).distance


def _epochs(
    scenario: Scenario, record: MultiRunRecord, alive: np.ndarray
) -> tuple[FloatArray, np.ndarray]:
    """Per epoch 1..K: ``(5, K)`` GOSPA, localisation, missed, false, OSPA; and ``(K, N)`` the
    id of the track holding each target (:data:`NOT_HELD` where none does)."""
    K, N = alive.shape[0] - 1, alive.shape[1]
    ev = scenario.evaluation
    held = np.full((K, N), NOT_HELD, dtype=int)
    series = np.zeros((5, K))
    for k in range(1, K + 1):
        X, targets, Y, ids = _epoch_sets(record, alive, k)
        split, distance = _epoch_gospa(scenario, X, Y)
        series[:, k - 1] = (
            distance,
            split.localisation,
            split.missed,
            split.false_tracks,
            ospa(X, Y, ev.cutoff, ev.order),
        )
        for i, j in split.assignment:
            held[k - 1, targets[i]] = ids[j]
    return series, held


def held_tracks(scenario: Scenario, record: MultiRunRecord) -> np.ndarray:
    """``(K, N)`` int: the id of the confirmed track holding target n at epoch k = 1..K
    (association in the module docstring), :data:`NOT_HELD` where none does."""
    return _epochs(scenario, record, alive_mask(scenario, record))[1]


def count_breaks_swaps(held: np.ndarray, alive: np.ndarray) -> tuple[int, int]:
    """(breaks, swaps) of ``held`` ``(K, N)`` (:func:`held_tracks`) with ``alive`` ``(K, N)``
    the targets alive at the same epochs (definitions in the module docstring)."""
    held = np.asarray(held)
    alive = np.asarray(alive, dtype=bool)
    if held.shape != alive.shape or held.ndim != 2:
        raise ValueError(f"held and alive must both be (K, N), got {held.shape} and {alive.shape}")
    before, now = held[:-1], held[1:]
    was_held = before != NOT_HELD
    is_held = now != NOT_HELD
    swaps = was_held & is_held & (now != before)
    breaks = was_held & ~is_held & alive[1:]
    return int(breaks.sum()), int(swaps.sum())


def _per_target(
    record: MultiRunRecord, held: np.ndarray, alive: np.ndarray, bound: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(target_rmse, target_bound, held_fraction), each ``(N,)``; ``alive`` ``(K, N)`` and
    ``bound`` ``(K, N, 4, 4)`` at epochs 1..K."""
    truth = np.asarray(record.truth, dtype=float)[1:]
    err2 = np.full(held.shape, math.nan)
    for k, row in enumerate(held):
        means = {t.track_id: t.mean for t in record.tracks[k + 1].confirmed}
        for n in np.flatnonzero(row != NOT_HELD):
            d = np.asarray(means[int(row[n])])[[0, 2]] - truth[k, n, [0, 2]]
            err2[k, n] = float(d @ d)
    on = held != NOT_HELD
    count = on.sum(axis=0)
    pos_bound = bound[..., 0, 0] + bound[..., 2, 2]  # (K, N) bound on the position MSE
    with np.errstate(invalid="ignore", divide="ignore"):
        rmse = np.sqrt(np.where(on, err2, 0.0).sum(axis=0) / count)
        bnd = np.sqrt(np.where(on, pos_bound, 0.0).sum(axis=0) / count)
        fraction = count / alive.sum(axis=0)
    return rmse, bnd, fraction


def evaluate_run(
    scenario: Scenario,
    record: MultiRunRecord,
    rng: np.random.Generator,
    *,
    n_samples: int = BOUND_SAMPLES,
) -> RunEvaluation:
    """GOSPA / OSPA over time, breaks, swaps and per-target RMSE and bound of one run.

    ``rng`` draws the bound's Monte Carlo samples (:func:`target_bounds`, ``n_samples`` per
    target); everything else is deterministic. ValueError when the record does not fit the
    scenario (shapes, target and sensor order, lifetimes).
    """
    alive = alive_mask(scenario, record)
    K = alive.shape[0] - 1
    series, held = _epochs(scenario, record, alive)
    breaks, swaps = count_breaks_swaps(held, alive[1:])
    bound = target_bounds(scenario, record, rng, n_samples=n_samples)
    rmse, bnd, fraction = _per_target(record, held, alive[1:], bound)
    return RunEvaluation(
        time=np.array([record.tracks[k].time for k in range(1, K + 1)], dtype=float),
        gospa=series[0],
        localisation=series[1],
        missed=series[2].astype(int),
        false=series[3].astype(int),
        ospa=series[4],
        breaks=breaks,
        swaps=swaps,
        target_rmse=rmse,
        target_bound=bnd,
        held_fraction=fraction,
    )
