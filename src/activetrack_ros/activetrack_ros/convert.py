"""Messages (msgs_defs) to the core's plain data (:mod:`activetrack.data`) and back: a
``*_msg`` / ``*_from_msg`` pair per message type, every field checked on the way in.

A round trip gives the same numbers bit for bit: arrays travel as float64 and times are
``epoch x dt``, as the core computes them (the stamp is checked against it, not used). Each
``*_from_msg`` returns core data or raises :class:`MessageError` naming the field and what is
allowed. Shared by the nodes, the runner's evaluator and the bag tools, so one message is
judged the same way everywhere.
"""

from __future__ import annotations

import array
import itertools
import math
import sys

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import Point, Vector3
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker

from activetrack import limits
from activetrack.closed_loop.components import scene_sensors, scene_targets
from activetrack.data import (
    CONFIRMED,
    TENTATIVE,
    BeamCommand,
    Command,
    Decision,
    PlanReportData,
    PlatformSnapshot,
    Scan,
    TrackEstimate,
    TrackSet,
    TruthSet,
)
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.fov import FieldOfView
from activetrack.scenarios.build import build_motion_model
from activetrack.scenarios.schema import Scenario
from activetrack.scenarios.tracking import TrackingConfig
from activetrack_ros import graph as topics
from activetrack_ros import sizes
from activetrack_ros.node_base import Rejected
from msgs_defs.msg import BeamCommand as BeamCommandMsg
from msgs_defs.msg import (
    GroundTruthArray,
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    SensorSelection,
    TrackArray,
    TrackItem,
)
from msgs_defs.msg import Scan as ScanMsg

# Plausibility limits for values arriving on topics (a sensor 1e300 m away is not a sensor):
# the scenario files' limits, so nothing a valid scenario produces is ever refused.
MAX_COORDINATE = limits.MAX_POSITION  # m, positions
MAX_SPEED = limits.MAX_SPEED  # m/s, velocities, range rates
MAX_STATE_VALUE = 1e12  # any track or truth state entry (estimates may overshoot positions)
STAMP_TOLERANCE = 1e-6  # s between a stamp and its epoch time k T
FRAME_ID = topics.FIXED_FRAME  # the default; each node takes its frame_id parameter
MAX_SCAN_DETECTIONS = limits.MAX_SCAN_DETECTIONS  # detections one scan may carry
# |value| bounds of a detection's components by their names (bearings are wrapped to [-pi,
# pi)); a component of another name (a plugin sensor's) is only bounded by MAX_STATE_VALUE.
_COMPONENT_LIMITS = {"bearing": math.pi + 1e-9, "range": limits.MAX_RANGE, "range_rate": MAX_SPEED}
_TWO_PI = 2.0 * math.pi
_ANGLE_TOLERANCE = 1e-9  # rad between a scan's field of view and the sensor's
_FOV_FIELDS = ("centre", "width", "r_min", "r_max")  # a Scan's fov_<name>: FieldOfView.<name>
_STATUS = {TENTATIVE: TrackItem.TENTATIVE, CONFIRMED: TrackItem.CONFIRMED}
_STATUS_NAME = {v: k for k, v in _STATUS.items()}
# TrackItem fields copied as they are from and to the TrackEstimate field of the same name.
_TRACK_COUNTS = ("hits", "misses", "missed_detections", "age", "particle_count")
_TRACK_FLOATS = ("priority", "existence", "nis", "ess")
# PlanReport fields of a PlanReportData field of the same name (labels: interned on the way in).
_REPORT_COUNTS = ("epoch", "horizon", "evaluations")
_REPORT_LABELS = ("cost_kind", "criterion", "search")
_ARRAY_COUNTS = ("updates", "detections", "unassociated")  # of a TrackArray and a TrackSet

# sensor id -> (platform id, the sensor in the scene)
SensorTable = dict[str, tuple[str, ClutteredSensor]]


class MessageError(Rejected, ValueError):
    """An invalid message: a Rejected for the nodes, a ValueError outside ROS."""


# --- shared helpers ----------------------------------------------------------------------------


