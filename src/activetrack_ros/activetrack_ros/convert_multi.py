"""Multi-target messages to the core's plain data (:mod:`activetrack.multitarget.data`) and back.

``scan_msg`` / ``scan_from_msg`` (msgs_defs/Scan), ``track_array_msg`` / ``track_array_from_msg``
(msgs_defs/TrackArray), ``beam_msg`` / ``beam_from_msg`` (msgs_defs/BeamCommand) and
``truth_array_msg`` / ``truth_array_from_msg`` (msgs_defs/GroundTruthArray). A round trip gives
the same numbers bit for bit: arrays travel as float64 and times are ``epoch x dt``, as the core
computes them (the stamp is checked against it, not used).

Each ``*_from_msg`` returns core data or raises :class:`MessageError`, a
:class:`~activetrack_ros.node_base.Rejected` (a node counts it as ``rejected.<reason>``, like
every other message) that is also a ValueError; its text names the field and what is allowed.
The single-target helpers (:mod:`activetrack_ros.convert`) do the field checks.
"""

from __future__ import annotations

import array
import functools
import math
from collections.abc import Callable
from typing import ParamSpec, TypeVar

import numpy as np
from geometry_msgs.msg import Point, Vector3

from activetrack import limits
from activetrack.models.clutter import ClutteredSensor
from activetrack.multitarget.data import (
    CONFIRMED,
    TENTATIVE,
    BeamCommand,
    FieldOfView,
    Scan,
    TrackEstimate,
    TrackSet,
    TruthSet,
)
from activetrack.scenarios.build import build_scan_sensors
from activetrack.scenarios.schema import Scenario
from activetrack_ros.convert import (
    FRAME_ID,
    MAX_SPEED,
    MAX_STATE_VALUE,
    _check_covariance,
    check_epoch_stamp,
    finite,
    header,
    pv_of,
    spd,
)
from activetrack_ros.node_base import Rejected
from msgs_defs.msg import BeamCommand as BeamCommandMsg
from msgs_defs.msg import GroundTruthArray, TrackArray, TrackItem
from msgs_defs.msg import Scan as ScanMsg

__all__ = [
    "MAX_SCAN_DETECTIONS",
    "MessageError",
    "SensorTable",
    "beam_from_msg",
    "beam_msg",
    "scan_from_msg",
    "scan_msg",
    "scan_sensors",
    "track_array_from_msg",
    "track_array_msg",
    "truth_array_from_msg",
    "truth_array_msg",
]

# Detections one scan may carry: Poisson clutter of mean <= MAX_CLUTTER_PER_SCAN stays below
# twice its mean (by ~100 standard deviations at the limit), plus one per target.
MAX_SCAN_DETECTIONS = int(2 * limits.MAX_CLUTTER_PER_SCAN) + limits.MAX_TARGETS
# |value| bounds of a detection's components (bearings are wrapped to [-pi, pi)).
_COMPONENT_LIMITS = {"bearing": math.pi + 1e-9, "range": limits.MAX_RANGE, "range_rate": MAX_SPEED}
_TWO_PI = 2.0 * math.pi
_ANGLE_TOLERANCE = 1e-9  # rad between a scan's field of view and the sensor's
_STATUS = {TENTATIVE: TrackItem.TENTATIVE, CONFIRMED: TrackItem.CONFIRMED}
_STATUS_NAME = {v: k for k, v in _STATUS.items()}

# sensor id -> (platform id, the sensor in clutter)
SensorTable = dict[str, tuple[str, ClutteredSensor]]
_P = ParamSpec("_P")
_T = TypeVar("_T")


class MessageError(Rejected, ValueError):
    """An invalid multi-target message: counted by the nodes like any Rejected, and a
    ValueError (naming the field and the allowed range) for code outside ROS."""


def _value_errors(fn: Callable[_P, _T]) -> Callable[_P, _T]:
    """Re-raise the shared helpers' Rejected as MessageError (same reason and detail)."""

    @functools.wraps(fn)
    def checked(*args: _P.args, **kwargs: _P.kwargs) -> _T:
        try:
            return fn(*args, **kwargs)
        except MessageError:
            raise
        except Rejected as e:
            raise MessageError(e.reason, e.detail) from None

    return checked


