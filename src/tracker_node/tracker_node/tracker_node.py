"""tracker_node: EKF or particle filter on bearing and polar measurements
(activetrack.closed_loop.TrackerCore).

Collects the measurements of an epoch (``epoch_measurement_count`` of them), updates the
filter once per epoch and publishes the track; an epoch without measurements (a stop-and-measure
robot on the move, a gated sensor) is announced by the platform states and only predicts, as in
the batch loop. Outputs: ``TrackEstimate`` (with the planner's posterior
samples for a PF), ``geometry_msgs/PoseWithCovarianceStamped`` and a subsampled particle cloud
(``geometry_msgs/PoseArray``) for standard tools. Bad messages (non-finite values, unknown
sensors, out-of-order or future epochs and stamps, a covariance that is not positive definite)
are rejected, counted and logged; the node keeps running.
"""

import array
import math

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, PoseWithCovarianceStamped
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.time import Time
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.counters import NodeCounters
from activetrack.closed_loop.tracker import TrackerCore, pose_of
from activetrack.filters.measurement import Measurement
from activetrack.geometry import covariance_ellipse
from activetrack.scenarios import load_scenario, with_tracker_overrides
from activetrack_ros import graph as topics
from msgs_defs.msg import BearingMeasurement, PlatformState, PolarMeasurement, TrackEstimate

LATCHED = topics.writer_qos(topics.TRACK)

BEARING_KINDS = ("bearing", "ambiguous_bearing")
STAMP_TOLERANCE = 1e-6  # s between a stamp and its epoch time k T