def header(seconds: float, frame_id: str = FRAME_ID) -> Header:
    """A header stamped with sim time ``seconds`` (>= 0) in the fixed frame ``frame_id``."""
    sec = math.floor(seconds)
    nanosec = min(round((seconds - sec) * 1e9), 999_999_999)
    return Header(stamp=TimeMsg(sec=int(sec), nanosec=int(nanosec)), frame_id=frame_id)


def marker(hdr: Header, ns: str, id_: int, kind: int, rgba, points=()) -> Marker:
    """A Marker to ADD (identity pose, colour ``rgba``, plane ``points``); the caller scales it."""
    m = Marker(header=hdr, ns=ns, id=id_, type=kind, action=Marker.ADD)
    m.pose.orientation.w = 1.0
    m.color = ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
    # (as Python floats in one go: a float() per numpy scalar doubled the time of an ellipse)
    m.points = [Point(x=x, y=y) for x, y in np.asarray(points, dtype=float).reshape(-1, 2).tolist()]
    return m


def check_epoch_stamp(msg, scenario: Scenario | TrackingConfig, what: str) -> float:
    """The epoch is within the run and the stamp a valid time k T for it; returns the stamp."""
    if scenario.steps is not None and msg.epoch > scenario.steps:
        raise MessageError("future_epoch", f"{what}: epoch {msg.epoch} > steps {scenario.steps}")
    stamp = msg.header.stamp
    if stamp.sec < 0 or not 0 <= stamp.nanosec < 1_000_000_000:
        raise MessageError(
            "bad_stamp",
            f"{what}: header.stamp must be sec >= 0, 0 <= nanosec < 1e9, got "
            f"({stamp.sec}, {stamp.nanosec})",
        )
    t = stamp.sec + stamp.nanosec * 1e-9
    if abs(t - msg.epoch * scenario.dt) > STAMP_TOLERANCE:
        raise MessageError(
            "bad_stamp", f"{what}: stamp {t} s is not epoch {msg.epoch} x dt {scenario.dt} s"
        )
    return t


def finite(values, what: str, limit: float) -> np.ndarray:
    """``values`` as a float array, all finite and within +-limit, else MessageError."""
    a = np.asarray(values, dtype=float)
    # (the methods, not np.all / np.max: their dispatch was a third of a track item's check)
    if not np.isfinite(a).all():
        raise MessageError("non_finite", f"{what} must be finite")
    if a.size and np.abs(a).max() > limit:
        raise MessageError("out_of_range", f"{what} must be within +-{limit:g}")
    return a


def pv_of(position, velocity, what: str) -> np.ndarray:
    """(x, xdot, y, ydot) from a Point and a Vector3, checked."""
    finite((position.x, position.y), f"{what} position", MAX_COORDINATE)
    finite((velocity.x, velocity.y), f"{what} velocity", MAX_SPEED)
    return np.array([position.x, velocity.x, position.y, velocity.y], dtype=float)


def spd(P: np.ndarray, what: str) -> np.ndarray:
    """A symmetric positive definite covariance, else MessageError("bad_covariance")."""
    if not _symmetric(P):
        raise MessageError("bad_covariance", f"{what} covariance is not symmetric")
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        raise MessageError(
            "bad_covariance", f"{what} covariance is not positive definite"
        ) from None
    return P


def _symmetric(P: np.ndarray) -> bool:
    """``np.allclose(P, P.T, rtol=1e-9, atol=0)`` by its own formula (``|a - b| <= rtol |b|``
    where b is finite, or a == b): the same verdict, a fifth of the time on a 4 x 4 (spd checks
    two per track item, and the planner and the evaluator each read every track array); P may
    be a stack ``(..., n, n)``, each matrix against its own transpose."""
    T = np.swapaxes(P, -1, -2)
    return bool(((np.abs(P - T) <= 1e-9 * np.abs(T)) & np.isfinite(T) | (P == T)).all())


