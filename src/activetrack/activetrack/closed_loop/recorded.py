"""Tracking recorded detections: the tracker alone, open loop (``activetrack track``,
docs/track-your-data.md).

:func:`track_detections` steps the configuration's tracker (the builder and generator of
(seed, run) a scenario's run uses) through epochs 1..K, K the data's last, with each epoch's
scans (none: it predicts): on the scans of a run with its scenario and run index it reproduces
the run's tracks bit for bit. With truth, GOSPA at each epoch (:class:`GospaSeries`) with the
configuration's cut-off, order and alpha (Rahmathullah, Garcia-Fernandez & Svensson 2017).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from activetrack.closed_loop.components import build_tracker, component_rngs
from activetrack.closed_loop.evaluation import epoch_gospa, reported_positions
from activetrack.data import TrackSet, TruthSet
from activetrack.scenarios.schema import EvaluationConfig
from activetrack.scenarios.tracking import TrackingConfig
from activetrack.tracking.detections import DataFileError, Detections

__all__ = ["GospaSeries", "TrackingRun", "gospa_series", "track_detections"]


@dataclass(frozen=True)
class GospaSeries:
    """GOSPA at epochs 1..K ``(K,)`` [m] and its alpha = 2 split: localisation [m^p], missed
    targets and false tracks (counts)."""

    epochs: np.ndarray
    gospa: np.ndarray
    localisation: np.ndarray
    missed: np.ndarray
    false: np.ndarray

    @property
    def mean(self) -> float:
        """GOSPA averaged over epochs 1..K [m]."""
        return float(np.mean(self.gospa))

    def to_json(self) -> dict:
        series = ("epochs", "gospa", "localisation", "missed", "false")
        return {"mean": self.mean, **{name: getattr(self, name).tolist() for name in series}}


@dataclass
class TrackingRun:
    """The track sets of epochs 0..K (without samples), GOSPA when truth was given, and the
    tracker's counters (deletions, detections not started, clusters split)."""

    config: TrackingConfig
    track_sets: list[TrackSet]
    gospa: GospaSeries | None = None
    counters: Counter[str] = field(default_factory=Counter)

    @property
    def epochs(self) -> int:
        return len(self.track_sets) - 1


def gospa_series(
    track_sets: Sequence[TrackSet], truth: Mapping[int, TruthSet], evaluation: EvaluationConfig
) -> GospaSeries:
    """GOSPA of each epoch 1..K between ``truth[k]`` (none: no target) and the confirmed
    tracks of ``track_sets[k]``."""
    rows = []
    for ts in track_sets[1:]:
        t = truth.get(ts.epoch)
        X = np.empty((0, 2)) if t is None else np.asarray(t.pv, dtype=float)[:, [0, 2]]
        distance, split = epoch_gospa(X, reported_positions(ts, ts.epoch), evaluation)
        rows.append((ts.epoch, distance, split.localisation, split.missed, split.false_tracks))
    epochs, dist, loc, missed, false = (np.array(c) for c in zip(*rows, strict=True))
    return GospaSeries(epochs.astype(int), dist, loc, missed.astype(int), false.astype(int))


def _check(config: TrackingConfig, detections: Detections, truth: Mapping[int, TruthSet] | None):
    """What the tracker would refuse mid-way, refused before it starts (DataFileError)."""
    if config.known_association:
        for k, scans in detections.scans.items():
            for scan in scans:
                if len(scan.Z) > 1:
                    raise DataFileError(
                        f"{detections.source}: {detections.rows[(k, scan.sensor_id)]}: the scan "
                        f"of {scan.sensor_id!r} at epoch {k} has {len(scan.Z)} detections; with "
                        "the association known (one target, no clutter) a scan holds at most "
                        "one: set association: jpda in the configuration"
                    )
    K = detections.last_epoch
    beyond = [k for k in (truth or {}) if k > K]
    if beyond:
        raise DataFileError(
            f"the truth holds epoch {max(beyond)}, the detections end at epoch {K}: give the "
            "truth of epochs 0..K"
        )


def track_detections(
    config: TrackingConfig,
    detections: Detections,
    truth: Mapping[int, TruthSet] | None = None,
    run: int | None = None,
) -> TrackingRun:
    """The configuration's tracker on the detections, epochs 1..K (module docstring)."""
    _check(config, detections, truth)
    K = detections.last_epoch
    tracker = build_tracker(config, component_rngs(config.seed, run)[1], steps=K)
    sets = [tracker.snapshot().without_samples()]
    for k in range(1, K + 1):
        sets.append(tracker.step(k, k * config.dt, detections.at(k)).without_samples())
    scores = None if truth is None else gospa_series(sets, truth, config.evaluation)
    return TrackingRun(config, sets, scores, tracker.counters)
