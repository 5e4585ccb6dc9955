"""Messages to the core's plain data and back, validating every field on the way in.

Each ``*_from_msg`` either returns core data or raises :class:`Rejected` with a reason and a
detail naming the field and what is allowed. Shared by the nodes and the runner's evaluator, so
one message is judged the same way everywhere.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker

from activetrack import limits
from activetrack.closed_loop.data import PlanReportData, PlatformSnapshot, TrackSnapshot
from activetrack.filters.measurement import Measurement
from activetrack.filters.registry import filter_names
from activetrack.scenarios.build import build_motion_model
from activetrack.scenarios.schema import Scenario
from activetrack_ros import graph as topics
from activetrack_ros.node_base import Rejected
from msgs_defs.msg import PlanReport

# Plausibility limits for values arriving on topics (a sensor 1e300 m away is not a sensor):
# the scenario files' limits, so nothing a valid scenario produces is ever refused.
MAX_COORDINATE = limits.MAX_POSITION  # m, positions
MAX_SPEED = limits.MAX_SPEED  # m/s, velocities, range rates
MAX_STATE_VALUE = 1e12  # any track or truth state entry (estimates may overshoot positions)
STAMP_TOLERANCE = 1e-6  # s between a stamp and its epoch time k T
FRAME_ID = topics.FIXED_FRAME  # the default; each node takes its frame_id parameter
# Sensor kinds with a typed message; every other kind (a registered one, docs/extending.md)
# travels as the generic Measurement on its own topic.
BEARING_KINDS = ("bearing", "ambiguous_bearing")
POLAR_KINDS = ("range_bearing", "range_rate_bearing")


def _check_covariance(msg, sensor, what: str) -> int:
    """The message's ``covariance`` is the sensor's R (dim_z x dim_z, SPD); returns dim_z."""
    n = sensor.dim_z
    if len(msg.covariance) != n * n:
        raise Rejected("bad_covariance", f"{what}: covariance must have {n * n} values")
    R = spd(finite(msg.covariance, f"{what} covariance", math.inf).reshape(n, n), what)
    if not np.allclose(R, sensor.R, rtol=1e-9, atol=0.0):
        raise Rejected("sensor_mismatch", f"{what}: covariance differs from the scenario's R")
    return n


def measurement_topic(kind: str) -> str:
    """The topic that measurements of a sensor kind travel on."""
    if kind in BEARING_KINDS:
        return topics.BEARING_MEASUREMENTS
    if kind in POLAR_KINDS:
        return topics.POLAR_MEASUREMENTS
    return topics.MEASUREMENTS


def header(seconds: float, frame_id: str = FRAME_ID) -> Header:
    """A header stamped with sim time ``seconds`` (>= 0) in the fixed frame ``frame_id``."""
    sec = math.floor(seconds)
    nanosec = min(round((seconds - sec) * 1e9), 999_999_999)
    return Header(stamp=TimeMsg(sec=int(sec), nanosec=int(nanosec)), frame_id=frame_id)


def marker(hdr: Header, ns: str, id_: int, kind: int, rgba, points=()) -> Marker:
    """A visualization_msgs Marker to ADD: identity pose, colour ``rgba`` (4 floats), the
    plane ``points`` ((x, y) pairs); the caller sets its scale (and pose) for its kind."""
    m = Marker(header=hdr, ns=ns, id=id_, type=kind, action=Marker.ADD)
    m.pose.orientation.w = 1.0
    m.color = ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
    m.points = [Point(x=float(x), y=float(y)) for x, y in points]
    return m


def stamp_seconds(stamp, what: str) -> float:
    """Seconds of a builtin_interfaces/Time, rejecting negative or denormal stamps."""
    if stamp.sec < 0 or not 0 <= stamp.nanosec < 1_000_000_000:
        raise Rejected(
            "bad_stamp",
            f"{what}: header.stamp must be sec >= 0, 0 <= nanosec < 1e9, got "
            f"({stamp.sec}, {stamp.nanosec})",
        )
    return stamp.sec + stamp.nanosec * 1e-9


def check_epoch_stamp(msg, scenario: Scenario, what: str) -> float:
    """The epoch is within the run and the stamp is its time k T; returns the stamp."""
    if msg.epoch > scenario.steps:
        raise Rejected("future_epoch", f"{what}: epoch {msg.epoch} > steps {scenario.steps}")
    t = stamp_seconds(msg.header.stamp, what)
    if abs(t - msg.epoch * scenario.dt) > STAMP_TOLERANCE:
        raise Rejected(
            "bad_stamp", f"{what}: stamp {t} s is not epoch {msg.epoch} x dt {scenario.dt} s"
        )
    return t


def finite(values, what: str, limit: float) -> np.ndarray:
    """``values`` as a float array, all finite and within +-limit, else Rejected."""
    a = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(a)):
        raise Rejected("non_finite", f"{what} must be finite")
    if a.size and np.max(np.abs(a)) > limit:
        raise Rejected("out_of_range", f"{what} must be within +-{limit:g}")
    return a


def pv_of(position, velocity, what: str) -> np.ndarray:
    """(x, xdot, y, ydot) from a Point and a Vector3, checked."""
    finite((position.x, position.y), f"{what} position", MAX_COORDINATE)
    finite((velocity.x, velocity.y), f"{what} velocity", MAX_SPEED)
    return np.array([position.x, velocity.x, position.y, velocity.y], dtype=float)


def spd(P: np.ndarray, what: str) -> np.ndarray:
    """A symmetric positive definite covariance, else Rejected("bad_covariance")."""
    if not np.allclose(P, P.T, rtol=1e-9, atol=0.0):
        raise Rejected("bad_covariance", f"{what} covariance is not symmetric")
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        raise Rejected("bad_covariance", f"{what} covariance is not positive definite") from None
    return P


# --- per message type --------------------------------------------------------------------------


def platform_from_msg(msg, scenario: Scenario, platform_ids) -> PlatformSnapshot:
    """A PlatformState as a PlatformSnapshot (epoch, stamp, ids and kinematics checked)."""
    what = f"platform state of {msg.platform_id!r}"
    if msg.platform_id not in platform_ids:
        raise Rejected(
            "unknown_platform", f"{msg.platform_id!r} is not one of {sorted(platform_ids)}"
        )
    t = check_epoch_stamp(msg, scenario, what)
    platform = next(p for p in scenario.platforms if p.id == msg.platform_id)
    if list(msg.sensor_ids) != [s.id for s in platform.sensors] or list(msg.sensor_kinds) != [
        s.kind for s in platform.sensors
    ]:
        raise Rejected(
            "sensor_mismatch", f"{what}: sensors {list(msg.sensor_ids)[:8]} are not the scenario's"
        )
    pv = pv_of(msg.position, msg.velocity, what)
    finite((msg.heading,), f"{what} heading", 4 * math.pi)
    finite((msg.speed,), f"{what} speed", MAX_SPEED)
    return PlatformSnapshot(msg.platform_id, msg.epoch, t, pv, msg.heading, msg.speed)


class TrackChecker:
    """Validates TrackEstimate messages against what the scenario's tracker publishes."""

    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        motion = scenario.tracker.motion or scenario.target.motion
        self.state_names = tuple(build_motion_model(motion).state_names)
        self.n = len(self.state_names)
        self.max_samples = scenario.tracker.planner_samples

    def __call__(self, msg) -> TrackSnapshot:
        what = f"track epoch {msg.epoch}"
        n = self.n
        if tuple(msg.state_names) != self.state_names or len(msg.state) != n:
            raise Rejected(
                "wrong_dimension",
                f"{what}: state_names must be {list(self.state_names)} with {n} values, got "
                f"{list(msg.state_names)[:8]} and {len(msg.state)} values",
            )
        if len(msg.covariance) != n * n:
            raise Rejected("wrong_dimension", f"{what}: covariance must have {n * n} values")
        if msg.filter_kind not in filter_names():  # the registry: plugins' filters too
            raise Rejected(
                "bad_field", f"{what}: filter_kind must be one of {list(filter_names())}"
            )
        if msg.sample_count > self.max_samples or len(msg.particle_samples) != msg.sample_count * n:
            raise Rejected(
                "wrong_dimension",
                f"{what}: sample_count must be <= {self.max_samples} with sample_count x {n} "
                f"particle_samples, got {msg.sample_count} and {len(msg.particle_samples)}",
            )
        t = check_epoch_stamp(msg, self.scenario, what)
        mean = finite(msg.state, f"{what} state", MAX_STATE_VALUE)
        P = spd(
            finite(msg.covariance, f"{what} covariance", MAX_STATE_VALUE**2).reshape(n, n), what
        )
        samples = None
        if msg.sample_count:
            samples = finite(msg.particle_samples, f"{what} samples", MAX_STATE_VALUE)
            samples = samples.reshape(msg.sample_count, n)
        return TrackSnapshot(
            epoch=msg.epoch,
            time=t,
            filter_kind=msg.filter_kind,
            motion_model=msg.motion_model,
            state_names=tuple(msg.state_names),
            mean=mean,
            cov=P,
            samples=samples,
            update_count=msg.update_count,
            missed_detections=msg.missed_detections,
            nis=msg.nis,
            ess=msg.ess,
            particle_count=msg.particle_count,
        )