def _doubles(values) -> array.array:
    """float64 values as the array.array rclpy stores a float64[] field in (no per-item copy)."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=float).tobytes())
    return out


def _shown(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:40] + "...")


def _check_known(name: str, known, reason: str, field: str = "") -> None:
    """``name`` is one of ``known``, else MessageError(reason) listing them."""
    if name not in known:
        raise MessageError(reason, f"{field}{_shown(name)} is not one of {sorted(known)}")


# --- platforms and their commands --------------------------------------------------------------


def platform_state_msg(s: PlatformSnapshot, scan_count: int, frame_id: str) -> PlatformState:
    """A platform's state at an epoch; ``scan_count``: the scans the sim published at it."""
    return PlatformState(
        header=header(s.time, frame_id),
        platform_id=s.platform_id,
        epoch=s.epoch,
        sensor_ids=list(s.sensor_ids),
        sensor_kinds=list(s.sensor_kinds),
        position=Point(x=float(s.pv[0]), y=float(s.pv[2])),
        velocity=Vector3(x=float(s.pv[1]), y=float(s.pv[3])),
        heading=float(s.heading),
        speed=float(s.speed),
        epoch_scan_count=int(scan_count),
    )


def platform_from_msg(msg, scenario: Scenario | TrackingConfig, platform_ids) -> PlatformSnapshot:
    """A PlatformState as a PlatformSnapshot (epoch, stamp, ids and kinematics checked)."""
    what = f"platform state of {_shown(msg.platform_id)}"
    _check_known(msg.platform_id, platform_ids, "unknown_platform")
    t = check_epoch_stamp(msg, scenario, what)
    platform = next(p for p in scenario.platforms if p.id == msg.platform_id)
    expected = ([s.id for s in platform.sensors], [s.kind for s in platform.sensors])
    if (list(msg.sensor_ids), list(msg.sensor_kinds)) != expected:
        raise MessageError(
            "sensor_mismatch", f"{what}: sensors {list(msg.sensor_ids)[:8]} are not the scenario's"
        )
    if msg.epoch_scan_count > sum(len(p.sensors) for p in scenario.platforms):
        raise MessageError("out_of_range", f"{what}: epoch_scan_count exceeds the sensors")
    pv = pv_of(msg.position, msg.velocity, what)
    finite((msg.heading,), f"{what} heading", 4 * math.pi)
    finite((msg.speed,), f"{what} speed", MAX_SPEED)
    ids, kinds = tuple(msg.sensor_ids), tuple(msg.sensor_kinds)
    return PlatformSnapshot(msg.platform_id, msg.epoch, t, pv, msg.heading, msg.speed, ids, kinds)


def command_msg(cmd: Command, dt: float, frame_id: str) -> ManoeuvreCommand:
    """A planner's command as a ManoeuvreCommand stamped with its decision epoch's time."""
    msg = ManoeuvreCommand(
        header=header(cmd.epoch * dt, frame_id),
        platform_id=cmd.platform_id,
        epoch=cmd.epoch,
        heading_change=float(cmd.heading_change),
        speed_change=float(cmd.speed_change),
        commanded_heading=float(cmd.commanded_heading),
        commanded_speed=float(cmd.commanded_speed),
        gate_measurement=cmd.take_measurement is not None,
        take_measurement=bool(cmd.take_measurement),
        has_waypoint=cmd.waypoint is not None,
    )
    if cmd.waypoint is not None:
        msg.waypoint = Point(x=float(cmd.waypoint[0]), y=float(cmd.waypoint[1]))
    return msg


def command_from_msg(
    msg: ManoeuvreCommand, scenario: Scenario, epoch: int, controllable
) -> Command:
    """A ManoeuvreCommand for one of the ``controllable`` platforms as a Command of ``epoch``
    (the sim's current one); the message's epoch is the caller's (the mode's) business."""
    what = f"command for {_shown(msg.platform_id)}"
    _check_known(msg.platform_id, controllable, "unknown_platform")
    check_epoch_stamp(msg, scenario, what)
    # A heading change beyond half a turn or a speed change beyond the platform's whole speed
    # range is not a command to clamp but garbage: reject it.
    finite((msg.heading_change,), f"{what} heading_change", math.pi + 1e-9)
    platform = next(p for p in scenario.platforms if p.id == msg.platform_id)
    v_max = platform.limits.v_max if platform.limits is not None else MAX_SPEED
    finite((msg.speed_change,), f"{what} speed_change", min(v_max, MAX_SPEED))
    return Command(
        msg.platform_id,
        epoch,
        msg.heading_change,
        msg.speed_change,
        take_measurement=msg.take_measurement if msg.gate_measurement else None,
    )