class TrackerNode(Node):
    def __init__(self, **kwargs):
        super().__init__("tracker_node", **kwargs)
        self.declare_parameter("scenario", "")
        self.declare_parameter("run", -1)
        self.declare_parameter("mode", "lockstep")  # lockstep: only epoch k+1 follows epoch k
        self.declare_parameter("cloud_size", 100)  # particles in the published cloud
        self.declare_parameter("filter", "")  # ekf | pf; empty: the scenario's
        self.declare_parameter("particles", 0)  # 0: the scenario's
        path = self.get_parameter("scenario").value
        if not path:
            raise ValueError("parameter 'scenario' must name a scenario YAML file")
        self.scenario = with_tracker_overrides(
            load_scenario(path),
            filter=self.get_parameter("filter").value or None,
            particles=self.get_parameter("particles").value or None,
        )
        self.mode = self.get_parameter("mode").value
        if self.mode not in ("lockstep", "free"):
            raise ValueError(f"parameter 'mode' must be 'lockstep' or 'free', got {self.mode!r}")
        run = int(self.get_parameter("run").value)
        rng = component_rngs(self.scenario.seed, None if run < 0 else run)[1]
        self.core = TrackerCore(self.scenario, rng)
        self.cloud_size = int(self.get_parameter("cloud_size").value)
        # Scenario order of the sensors: measurements of an epoch are applied in this order.
        self.sensor_order = {sid: i for i, sid in enumerate(self.core.sensors)}
        self.platform_ids = {p.id for p in self.scenario.platforms}
        self.counters = NodeCounters()
        self.buffer: dict[int, list[Measurement]] = {}
        self.expected: dict[int, int] = {}
        self.quiet: dict[int, set[str]] = {}  # platforms whose state says epoch k had nothing
        self.last_epoch = 0

        self.track_pub = self.create_publisher(TrackEstimate, topics.TRACK, LATCHED)
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, topics.TRACK_POSE, 10)
        self.cloud_pub = self.create_publisher(PoseArray, topics.PARTICLES, 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        self.marker_pub = self.create_publisher(MarkerArray, topics.MARKERS, 10)
        self.create_subscription(
            BearingMeasurement, topics.BEARING_MEASUREMENTS, self.on_bearing, LATCHED
        )
        self.create_subscription(
            PolarMeasurement, topics.POLAR_MEASUREMENTS, self.on_polar, LATCHED
        )
        self.create_subscription(PlatformState, topics.PLATFORM_STATES, self.on_platform, LATCHED)
        self.publish_track(self.core.snapshot())  # epoch 0: the prior

    # --- validation and conversion -------------------------------------------------------

    def _reject(self, reason: str, detail: str) -> None:
        self.counters.rejected(reason)
        self.get_logger().warning(f"rejected {reason}: {detail}")

    def _check_common(self, msg, kinds) -> str | None:
        """Reason to reject a measurement message, or None."""
        sensor = self.core.sensors.get(msg.sensor_id)
        if sensor is None:
            return "unknown_sensor"
        if sensor.kind not in kinds:
            return "wrong_sensor_kind"
        pos = (msg.sensor_position.x, msg.sensor_position.y)
        vel = (msg.sensor_velocity.x, msg.sensor_velocity.y)
        if not all(math.isfinite(v) for v in (*pos, *vel)):
            return "non_finite"
        if msg.epoch <= self.last_epoch:
            return "out_of_order"
        if msg.epoch > self.scenario.steps or (
            self.mode == "lockstep" and msg.epoch > self.last_epoch + 1
        ):
            return "future_epoch"
        stamp = Time.from_msg(msg.header.stamp).nanoseconds * 1e-9
        if abs(stamp - msg.epoch * self.scenario.dt) > STAMP_TOLERANCE:
            return "bad_stamp"
        return None

    def _measurement(self, msg, z) -> Measurement:
        s = msg.sensor_position, msg.sensor_velocity
        return Measurement(
            self.core.sensors[msg.sensor_id],
            np.array([s[0].x, s[1].x, s[0].y, s[1].y]),
            z,
            msg.epoch * self.scenario.dt,  # exact k T, as in the batch loop
            msg.sensor_id,
        )

    def on_bearing(self, msg: BearingMeasurement) -> None:
        self.counters.received("BearingMeasurement")
        reason = self._check_common(msg, BEARING_KINDS)
        if reason is None and msg.detected and not math.isfinite(msg.bearing):
            reason = "non_finite"
        if reason is not None:
            return self._reject(reason, f"bearing from {msg.sensor_id!r} epoch {msg.epoch}")
        z = [msg.bearing] if msg.detected else None
        self.accept(msg, self._measurement(msg, z))

    def on_polar(self, msg: PolarMeasurement) -> None:
        self.counters.received("PolarMeasurement")
        reason = self._check_common(msg, ("range_bearing", "range_rate_bearing"))
        if reason is None:
            sensor = self.core.sensors[msg.sensor_id]
            values = {"range": msg.range, "range_rate": msg.range_rate, "bearing": msg.bearing}
            z = [values[c] for c in sensor.components]
            n = sensor.dim_z
            if msg.has_range_rate != ("range_rate" in sensor.components):
                reason = "wrong_sensor_kind"
            elif msg.detected and not all(math.isfinite(v) for v in z):
                reason = "non_finite"
            elif len(msg.covariance) != n * n:
                reason = "bad_covariance"
            else:
                R = np.array(msg.covariance, dtype=float).reshape(n, n)
                if not (np.all(np.isfinite(R)) and np.allclose(R, R.T)):
                    reason = "bad_covariance"
                elif np.any(np.linalg.eigvalsh(R) <= 0):
                    reason = "bad_covariance"
        if reason is not None:
            return self._reject(reason, f"polar from {msg.sensor_id!r} epoch {msg.epoch}")
        self.accept(msg, self._measurement(msg, z if msg.detected else None))

    def on_platform(self, msg: PlatformState) -> None:
        """An epoch with no measurements at all is only seen here: once every platform's state
        of epoch k says the sim published nothing at k, predict through it."""
        self.counters.received("PlatformState")
        if msg.platform_id not in self.platform_ids:
            return self._reject("unknown_platform", f"platform state of {msg.platform_id!r}")
        values = (msg.position.x, msg.position.y, msg.velocity.x, msg.velocity.y)
        if not all(math.isfinite(v) for v in values):
            return self._reject("non_finite", f"platform state of {msg.platform_id!r}")
        k = msg.epoch
        if msg.epoch_measurement_count > 0 or k <= self.last_epoch or k in self.buffer:
            return  # measurements will drive the epoch, or it is done already
        if k > self.scenario.steps or (self.mode == "lockstep" and k > self.last_epoch + 1):
            return self._reject("future_epoch", f"platform state of {msg.platform_id!r} at {k}")
        quiet = self.quiet.setdefault(k, set())
        quiet.add(msg.platform_id)
        if quiet != self.platform_ids:
            return
        self.flush_before(k)
        self.buffer[k] = []
        self.counters.count("epochs_without_measurements")
        self.process(k)

    # --- epochs --------------------------------------------------------------------------

    def accept(self, msg, measurement: Measurement) -> None:
        k = msg.epoch
        if any(m.sensor_id == measurement.sensor_id for m in self.buffer.get(k, [])):
            return self._reject("duplicate", f"second measurement of {msg.sensor_id!r} at {k}")
        self.buffer.setdefault(k, []).append(measurement)
        self.expected[k] = msg.epoch_measurement_count
        self.flush_before(k)
        count = self.expected[k]
        if count == 0 or len(self.buffer[k]) >= count:
            self.process(k)

    def flush_before(self, k: int) -> None:
        """Earlier incomplete epochs are processed when a later one starts (free mode only)."""
        for e in sorted(e for e in self.buffer if e < k):
            self.counters.count("incomplete_epochs")
            self.process(e)

    def process(self, epoch: int) -> None:
        measurements = sorted(self.buffer.pop(epoch), key=lambda m: self.sensor_order[m.sensor_id])
        self.expected.pop(epoch, None)
        for e in [e for e in self.quiet if e <= epoch]:
            del self.quiet[e]
        snapshot = self.core.step(epoch, epoch * self.scenario.dt, measurements)
        self.last_epoch = epoch
        self.counters.count("updates")
        self.counters.count("missed_detections", sum(m.z is None for m in measurements))
        self.publish_track(snapshot)

    # --- outputs -------------------------------------------------------------------------

    def publish_track(self, snap) -> None:
        header = Header(
            stamp=Time(seconds=snap.epoch * self.scenario.dt).to_msg(), frame_id="world"
        )
        samples = snap.samples
        self.track_pub.publish(
            TrackEstimate(
                header=header,
                target_id=self.scenario.target.id,
                epoch=snap.epoch,
                filter_kind=snap.filter_kind,
                motion_model=snap.motion_model,
                state_names=list(snap.state_names),
                state=[float(v) for v in snap.mean],
                covariance=[float(v) for v in snap.cov.ravel()],
                update_count=snap.update_count,
                missed_detections=snap.missed_detections,
                nis=float(snap.nis),
                ess=float(snap.ess),
                particle_count=snap.particle_count,
                # array('d') from the raw buffer: a 10,000 x 4 list would cost ~25 ms per epoch.
                particle_samples=array.array("d")
                if samples is None
                else array.array("d", np.ascontiguousarray(samples, dtype=float).tobytes()),
                sample_count=0 if samples is None else len(samples),
            )
        )
        x, y, course, P_xy = pose_of(snap, self.core.model)
        pose = PoseWithCovarianceStamped(header=header)
        pose.pose.pose.position.x, pose.pose.pose.position.y = x, y
        pose.pose.pose.orientation.z = math.sin(course / 2)
        pose.pose.pose.orientation.w = math.cos(course / 2)
        cov6 = [0.0] * 36  # (x, y, z, roll, pitch, yaw), row-major
        cov6[0], cov6[1], cov6[6], cov6[7] = (float(v) for v in P_xy.ravel())
        pose.pose.covariance = cov6
        self.pose_pub.publish(pose)
        ellipse = Marker(header=header, ns="track", id=0, type=Marker.LINE_STRIP)
        ellipse.action = Marker.ADD
        ellipse.pose.orientation.w = 1.0
        ellipse.scale.x = 5.0  # line width, m
        ellipse.color = ColorRGBA(r=0.9, g=0.1, b=0.1, a=1.0)
        # 2-sigma position ellipse of the track.
        ellipse.points = [
            Point(x=float(px), y=float(py)) for px, py in covariance_ellipse((x, y), P_xy, 2.0)
        ]
        self.marker_pub.publish(MarkerArray(markers=[ellipse]))
        if samples is not None and self.cloud_size > 0:
            step = max(1, len(samples) // self.cloud_size)
            cloud = PoseArray(header=header)
            for x in self.core.model.kinematics(samples[::step]):
                p = Pose()
                p.position.x, p.position.y = float(x[0]), float(x[2])
                cloud.poses.append(p)
            self.cloud_pub.publish(cloud)
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN if self.counters.total_rejected else DiagnosticStatus.OK,
            name="activetrack/tracker_node",
            hardware_id=self.scenario.name,
            message=f"epoch {snap.epoch} {snap.filter_kind}: ESS {snap.ess:.0f} NIS {snap.nis:.2f}",
            values=[KeyValue(key=k, value=v) for k, v in self.counters.as_pairs()],
        )
        self.diag_pub.publish(DiagnosticArray(header=header, status=[status]))


def main(args=None):
    rclpy.init(args=args)
    try:
        node = TrackerNode()
    except ValueError as exc:
        print(f"tracker_node: {exc}")
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
