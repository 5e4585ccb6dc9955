"""Plain data crossing the closed loop's component boundaries (docs/closed-loop.md).

Each maps one to one onto a msgs_defs message, so the ROS nodes only convert.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


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
class TrackSnapshot:
    """The tracker's posterior after the update at ``epoch``."""

    epoch: int
    time: float
    filter_kind: str
    motion_model: str
    state_names: tuple[str, ...]
    mean: np.ndarray  # (n,)
    cov: np.ndarray  # (n, n)
    samples: np.ndarray | None = None  # (N, n) equally weighted posterior samples (PF)
    update_count: int = 0
    missed_detections: int = 0
    nis: float = math.nan
    ess: float = math.nan
    particle_count: int = 0


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
    """What the planner decided at ``epoch``: commands, selection for epoch+1, report."""

    epoch: int
    commands: tuple[Command, ...]
    selected_sensor_ids: tuple[str, ...] | None = None  # None: selection off (all measure)
    candidate_sensor_ids: tuple[str, ...] = ()
    selection_costs: tuple[float, ...] = ()
    selection_criterion: str = ""
    report: PlanReportData | None = None
    extra: dict = field(default_factory=dict)


def heading_speed(pv: np.ndarray) -> tuple[float, float]:
    """Heading (rad from +x, counter-clockwise) and speed of a pv state."""
    return math.atan2(pv[3], pv[1]), math.hypot(pv[1], pv[3])