def selection_msg(epoch: int, dt: float, frame_id: str, decision: Decision) -> SensorSelection:
    """The sensors the decision of ``epoch`` chose to measure at epoch + 1."""
    return SensorSelection(
        header=header(epoch * dt, frame_id),
        epoch=epoch,
        selected_sensor_ids=list(decision.selected_sensor_ids),
        candidate_sensor_ids=list(decision.candidate_sensor_ids),
        predicted_cost=[float(c) for c in decision.selection_costs],
        criterion=decision.selection_criterion,
    )


def selection_from_msg(msg: SensorSelection, scenario: Scenario, sensor_ids) -> tuple[str, ...]:
    """A SensorSelection's chosen sensors: 1..count distinct sensors of the scenario."""
    check_epoch_stamp(msg, scenario, "selection")
    ids = list(msg.selected_sensor_ids)
    unknown = [s for s in ids if s not in sensor_ids]
    if unknown:
        raise MessageError("unknown_sensor", f"selection names {[_shown(s) for s in unknown[:5]]}")
    count = scenario.planner.selection.count
    if len(set(ids)) != len(ids) or not 1 <= len(ids) <= count:
        raise MessageError("bad_selection", f"selection must name 1..{count} distinct sensors")
    return tuple(ids)


# --- scans -------------------------------------------------------------------------------------


def scan_msg(
    scan: Scan,
    scenario: Scenario | TrackingConfig,
    epoch_scan_count: int = 0,
    frame_id: str = FRAME_ID,
    sensors: SensorTable | None = None,
) -> ScanMsg:
    """A core Scan as a Scan message with its sensor's platform, kind, R and clutter density
    (ValueError naming ``sensor_id`` for an unknown sensor). ``sensors``: the scene's sensors
    (:func:`~activetrack.closed_loop.components.scene_sensors`), built once for many scans."""
    sensors = scene_sensors(scenario) if sensors is None else sensors
    if scan.sensor_id not in sensors:
        raise ValueError(f"sensor_id must be one of {sorted(sensors)}, got {scan.sensor_id!r}")
    platform_id, sensor = sensors[scan.sensor_id]
    pv = scan.sensor_pv
    msg = ScanMsg(
        header=header(scan.time, frame_id),
        platform_id=platform_id,
        sensor_id=scan.sensor_id,
        sensor_kind=sensor.kind,
        epoch=scan.epoch,
        epoch_scan_count=epoch_scan_count,
        dim=int(sensor.dim_z),
        detections=_doubles(scan.Z),
        covariance=_doubles(sensor.R),
        clutter_density=float(sensor.clutter_density),
        **{f"fov_{name}": float(getattr(scan.fov, name)) for name in _FOV_FIELDS},
    )
    msg.sensor_position.x, msg.sensor_position.y = float(pv[0]), float(pv[2])
    msg.sensor_velocity.x, msg.sensor_velocity.y = float(pv[1]), float(pv[3])
    return msg


def _scan_sensor(msg: ScanMsg, sensors: SensorTable, what: str) -> ClutteredSensor:
    """The scan's sensor, with its platform, kind, clutter density and R as in the scenario."""
    _check_known(msg.sensor_id, sensors, "unknown_sensor", "sensor_id ")
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
    n = int(sensor.dim_z)  # covariance: the sensor's R (n x n, SPD)
    if len(msg.covariance) != n * n:
        raise MessageError("bad_covariance", f"{what}: covariance must have {n * n} values")
    R = spd(finite(msg.covariance, f"{what} covariance", math.inf).reshape(n, n), what)
    if not np.allclose(R, sensor.R, rtol=1e-9, atol=0.0):
        raise MessageError("sensor_mismatch", f"{what}: covariance differs from the scenario's R")
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


