"""Plain data crossing the multi-target loop's component boundaries.

Each maps one to one onto a msgs_defs message (``Scan``, ``TrackArray``), so the ROS nodes
only convert. Detections carry no target labels; the simulator keeps them in
:class:`ScanTruth` for evaluation only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from activetrack.closed_loop.data import Command, PlanReportData
from activetrack.models.fov import FieldOfView  # re-exported: it moved to the sensor side

__all__ = [
    "BeamCommand",
    "FieldOfView",
    "MultiDecision",
    "MultiRunRecord",
    "Scan",
    "ScanTruth",
    "TrackEstimate",
    "TrackSet",
    "TruthSet",
]

TENTATIVE = "tentative"
CONFIRMED = "confirmed"


@dataclass(frozen=True)
class Scan:
    """One sensor's unlabelled detections at an epoch: ``Z`` ``(m, dim_z)`` (m >= 0), taken
    from ``sensor_pv`` ``(4,)`` within ``fov``. An empty ``Z`` is "looked, saw nothing"."""

    sensor_id: str
    epoch: int
    time: float
    sensor_pv: np.ndarray
    Z: np.ndarray
    fov: FieldOfView = FieldOfView()


@dataclass(frozen=True)
class ScanTruth:
    """The labels of a scan's detections (evaluation only): target id or "" for clutter."""

    sensor_id: str
    epoch: int
    labels: tuple[str, ...]


@dataclass(frozen=True)
class TruthSet:
    """The targets alive at an epoch: ids and pv states ``(N, 4)``."""

    epoch: int
    time: float
    ids: tuple[str, ...]
    pv: np.ndarray


@dataclass(frozen=True)
class TrackEstimate:
    """One track after the update at an epoch: a stable integer id, ``status`` (tentative or
    confirmed), pv ``mean`` ``(4,)`` and ``cov`` ``(4, 4)``; ``origin`` is the target id whose
    prior started it ("" for a track started from detections), ``priority`` its planner
    weight, ``hits``/``misses`` of its looks, ``samples`` ``(M, 4)`` for particle filters."""

    track_id: int
    status: str
    mean: np.ndarray
    cov: np.ndarray
    origin: str = ""
    priority: float = 1.0
    age: int = 0
    hits: int = 0
    misses: int = 0
    ess: float = math.nan
    samples: np.ndarray | None = None

    @property
    def confirmed(self) -> bool:
        return self.status == CONFIRMED


@dataclass(frozen=True)
class TrackSet:
    """The tracker's output at an epoch (every live track, tentative ones included)."""

    epoch: int
    time: float
    filter_kind: str
    tracks: tuple[TrackEstimate, ...] = ()
    detections: int = 0  # detections of the epoch's scans
    unassociated: int = 0  # of them, gated by no track

    @property
    def confirmed(self) -> tuple[TrackEstimate, ...]:
        return tuple(t for t in self.tracks if t.confirmed)


@dataclass(frozen=True)
class BeamCommand:
    """Point ``sensor_id``'s beam at ``bearing`` [rad, world frame] for epoch ``epoch + 1``;
    ``track_id`` is the track it serves (-1: none)."""

    sensor_id: str
    epoch: int
    bearing: float
    track_id: int = -1


@dataclass(frozen=True)
class MultiDecision:
    """What the multi-target planner decided at ``epoch``: manoeuvres for the leg to
    epoch+1, beam pointings for epoch+1 and the plan report (per-track costs in ``extra``)."""

    epoch: int
    commands: tuple[Command, ...] = ()
    beams: tuple[BeamCommand, ...] = ()
    report: PlanReportData | None = None
    extra: dict = field(default_factory=dict)


@dataclass
class MultiRunRecord:
    """One multi-target closed-loop run, epochs 0..K.

    ``truth`` ``(K+1, N, 4)``: target pv in scenario order, NaN where a target is not alive;
    ``tracks``: the tracker's output at each epoch; ``platform_paths`` ``(K+1, P, 4)``;
    ``scans`` / ``scan_truth``: each epoch 1..K's scans and their labels; ``observed``
    ``(K, S, N)``: sensor s looked at epoch k and target n was alive inside its field of view
    (what the per-target bound counts); ``decisions``: one per epoch 0..K-1."""

    target_ids: tuple[str, ...]
    sensor_ids: tuple[str, ...]
    platform_ids: tuple[str, ...]
    truth: np.ndarray
    tracks: list[TrackSet]
    platform_paths: np.ndarray
    scans: list[list[Scan]] = field(default_factory=list)
    scan_truth: list[list[ScanTruth]] = field(default_factory=list)
    observed: np.ndarray | None = None
    decisions: list[MultiDecision] = field(default_factory=list)
    clamps: int = 0
    wall_time_s: float = 0.0
    planning_time_s: float = 0.0
