"""What one closed-loop run leaves: truth, tracks, platform paths, scans and decisions."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from activetrack.data import Decision, Scan, ScanTruth, TrackSet

__all__ = ["RunRecord"]


@dataclass
class RunRecord:
    """One closed-loop run, epochs 0..K (N targets, S sensors, P platforms, scenario order).

    ``truth`` ``(K+1, N, 4)``: target pv, NaN where a target is not alive; ``tracks``: the
    tracker's output at each epoch (without the planner's samples); ``platform_paths``
    ``(K+1, P, 4)``; ``scans`` / ``scan_truth``: each epoch 1..K's scans and their labels;
    ``looked`` ``(K, S)``: which sensors scanned at epochs 1..K (selection, stop-and-measure);
    ``detected`` ``(K, S)``: and reported at least one detection; ``observed`` ``(K, S, N)``:
    sensor s scanned at epoch k and target n was alive inside its field of view and detection
    ranges; ``decisions``: one per epoch 0..K-1."""

    target_ids: tuple[str, ...]
    sensor_ids: tuple[str, ...]
    platform_ids: tuple[str, ...]
    truth: np.ndarray
    tracks: list[TrackSet]
    platform_paths: np.ndarray
    scans: list[list[Scan]] = field(default_factory=list)
    scan_truth: list[list[ScanTruth]] = field(default_factory=list)
    looked: np.ndarray | None = None
    detected: np.ndarray | None = None
    observed: np.ndarray | None = None
    decisions: list[Decision] = field(default_factory=list)
    clamps: int = 0
    wall_time_s: float = 0.0
    planning_time_s: float = 0.0
    evaluations: int = 0

    @property
    def steps(self) -> int:
        return len(self.tracks) - 1

    def track_series(self, track_id: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The filter state ``(K+1, n)`` and covariance ``(K+1, n, n)`` of one track at
        epochs 0..K (NaN where it is not live); track 1 is the first target's from its prior
        (the papers' one target)."""
        rows = [next((t for t in ts.tracks if t.track_id == track_id), None) for ts in self.tracks]
        found = next((t for t in rows if t is not None), None)
        if found is None:
            raise ValueError(f"track_id: no track {track_id} in the run")
        n = found.state.shape[0]
        x = np.full((len(rows), n), np.nan)
        P = np.full((len(rows), n, n), np.nan)
        for k, t in enumerate(rows):
            if t is not None:
                x[k], P[k] = t.state, t.state_cov
        return x, P

    def missed_detections(self, track_id: int = 1) -> int:
        """The scans that covered a track without a detection of it, by the end of the run."""
        for t in self.tracks[-1].tracks:
            if t.track_id == track_id:
                return t.missed_detections
        raise ValueError(f"track_id: no live track {track_id} at the end of the run")