def scan_from_msg(
    msg: ScanMsg, scenario: Scenario | TrackingConfig, sensors: SensorTable | None = None
) -> Scan:
    """A Scan message as a core Scan, checked against its sensor; ``sensors`` as in scan_msg."""
    what = f"scan of {_shown(msg.sensor_id)} epoch {msg.epoch}"
    sensors = scene_sensors(scenario) if sensors is None else sensors
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
    n = int(np.asarray(t.state).shape[0])
    samples = np.empty((0, n)) if t.samples is None else np.asarray(t.samples, dtype=float)
    return TrackItem(
        track_id=int(t.track_id),
        status=_STATUS[t.status],
        origin=t.origin,
        state=_doubles(t.state),
        state_covariance=_doubles(t.state_cov),
        mean=np.asarray(t.mean, dtype=float).reshape(4),
        covariance=np.asarray(t.cov, dtype=float).reshape(16),
        samples=_doubles(samples),
        sample_count=int(samples.shape[0]),
        withheld=bool(t.withheld),
        **{name: int(getattr(t, name)) for name in _TRACK_COUNTS},
        **{name: float(getattr(t, name)) for name in _TRACK_FLOATS},
    )


def track_array_msg(tracks: TrackSet, frame_id: str = FRAME_ID) -> TrackArray:
    """The tracker's TrackSet as a TrackArray message."""
    return TrackArray(
        header=header(tracks.time, frame_id),
        epoch=tracks.epoch,
        filter_kind=tracks.filter_kind,
        motion_model=tracks.motion_model,
        state_names=list(tracks.state_names),
        tracks=[_track_item(t) for t in tracks.tracks],
        **{name: int(getattr(tracks, name)) for name in _ARRAY_COUNTS},
    )