def _doubles(values) -> array.array:
    """float64 values as the array.array rclpy stores a float64[] field in (no per-item copy)."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=float).tobytes())
    return out


def _shown(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:40] + "...")


def scan_sensors(scenario: Scenario) -> SensorTable:
    """Every sensor of the scenario by id: ``(platform id, sensor in clutter)``, the models the
    simulator and tracker build (gate from ``tracker.tracks.gate_sigmas``)."""
    return build_scan_sensors(scenario)


# --- scans -------------------------------------------------------------------------------------


def scan_msg(
    scan: Scan,
    scenario: Scenario,
    epoch_scan_count: int = 0,
    frame_id: str = FRAME_ID,
    sensors: SensorTable | None = None,
) -> ScanMsg:
    """A core Scan as a Scan message; the sensor's platform, kind, R and clutter density come
    from the scenario (ValueError naming ``sensor_id`` if it has no such sensor). ``sensors``:
    :func:`scan_sensors` of the scenario, built once by a caller that converts many scans."""
    sensors = scan_sensors(scenario) if sensors is None else sensors
    if scan.sensor_id not in sensors:
        raise ValueError(f"sensor_id must be one of {sorted(sensors)}, got {scan.sensor_id!r}")
    platform_id, sensor = sensors[scan.sensor_id]
    pv, fov = scan.sensor_pv, scan.fov
    msg = ScanMsg(
        header=header(scan.time, frame_id),
        platform_id=platform_id,
        sensor_id=scan.sensor_id,
        sensor_kind=sensor.kind,
        epoch=scan.epoch,
        epoch_scan_count=epoch_scan_count,
        fov_centre=float(fov.centre),
        fov_width=float(fov.width),
        fov_r_min=float(fov.r_min),
        fov_r_max=float(fov.r_max),
        dim=int(sensor.dim_z),
        detections=_doubles(scan.Z),
        covariance=_doubles(sensor.R),
        clutter_density=float(sensor.clutter_density),
    )
    msg.sensor_position.x, msg.sensor_position.y = float(pv[0]), float(pv[2])
    msg.sensor_velocity.x, msg.sensor_velocity.y = float(pv[1]), float(pv[3])
    return msg


def _scan_sensor(msg: ScanMsg, sensors: SensorTable, what: str) -> ClutteredSensor:
    """The scan's sensor, with its platform, kind, R and clutter density as in the scenario."""
    if msg.sensor_id not in sensors:
        raise MessageError(
            "unknown_sensor", f"sensor_id {_shown(msg.sensor_id)} is not one of {sorted(sensors)}"
        )
    platform_id, sensor = sensors[msg.sensor_id]
    if msg.platform_id != platform_id:
        raise MessageError(
            "inconsistent", f"{what}: platform_id must be {platform_id!r} (the sensor's)"
        )
    if msg.sensor_kind != sensor.kind:
        raise MessageError("wrong_sensor_kind", f"{what}: sensor_kind must be {sensor.kind!r}")
    if msg.epoch_scan_count > len(sensors):
        raise MessageError(
            "out_of_range", f"{what}: epoch_scan_count must be <= {len(sensors)} (the sensors)"
        )
    if not math.isclose(msg.clutter_density, sensor.clutter_density, rel_tol=1e-9):
        raise MessageError(
            "sensor_mismatch",
            f"{what}: clutter_density {msg.clutter_density!r} is not the scenario's "
            f"{sensor.clutter_density!r}",
        )
    _check_covariance(msg, sensor, what)
    return sensor


