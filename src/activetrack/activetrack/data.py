"""Plain data crossing the closed loop's component boundaries (docs/closed-loop.md).

One family for every scene, one target or many: the simulator sends :class:`Scan` s of
unlabelled detections (one target without clutter is the scan of at most one detection), the
tracker answers with a :class:`TrackSet`, the planner with a :class:`Decision`. Each maps one
to one onto a msgs_defs message (``Scan``, ``TrackArray``, ``ManoeuvreCommand``,
``BeamCommand``, ``SensorSelection``, ``PlanReport``, ``PlatformState``,
``GroundTruthArray``), so the ROS nodes only convert. The labels of the detections stay in
:class:`ScanTruth`, for evaluation only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from activetrack.models.fov import FieldOfView

__all__ = [
    "CONFIRMED",
    "TENTATIVE",
    "BeamCommand",
    "Command",
    "Decision",
    "PlanReportData",
    "PlatformSnapshot",
    "Scan",
    "ScanTruth",
    "TrackEstimate",
    "TrackSet",
    "TruthSet",
    "heading_speed",
]

TENTATIVE = "tentative"
CONFIRMED = "confirmed"


def heading_speed(pv: np.ndarray) -> tuple[float, float]:
    """Heading (rad from +x, counter-clockwise) and speed of a pv state."""
    return math.atan2(pv[3], pv[1]), math.hypot(pv[1], pv[3])


# --- platforms and their commands --------------------------------------------------------------


@dataclass(frozen=True)
class PlatformSnapshot:
    """A platform at an epoch: pv state, heading (rad from +x) and speed (m/s)."""

    platform_id: str
    epoch: int
    time: float
    pv: np.ndarray  # (4,) x, xdot, y, ydot
    heading: float
    speed: float
    sensor_ids: tuple[str, ...] = ()
    sensor_kinds: tuple[str, ...] = ()


@dataclass(frozen=True)
class Command:
    """A manoeuvre decided at epoch ``epoch`` for the leg from t_epoch to t_epoch+1.

    take_measurement: None, the platform's sensors always measure; True/False, they measure at
    epoch+1 or not (stop-and-measure platforms). waypoint: (x, y) the platform is heading for,
    for display only (the heading and speed changes are what the simulator flies).
    """

    platform_id: str
    epoch: int
    heading_change: float
    speed_change: float
    commanded_heading: float = math.nan
    commanded_speed: float = math.nan
    take_measurement: bool | None = None
    waypoint: tuple[float, float] | None = None


@dataclass(frozen=True)
class BeamCommand:
    """Point ``sensor_id``'s beam at ``bearing`` [rad, world frame] for epoch ``epoch + 1``;
    ``track_id`` is the track it serves (-1: none)."""

    sensor_id: str
    epoch: int
    bearing: float
    track_id: int = -1


# --- measurements and truth ----------------------------------------------------------------------


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
    """The targets alive at an epoch: ids, pv states ``(N, 4)`` and the motion models' own
    states (``states[i]`` in the coordinates of target i's model)."""

    epoch: int
    time: float
    ids: tuple[str, ...]
    pv: np.ndarray
    states: tuple[np.ndarray, ...] = ()
    state_names: tuple[tuple[str, ...], ...] = ()


# --- tracks --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TrackEstimate:
    """One track after the update at an epoch.

    ``track_id`` is stable over the run; ``status`` tentative or confirmed; ``mean`` ``(4,)``
    and ``cov`` ``(4, 4)`` the pv kinematics of the filter's ``state`` ``(n,)`` and
    ``state_cov`` ``(n, n)`` (the same arrays for a pv model); ``origin`` the target id whose
    prior started it ("" for a track started from detections), ``priority`` its planner
    weight; ``hits`` / ``misses`` its looks (epochs a scan covered it) with and without a
    detection, ``missed_detections`` the scans that covered it without one; ``existence`` its
    probability of existence (1 for a target known to exist); ``nis`` of the epoch's last
    update of a Gaussian track (under JPDA the association-weighted NIS on the gate's S,
    :func:`activetrack.filters.jpda.pda_nis`; NaN without one), ``ess`` of a particle track's;
    ``samples`` ``(M, n)`` equally weighted
    posterior samples for the planner (particle filters); ``withheld``: a confirmed track the
    tracker leaves out of its estimate of the targets (``tracker.tracks.report: gospa``,
    :func:`activetrack.metrics.gospa_reported`), still tracked and planned for."""

    track_id: int
    status: str
    mean: np.ndarray
    cov: np.ndarray
    state: np.ndarray
    state_cov: np.ndarray
    origin: str = ""
    priority: float = 1.0
    age: int = 0
    hits: int = 0
    misses: int = 0
    missed_detections: int = 0
    existence: float = 1.0
    nis: float = math.nan
    ess: float = math.nan
    particle_count: int = 0
    samples: np.ndarray | None = None
    withheld: bool = False

    @property
    def confirmed(self) -> bool:
        return self.status == CONFIRMED

    @property
    def reported(self) -> bool:
        """In the tracker's estimate of the targets: confirmed and not withheld."""
        return self.confirmed and not self.withheld


@dataclass(frozen=True)
class TrackSet:
    """The tracker's output at an epoch: every live track by id (tentative ones included),
    the filter and motion model they use (``state_names`` of their ``state``), the updates so
    far, and of the epoch's scans the detections and those no track gated."""

    epoch: int
    time: float
    filter_kind: str
    motion_model: str = ""
    state_names: tuple[str, ...] = ("x", "xdot", "y", "ydot")
    tracks: tuple[TrackEstimate, ...] = ()
    updates: int = 0
    detections: int = 0
    unassociated: int = 0

    @property
    def confirmed(self) -> tuple[TrackEstimate, ...]:
        return tuple(t for t in self.tracks if t.confirmed)

    @property
    def reported(self) -> tuple[TrackEstimate, ...]:
        """The tracker's estimate of the targets: the confirmed tracks it does not withhold
        (what GOSPA scores; the planner plans for every confirmed track)."""
        return tuple(t for t in self.tracks if t.reported)

    def without_samples(self) -> TrackSet:
        """The same tracks without their posterior samples (what a run's record keeps)."""
        if all(t.samples is None for t in self.tracks):
            return self
        return replace(self, tracks=tuple(replace(t, samples=None) for t in self.tracks))


# --- the planner's answer ------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)  # one per epoch is kept for a run's record: small
class PlanReportData:
    epoch: int
    cost_kind: str
    criterion: str
    search: str
    horizon: int
    cost_names: tuple[str, ...] = ()
    predicted_costs: tuple[float, ...] = ()
    evaluations: int = 0
    wall_time_s: float = 0.0


@dataclass(frozen=True)
class Decision:
    """What the planner decided at ``epoch``: manoeuvres for the leg to epoch+1, beam
    pointings and the sensor selection for epoch+1 (``selected_sensor_ids`` None: every
    sensor measures), the plan report and strategy-specific ``extra`` data."""

    epoch: int
    commands: tuple[Command, ...] = ()
    beams: tuple[BeamCommand, ...] = ()
    selected_sensor_ids: tuple[str, ...] | None = None
    candidate_sensor_ids: tuple[str, ...] = ()
    selection_costs: tuple[float, ...] = ()
    selection_criterion: str = ""
    report: PlanReportData | None = None
    extra: dict = field(default_factory=dict)