class TrackArrayChecker:
    """Validates TrackArray messages against what the scenario's tracker publishes."""

    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        motion = scenario.tracker.motion or scenario.target.motion
        self.motion_model = motion.model
        self.state_names = tuple(build_motion_model(motion).state_names)
        self.targets = [t.id for t in scene_targets(scenario)]
        self.max_samples = scenario.tracker.planner_samples
        self.most = sizes.most_tracks(scenario)

    def __call__(self, msg: TrackArray) -> TrackSet:
        what = f"track array epoch {msg.epoch}"
        cfg = self.scenario.tracker
        if msg.filter_kind != cfg.filter:
            raise MessageError(
                "bad_field", f"{what}: filter_kind must be {cfg.filter!r} (tracker.filter)"
            )
        if msg.motion_model != self.motion_model or tuple(msg.state_names) != self.state_names:
            raise MessageError(
                "wrong_dimension",
                f"{what}: motion_model and state_names must be {self.motion_model!r} "
                f"{list(self.state_names)}, got {_shown(msg.motion_model)} "
                f"{list(msg.state_names)[:8]}",
            )
        if len(msg.tracks) > self.most:
            raise MessageError("out_of_range", f"{what}: tracks must hold at most {self.most}")
        ids = [item.track_id for item in msg.tracks]
        if len(set(ids)) != len(ids):
            raise MessageError("bad_field", f"{what}: track_id must be unique among tracks")
        if msg.unassociated > msg.detections:
            raise MessageError("out_of_range", f"{what}: unassociated must be <= detections")
        check_epoch_stamp(msg, self.scenario, what)
        return TrackSet(
            epoch=msg.epoch,
            time=msg.epoch * self.scenario.dt,
            filter_kind=msg.filter_kind,
            motion_model=msg.motion_model,
            state_names=self.state_names,
            tracks=self._tracks(msg.tracks, what),
            **{name: getattr(msg, name) for name in _ARRAY_COUNTS},
        )

    def _tracks(self, items, what: str) -> tuple[TrackEstimate, ...]:
        """Every item by :meth:`_track`, then their covariances checked SPD all at once
        (:func:`_spd_all`; one by one they were a third of the check, which the planner and
        the evaluator each run on every track array). The first error is the one the items
        checked in turn would raise: an item's failure first checks the covariances of the
        items before it."""
        tracks: list[TrackEstimate] = []
        for item in items:
            try:
                tracks.append(self._track(item, what))
            except Exception:
                _spd_all(tracks, what)
                raise
        _spd_all(tracks, what)
        return tuple(tracks)

    def _track(self, item: TrackItem, what: str) -> TrackEstimate:
        """One TrackItem: status, origin, priority, finite state and pv (its covariances SPD:
        :func:`_spd_all`, for all items at once)."""
        what = f"{what} track {item.track_id}"
        n = len(self.state_names)
        if item.status not in _STATUS_NAME:
            raise MessageError(
                "bad_field",
                f"{what}: status must be TENTATIVE (0) or CONFIRMED (1), got {item.status}",
            )
        if item.origin and item.origin not in self.targets:
            raise MessageError(
                "bad_field",
                f"{what}: origin must be empty or one of {self.targets}, got {_shown(item.origin)}",
            )
        finite((item.priority,), f"{what} priority", 1e6)
        if item.priority <= 0:
            raise MessageError("out_of_range", f"{what}: priority must be > 0")
        for name in ("ess", "nis"):
            value = getattr(item, name)
            if not math.isnan(value):
                finite((value,), f"{what} {name}", limits.MAX_PARTICLES)
        if not 0.0 <= item.existence <= 1.0:
            raise MessageError("out_of_range", f"{what}: existence must be in [0, 1]")
        if item.withheld and _STATUS_NAME[item.status] != CONFIRMED:
            raise MessageError("bad_field", f"{what}: withheld must be false on a TENTATIVE track")
        if len(item.state) != n or len(item.state_covariance) != n * n:
            raise MessageError(
                "wrong_dimension", f"{what}: state must have {n} values, state_covariance {n * n}"
            )
        if item.sample_count > self.max_samples or len(item.samples) != n * item.sample_count:
            raise MessageError(
                "wrong_dimension",
                f"{what}: sample_count must be <= {self.max_samples} with sample_count x {n} "
                f"samples, got {item.sample_count} and {len(item.samples)}",
            )
        state = finite(item.state, f"{what} state", MAX_STATE_VALUE).copy()
        state_cov = finite(item.state_covariance, f"{what} state_covariance", MAX_STATE_VALUE**2)
        mean = finite(item.mean, f"{what} mean", MAX_STATE_VALUE).copy()
        cov = finite(item.covariance, f"{what} covariance", MAX_STATE_VALUE**2).reshape(4, 4)
        samples = None
        if item.sample_count:
            samples = finite(item.samples, f"{what} samples", MAX_STATE_VALUE).reshape(-1, n)
        return TrackEstimate(
            track_id=item.track_id,
            status=_STATUS_NAME[item.status],
            mean=mean,
            cov=cov.copy(),
            state=state,
            state_cov=state_cov.reshape(n, n).copy(),
            origin=item.origin,
            samples=samples,
            withheld=bool(item.withheld),
            **{name: getattr(item, name) for name in (*_TRACK_COUNTS, *_TRACK_FLOATS)},
        )


def _spd_all(tracks: list[TrackEstimate], what: str) -> None:
    """:func:`spd` of each track's ``cov`` then ``state_cov``, in turn, with its error: in
    one batch (allclose's formula and a Cholesky of the stack), and only if that fails track
    by track for the first error."""
    if not tracks:
        return
    for stack in (np.stack([t.cov for t in tracks]), np.stack([t.state_cov for t in tracks])):
        if not _symmetric(stack):
            break
        try:
            np.linalg.cholesky(stack)
        except np.linalg.LinAlgError:
            break
    else:
        return
    for t in tracks:
        spd(t.cov, f"{what} track {t.track_id}")
        spd(t.state_cov, f"{what} track {t.track_id}")