def _detections(msg: ScanMsg, sensor: ClutteredSensor, what: str) -> np.ndarray:
    """The detections ``(m, dim)``: dim the sensor's, each component finite and in range."""
    n = int(sensor.dim_z)
    if msg.dim != n:
        raise MessageError(
            "wrong_dimension", f"{what}: dim must be {n} {list(sensor.components)}, got {msg.dim}"
        )
    count = len(msg.detections)
    if count % n or count > n * MAX_SCAN_DETECTIONS:
        raise MessageError(
            "wrong_dimension",
            f"{what}: detections must hold a multiple of dim {n} values, at most "
            f"{MAX_SCAN_DETECTIONS} detections, got {count} values",
        )
    Z = finite(msg.detections, f"{what} detections", MAX_STATE_VALUE).reshape(-1, n)
    for j, component in enumerate(sensor.components):
        limit = _COMPONENT_LIMITS.get(component, MAX_STATE_VALUE)
        finite(Z[:, j], f"{what} detections ({component})", limit)
    return Z


def _field_of_view(msg: ScanMsg, sensor: ClutteredSensor, pv, what: str) -> FieldOfView:
    """The scan's field of view: a sector in (0, 2 pi], and the sensor's (its beam pointed at
    fov_centre, or its fixed sector off the heading of ``pv``)."""
    finite((msg.fov_centre,), f"{what} fov_centre", math.pi + _ANGLE_TOLERANCE)
    finite((msg.fov_width,), f"{what} fov_width", _TWO_PI)
    if not 0.0 < msg.fov_width <= _TWO_PI:
        raise MessageError("out_of_range", f"{what}: fov_width must be in (0, 2 pi]")
    finite((msg.fov_r_min,), f"{what} fov_r_min", limits.MAX_RANGE)
    if math.isnan(msg.fov_r_max) or not 0.0 <= msg.fov_r_min <= msg.fov_r_max:
        raise MessageError(
            "out_of_range", f"{what}: need 0 <= fov_r_min <= fov_r_max (inf allowed)"
        )
    fov = FieldOfView(msg.fov_centre, msg.fov_width, msg.fov_r_min, msg.fov_r_max)
    expected = sensor.field_of_view(pv, msg.fov_centre if sensor.steerable else None)
    off = abs(math.remainder(fov.centre - expected.centre, _TWO_PI))
    same = (fov.width, fov.r_min, fov.r_max) == (expected.width, expected.r_min, expected.r_max)
    if not same or off > _ANGLE_TOLERANCE:
        raise MessageError(
            "sensor_mismatch",
            f"{what}: fov_centre/fov_width/fov_r_min/fov_r_max must be the sensor's field of "
            f"view {expected}",
        )
    return fov


@_value_errors
def scan_from_msg(msg: ScanMsg, scenario: Scenario, sensors: SensorTable | None = None) -> Scan:
    """A Scan message as a core Scan, every field checked against the scenario's sensor
    (``sensors``: :func:`scan_sensors` of the scenario, to build it once for many scans)."""
    what = f"scan of {_shown(msg.sensor_id)} epoch {msg.epoch}"
    sensors = scan_sensors(scenario) if sensors is None else sensors
    sensor = _scan_sensor(msg, sensors, what)
    if msg.epoch == 0:
        raise MessageError("out_of_order", f"{what}: epoch must be >= 1 (no scan at epoch 0)")
    check_epoch_stamp(msg, scenario, what)
    pv = pv_of(msg.sensor_position, msg.sensor_velocity, f"{what} sensor")
    Z = _detections(msg, sensor, what)
    fov = _field_of_view(msg, sensor, pv, what)
    return Scan(msg.sensor_id, msg.epoch, msg.epoch * scenario.dt, pv, Z, fov)


# --- track arrays ------------------------------------------------------------------------------


def _track_item(t: TrackEstimate) -> TrackItem:
    if t.status not in _STATUS:
        raise ValueError(f"status must be one of {sorted(_STATUS)}, got {t.status!r}")
    samples = np.empty((0, 4)) if t.samples is None else np.asarray(t.samples, dtype=float)
    return TrackItem(
        track_id=int(t.track_id),
        status=_STATUS[t.status],
        origin=t.origin,
        priority=float(t.priority),
        mean=np.asarray(t.mean, dtype=float).reshape(4),
        covariance=np.asarray(t.cov, dtype=float).reshape(16),
        hits=int(t.hits),
        misses=int(t.misses),
        age=int(t.age),
        ess=float(t.ess),
        samples=_doubles(samples),
        sample_count=int(samples.shape[0]),
    )