class MeasurementChecker:
    """Validates BearingMeasurement, PolarMeasurement and (generic) Measurement messages
    against the scenario's sensors: each sensor's measurements must arrive on the topic of its
    kind (:func:`measurement_topic`)."""

    def __init__(self, scenario: Scenario, sensors: dict, sensor_platform: dict[str, str]):
        self.scenario = scenario
        self.sensors = sensors  # sensor id -> sensor model
        self.sensor_platform = sensor_platform  # sensor id -> platform id

    def _common(self, msg, topic: str) -> tuple:
        sensor = self.sensors.get(msg.sensor_id)
        what = f"measurement of {msg.sensor_id!r} epoch {msg.epoch}"
        if sensor is None:
            raise Rejected(
                "unknown_sensor", f"{msg.sensor_id!r} is not one of {sorted(self.sensors)}"
            )
        if measurement_topic(sensor.kind) != topic:
            raise Rejected(
                "wrong_sensor_kind",
                f"{what}: sensor is {sensor.kind}, measured on {measurement_topic(sensor.kind)}",
            )
        if msg.platform_id != self.sensor_platform[msg.sensor_id]:
            raise Rejected(
                "inconsistent",
                f"{what}: sensor belongs to {self.sensor_platform[msg.sensor_id]!r}, not "
                f"{msg.platform_id!r}",
            )
        if msg.epoch == 0:
            raise Rejected("out_of_order", f"{what}: no measurement is taken at epoch 0")
        check_epoch_stamp(msg, self.scenario, what)
        pv = pv_of(msg.sensor_position, msg.sensor_velocity, what)
        return sensor, pv, what

    def bearing(self, msg) -> Measurement:
        sensor, pv, what = self._common(msg, topics.BEARING_MEASUREMENTS)
        if msg.ambiguous != (sensor.kind == "ambiguous_bearing"):
            raise Rejected(
                "wrong_sensor_kind", f"{what}: ambiguous flag does not match {sensor.kind}"
            )
        if not math.isclose(msg.sigma, sensor.sigma, rel_tol=1e-9):
            raise Rejected(
                "sensor_mismatch", f"{what}: sigma {msg.sigma} != scenario {sensor.sigma}"
            )
        z = None
        if msg.detected:
            finite((msg.bearing,), f"{what} bearing", math.pi + 1e-9)
            z = np.array([msg.bearing])
        return Measurement(sensor, pv, z, msg.epoch * self.scenario.dt, msg.sensor_id)

    def polar(self, msg) -> Measurement:
        sensor, pv, what = self._common(msg, topics.POLAR_MEASUREMENTS)
        if msg.has_range_rate != ("range_rate" in sensor.components):
            raise Rejected(
                "wrong_sensor_kind", f"{what}: has_range_rate does not match {sensor.kind}"
            )
        _check_covariance(msg, sensor, what)
        z = None
        if msg.detected:
            values = {"range": msg.range, "range_rate": msg.range_rate, "bearing": msg.bearing}
            z = np.array([values[c] for c in sensor.components], dtype=float)
            finite((msg.bearing,), f"{what} bearing", math.pi + 1e-9)
            finite((msg.range,), f"{what} range", MAX_COORDINATE)
            if msg.range < 0:
                raise Rejected("out_of_range", f"{what}: range must be >= 0")
            finite((msg.range_rate,), f"{what} range_rate", MAX_SPEED)
        return Measurement(sensor, pv, z, msg.epoch * self.scenario.dt, msg.sensor_id)

    def generic(self, msg) -> Measurement:
        """A Measurement of a sensor without a typed message: its kind as in the scenario, R
        equal to the sensor's, ``z`` with one finite value per component when detected (what
        a value means is the sensor's: only a generic bound, MAX_STATE_VALUE, applies), empty
        otherwise."""
        sensor, pv, what = self._common(msg, topics.MEASUREMENTS)
        if msg.sensor_kind != sensor.kind:
            shown = msg.sensor_kind if len(msg.sensor_kind) <= 40 else msg.sensor_kind[:40] + "..."
            raise Rejected(
                "wrong_sensor_kind", f"{what}: sensor_kind {shown!r} is not {sensor.kind!r}"
            )
        n = _check_covariance(msg, sensor, what)
        z = None
        if msg.detected:
            if len(msg.z) != n:
                raise Rejected(
                    "wrong_dimension",
                    f"{what}: z must have {n} values {list(sensor.components)}, got {len(msg.z)}",
                )
            z = finite(msg.z, f"{what} z", MAX_STATE_VALUE)
        elif len(msg.z):
            raise Rejected("wrong_dimension", f"{what}: z must be empty when detected is false")
        return Measurement(sensor, pv, z, msg.epoch * self.scenario.dt, msg.sensor_id)