def track_array_from_msg(msg: TrackArray, scenario: Scenario) -> TrackSet:
    """A TrackArray message as a TrackSet (:class:`TrackArrayChecker`, built for one call)."""
    return TrackArrayChecker(scenario)(msg)


# --- beam commands -----------------------------------------------------------------------------


def beam_msg(beam: BeamCommand, dt: float, frame_id: str = FRAME_ID) -> BeamCommandMsg:
    """A planner's BeamCommand as a message stamped with its decision epoch's time."""
    return BeamCommandMsg(
        header=header(beam.epoch * dt, frame_id),
        sensor_id=beam.sensor_id,
        epoch=beam.epoch,
        bearing=float(beam.bearing),
        track_id=int(beam.track_id),
    )


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
    msg.state_sizes = [len(x) for x in truth.states]
    msg.state_names = [name for names in truth.state_names for name in names]
    msg.states = _doubles(np.concatenate([np.ravel(x) for x in truth.states] or [np.empty(0)]))
    return msg


def truth_array_from_msg(msg: GroundTruthArray, scenario: Scenario) -> TruthSet:
    """A GroundTruthArray message as a TruthSet: target ids of the scenario, each once and in
    scenario order, one finite position and velocity per id, each target's state in its
    motion model's coordinates."""
    what = f"truth array epoch {msg.epoch}"
    targets = scene_targets(scenario)
    order = [t.id for t in targets]
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
    names = [tuple(build_motion_model(targets[r].motion).state_names) for r in rank]
    every_name = [name for n in names for name in n]
    if list(msg.state_sizes) != [len(n) for n in names] or list(msg.state_names) != every_name:
        raise MessageError(
            "wrong_dimension", f"{what}: state_sizes and state_names must be the targets' models'"
        )
    if len(msg.states) != sum(len(n) for n in names):
        raise MessageError("wrong_dimension", f"{what}: states must hold every target's state")
    check_epoch_stamp(msg, scenario, what)
    kinematics = zip(ids, msg.positions, msg.velocities, strict=True)
    pv = np.array([pv_of(p, v, f"{what} target {i}") for i, p, v in kinematics]).reshape(-1, 4)
    flat = finite(msg.states, f"{what} states", MAX_STATE_VALUE)
    cuts = np.cumsum([0, *(len(n) for n in names)])
    states = tuple(flat[a:b].copy() for a, b in itertools.pairwise(cuts))
    return TruthSet(msg.epoch, msg.epoch * scenario.dt, tuple(ids), pv, states, tuple(names))


# --- plan reports ------------------------------------------------------------------------------


def report_msg(r: PlanReportData, hdr: Header) -> PlanReport:
    """The planner's report of a decision as a PlanReport message."""
    return PlanReport(
        header=hdr,
        cost_names=list(r.cost_names),
        predicted_costs=[float(v) for v in r.predicted_costs],
        planning_wall_time=r.wall_time_s,
        **{name: getattr(r, name) for name in (*_REPORT_COUNTS, *_REPORT_LABELS)},
    )


def report_from_msg(msg: PlanReport, scenario: Scenario) -> PlanReportData:
    """A PlanReport as PlanReportData (epoch < steps, finite costs, one per cost name). Its
    repeated strings are interned: a run's record keeps one report per epoch."""
    if msg.epoch >= scenario.steps:
        raise MessageError("future_epoch", f"plan report of epoch {msg.epoch}")
    check_epoch_stamp(msg, scenario, "plan report")
    costs = finite(msg.predicted_costs, "predicted_costs", math.inf)
    if len(costs) != len(msg.cost_names):
        raise MessageError("wrong_dimension", "predicted_costs and cost_names differ in length")
    finite((msg.planning_wall_time,), "planning_wall_time", 1e9)
    return PlanReportData(
        cost_names=tuple(sys.intern(n) for n in msg.cost_names),
        predicted_costs=tuple(costs.tolist()),
        wall_time_s=msg.planning_wall_time,
        **{name: getattr(msg, name) for name in _REPORT_COUNTS},
        **{name: sys.intern(getattr(msg, name)) for name in _REPORT_LABELS},
    )