def track_array_msg(tracks: TrackSet, frame_id: str = FRAME_ID) -> TrackArray:
    """The tracker's TrackSet as a TrackArray message (pv means, 4x4 covariances)."""
    return TrackArray(
        header=header(tracks.time, frame_id),
        epoch=tracks.epoch,
        filter_kind=tracks.filter_kind,
        tracks=[_track_item(t) for t in tracks.tracks],
        detections=int(tracks.detections),
        unassociated=int(tracks.unassociated),
    )


def _track_from_item(item: TrackItem, scenario: Scenario, what: str) -> TrackEstimate:
    """One TrackItem: status, origin, priority, finite mean, SPD covariance, samples."""
    what = f"{what} track {item.track_id}"
    if item.status not in _STATUS_NAME:
        raise MessageError(
            "bad_field", f"{what}: status must be TENTATIVE (0) or CONFIRMED (1), got {item.status}"
        )
    targets = [t.id for t in scenario.targets or [scenario.target]]
    if item.origin and item.origin not in targets:
        raise MessageError(
            "bad_field",
            f"{what}: origin must be empty or one of {targets}, got {_shown(item.origin)}",
        )
    finite((item.priority,), f"{what} priority", 1e6)
    if item.priority <= 0:
        raise MessageError("out_of_range", f"{what}: priority must be > 0")
    if not math.isnan(item.ess):
        finite((item.ess,), f"{what} ess", limits.MAX_PARTICLES)
    mean = finite(item.mean, f"{what} mean", MAX_STATE_VALUE).copy()
    cov = finite(item.covariance, f"{what} covariance", MAX_STATE_VALUE**2).reshape(4, 4)
    samples = None
    max_samples = scenario.tracker.planner_samples
    if item.sample_count > max_samples or len(item.samples) != 4 * item.sample_count:
        raise MessageError(
            "wrong_dimension",
            f"{what}: sample_count must be <= {max_samples} with sample_count x 4 samples, got "
            f"{item.sample_count} and {len(item.samples)}",
        )
    if item.sample_count:
        samples = finite(item.samples, f"{what} samples", MAX_STATE_VALUE).reshape(-1, 4)
    return TrackEstimate(
        track_id=item.track_id,
        status=_STATUS_NAME[item.status],
        mean=mean,
        cov=spd(cov.copy(), what),
        origin=item.origin,
        priority=item.priority,
        age=item.age,
        hits=item.hits,
        misses=item.misses,
        ess=item.ess,
        samples=samples,
    )


@_value_errors
def track_array_from_msg(msg: TrackArray, scenario: Scenario) -> TrackSet:
    """A TrackArray message as a TrackSet: the scenario's filter, unique track ids, at most
    ``max_tracks`` (plus the targets' prior tracks), each track checked."""
    what = f"track array epoch {msg.epoch}"
    if msg.filter_kind != scenario.tracker.filter:
        raise MessageError(
            "bad_field", f"{what}: filter_kind must be {scenario.tracker.filter!r} (tracker.filter)"
        )
    most = scenario.tracker.tracks.max_tracks + len(scenario.targets or [scenario.target])
    if len(msg.tracks) > most:
        raise MessageError("out_of_range", f"{what}: tracks must hold at most {most} tracks")
    ids = [item.track_id for item in msg.tracks]
    if len(set(ids)) != len(ids):
        raise MessageError("bad_field", f"{what}: track_id must be unique among tracks")
    if msg.unassociated > msg.detections:
        raise MessageError("out_of_range", f"{what}: unassociated must be <= detections")
    check_epoch_stamp(msg, scenario, what)
    tracks = tuple(_track_from_item(item, scenario, what) for item in msg.tracks)
    return TrackSet(
        epoch=msg.epoch,
        time=msg.epoch * scenario.dt,
        filter_kind=msg.filter_kind,
        tracks=tracks,
        detections=msg.detections,
        unassociated=msg.unassociated,
    )