def report_msg(r: PlanReportData, hdr: Header) -> PlanReport:
    """The planner's report of a decision as a PlanReport message."""
    return PlanReport(
        header=hdr,
        epoch=r.epoch,
        cost_kind=r.cost_kind,
        criterion=r.criterion,
        search=r.search,
        horizon=r.horizon,
        cost_names=list(r.cost_names),
        predicted_costs=[float(v) for v in r.predicted_costs],
        evaluations=r.evaluations,
        planning_wall_time=r.wall_time_s,
    )


def report_from_msg(msg: PlanReport, scenario: Scenario) -> PlanReportData:
    """A PlanReport as PlanReportData (epoch < steps, finite costs, one per cost name). Its
    repeated strings are interned: a run's record keeps one report per epoch."""
    if msg.epoch >= scenario.steps:
        raise Rejected("future_epoch", f"plan report of epoch {msg.epoch}")
    check_epoch_stamp(msg, scenario, "plan report")
    costs = finite(msg.predicted_costs, "predicted_costs", math.inf)
    if len(costs) != len(msg.cost_names):
        raise Rejected("wrong_dimension", "predicted_costs and cost_names differ in length")
    finite((msg.planning_wall_time,), "planning_wall_time", 1e9)
    return PlanReportData(
        epoch=msg.epoch,
        cost_kind=sys.intern(msg.cost_kind),
        criterion=sys.intern(msg.criterion),
        search=sys.intern(msg.search),
        horizon=msg.horizon,
        cost_names=tuple(sys.intern(n) for n in msg.cost_names),
        predicted_costs=tuple(costs.tolist()),
        evaluations=msg.evaluations,
        wall_time_s=msg.planning_wall_time,
    )