# --- beam commands -----------------------------------------------------------------------------


def beam_msg(beam: BeamCommand, scenario: Scenario, frame_id: str = FRAME_ID) -> BeamCommandMsg:
    """A planner's BeamCommand as a message stamped with its decision epoch's time."""
    return BeamCommandMsg(
        header=header(beam.epoch * scenario.dt, frame_id),
        sensor_id=beam.sensor_id,
        epoch=beam.epoch,
        bearing=float(beam.bearing),
        track_id=int(beam.track_id),
    )


@_value_errors
def beam_from_msg(msg: BeamCommandMsg, scenario: Scenario) -> BeamCommand:
    """A BeamCommand message as core data: a steerable sensor (one with ``beam_width``), a
    decision epoch before the last, a finite bearing, track_id >= -1."""
    steerable = sorted(s.id for p in scenario.platforms for s in p.sensors if s.beam_width)
    what = f"beam command of {_shown(msg.sensor_id)} epoch {msg.epoch}"
    if msg.sensor_id not in steerable:
        raise MessageError(
            "unknown_sensor",
            f"sensor_id must be a steerable sensor (beam_width), one of {steerable}, got "
            f"{_shown(msg.sensor_id)}",
        )
    if msg.epoch >= scenario.steps:
        raise MessageError(
            "future_epoch", f"{what}: epoch must be < steps {scenario.steps} (a decision epoch)"
        )
    check_epoch_stamp(msg, scenario, what)
    finite((msg.bearing,), f"{what} bearing", limits.MAX_ANGLE)
    if msg.track_id < -1:
        raise MessageError("out_of_range", f"{what}: track_id must be >= -1 (-1: no track)")
    return BeamCommand(msg.sensor_id, msg.epoch, msg.bearing, msg.track_id)


# --- truth -------------------------------------------------------------------------------------


def truth_array_msg(truth: TruthSet, frame_id: str = FRAME_ID) -> GroundTruthArray:
    """Every alive target's truth at an epoch as a GroundTruthArray message."""
    msg = GroundTruthArray(
        header=header(truth.time, frame_id), epoch=truth.epoch, target_ids=list(truth.ids)
    )
    pv = np.asarray(truth.pv, dtype=float).reshape(-1, 4)
    msg.positions = [Point(x=x, y=y) for x, y in pv[:, [0, 2]].tolist()]
    msg.velocities = [Vector3(x=vx, y=vy) for vx, vy in pv[:, [1, 3]].tolist()]
    return msg


@_value_errors
def truth_array_from_msg(msg: GroundTruthArray, scenario: Scenario) -> TruthSet:
    """A GroundTruthArray message as a TruthSet: target ids of the scenario, each once and in
    scenario order, one finite position and velocity per id."""
    what = f"truth array epoch {msg.epoch}"
    order = [t.id for t in scenario.targets or [scenario.target]]
    ids = list(msg.target_ids)
    rank = [order.index(i) if i in order else -1 for i in ids]
    if -1 in rank or rank != sorted(set(rank)):
        raise MessageError(
            "bad_field",
            f"{what}: target_ids must be distinct ids of {order} in that order, got "
            f"{[_shown(i) for i in ids[:8]]}",
        )
    if len(msg.positions) != len(ids) or len(msg.velocities) != len(ids):
        raise MessageError(
            "wrong_dimension", f"{what}: positions and velocities need one entry per target id"
        )
    check_epoch_stamp(msg, scenario, what)
    pv = np.array(
        [
            pv_of(p, v, f"{what} target {i}")
            for i, p, v in zip(ids, msg.positions, msg.velocities, strict=True)
        ]
    ).reshape(-1, 4)
    return TruthSet(msg.epoch, msg.epoch * scenario.dt, tuple(ids), pv)
