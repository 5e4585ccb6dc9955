"""sim_node: simulated target and sensor platforms (activetrack.closed_loop.Simulator).

Publishes /clock, ground truth (evaluators only), platform states and bearing / polar
measurements; obeys ManoeuvreCommand (clamped to each platform's limits, logged and counted)
and SensorSelection.

Modes (parameter ``mode``):
- ``lockstep`` (default): epoch k+1 is simulated only when every controllable platform's
  command for epoch k has arrived, so a run is deterministic for a seed; a command missing
  after ``command_timeout`` wall seconds means hold course (warned and counted).
- ``free``: sim time runs at ``rate`` x wall time; commands apply to the current leg when they
  arrive.
"""

import math
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Vector3
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.time import Time
from rosgraph_msgs.msg import Clock
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.counters import NodeCounters
from activetrack.closed_loop.data import Command
from activetrack.closed_loop.simulator import Simulator
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    ManoeuvreCommand,
    PlatformState,
    PolarMeasurement,
    SensorSelection,
    TrackEstimate,
)

LATCHED = topics.writer_qos(topics.TRACK)

BEARING_KINDS = ("bearing", "ambiguous_bearing")


def _stamp(seconds: float) -> Header:
    return Header(stamp=Time(seconds=seconds).to_msg(), frame_id="world")


class SimNode(Node):
    def __init__(self, **kwargs):
        super().__init__("sim_node", **kwargs)
        self.declare_parameter("scenario", "")
        self.declare_parameter("run", -1)
        self.declare_parameter("mode", "lockstep")
        self.declare_parameter("rate", 1.0)
        self.declare_parameter("command_timeout", 5.0)
        self.declare_parameter("tick", 0.01)  # s between checks for timeouts (free: steps)
        self.declare_parameter("exit_when_done", False)  # else keep serving latched topics
        path = self.get_parameter("scenario").value
        if not path:
            raise ValueError("parameter 'scenario' must name a scenario YAML file")
        self.scenario = load_scenario(path)
        self.mode = self.get_parameter("mode").value
        if self.mode not in ("lockstep", "free"):
            raise ValueError(f"parameter 'mode' must be 'lockstep' or 'free', got {self.mode!r}")
        self.rate = float(self.get_parameter("rate").value)
        if not (math.isfinite(self.rate) and self.rate > 0):
            raise ValueError(f"parameter 'rate' must be > 0, got {self.rate!r}")
        self.timeout = float(self.get_parameter("command_timeout").value)
        run = int(self.get_parameter("run").value)
        rng = component_rngs(self.scenario.seed, None if run < 0 else run)[0]
        self.sim = Simulator(self.scenario, rng)
        self.counters = NodeCounters()

        self.clock_pub = self.create_publisher(Clock, topics.CLOCK, 10)
        self.truth_pub = self.create_publisher(GroundTruth, topics.GROUND_TRUTH, LATCHED)
        self.platform_pub = self.create_publisher(PlatformState, topics.PLATFORM_STATES, LATCHED)
        self.bearing_pub = self.create_publisher(
            BearingMeasurement, topics.BEARING_MEASUREMENTS, LATCHED
        )
        self.polar_pub = self.create_publisher(PolarMeasurement, topics.POLAR_MEASUREMENTS, LATCHED)
        self.diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        self.marker_pub = self.create_publisher(MarkerArray, topics.MARKERS, 10)
        self.paths: dict[str, list[Point]] = {pid: [] for pid in self.sim.platforms}
        self.create_subscription(
            ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command, LATCHED
        )
        self.create_subscription(
            SensorSelection, topics.SENSOR_SELECTION, self.on_selection, LATCHED
        )
        self.create_subscription(TrackEstimate, topics.TRACK, self.on_track, LATCHED)

        self.pending: dict[str, Command] = {}
        self.selection: tuple[str, ...] | None = None
        self.selection_epoch = -1
        # Lockstep: with selection on, epoch k+1 also waits for the selection decided at k.
        planner = self.scenario.planner
        self.expects_selection = planner.enabled and planner.selection.enabled
        self.last_track_epoch = -1
        self.done = False
        self.epoch_started = time.monotonic()
        self.wall_start = time.monotonic()
        self.publish_epoch([])
        self.timer = self.create_timer(float(self.get_parameter("tick").value), self.on_tick)

    # --- inputs --------------------------------------------------------------------------

    def _reject(self, reason: str, detail: str) -> None:
        self.counters.rejected(reason)
        self.get_logger().warning(f"rejected {reason}: {detail}")

    def on_command(self, msg: ManoeuvreCommand) -> None:
        self.counters.received("ManoeuvreCommand")
        values = (msg.heading_change, msg.speed_change)
        if not all(math.isfinite(v) for v in values):
            return self._reject("non_finite", f"command for {msg.platform_id!r}: {values}")
        if msg.platform_id not in self.sim.controllable_ids:
            return self._reject(
                "unknown_platform",
                f"{msg.platform_id!r} is not one of {list(self.sim.controllable_ids)}",
            )
        if self.mode == "lockstep":
            if msg.epoch < self.sim.epoch:
                return self._reject("stale_epoch", f"epoch {msg.epoch} < {self.sim.epoch}")
            if msg.epoch > self.sim.epoch:
                return self._reject("future_epoch", f"epoch {msg.epoch} > {self.sim.epoch}")
        cmd = Command(
            msg.platform_id,
            self.sim.epoch,
            msg.heading_change,
            msg.speed_change,
            take_measurement=msg.take_measurement if msg.gate_measurement else None,
        )
        if self.mode == "free":
            self.apply(cmd)
        else:
            self.pending[msg.platform_id] = cmd
            if self.ready():
                self.on_tick()  # the last command of the epoch: step now, not at the next tick

    def on_selection(self, msg: SensorSelection) -> None:
        self.counters.received("SensorSelection")
        unknown = [s for s in msg.selected_sensor_ids if s not in self.sim.sensors]
        if unknown:
            return self._reject("unknown_sensor", f"selection names {unknown}")
        if self.mode == "lockstep" and msg.epoch != self.sim.epoch:
            return self._reject("stale_epoch", f"selection for epoch {msg.epoch}")
        self.selection = tuple(msg.selected_sensor_ids)
        self.selection_epoch = msg.epoch

    def on_track(self, msg: TrackEstimate) -> None:
        # Only a lockstep signal when no platform is commanded: the sim never reads the estimate.
        self.last_track_epoch = max(self.last_track_epoch, msg.epoch)
        if self.mode == "lockstep" and not self.sim.controllable_ids and self.ready():
            self.on_tick()

    # --- stepping ------------------------------------------------------------------------

    def apply(self, cmd: Command) -> None:
        result = self.sim.apply_command(cmd)
        self.counters.count("commands_applied")
        if result.clamped:
            self.counters.count("commands_clamped")
            self.get_logger().warning(f"command for {cmd.platform_id!r} clamped: {result.message}")

    def ready(self) -> bool:
        k = self.sim.epoch
        if self.expects_selection and self.selection_epoch != k:
            return False
        if not self.sim.controllable_ids:
            return self.last_track_epoch >= k
        return all(pid in self.pending for pid in self.sim.controllable_ids)

    def on_tick(self) -> None:
        if self.done:
            return
        if self.sim.finished:
            self.done = True
            self.publish_diagnostics(finished=True)
            self.get_logger().info(f"scenario {self.scenario.name} finished")
            return
        if self.mode == "free":
            sim_time = (time.monotonic() - self.wall_start) * self.rate
            self.clock_pub.publish(Clock(clock=Time(seconds=sim_time).to_msg()))
            if sim_time >= self.sim.time + self.sim.dt:
                self.step()
            return
        if not self.ready():
            if time.monotonic() - self.epoch_started < self.timeout:
                return
            missing = [p for p in self.sim.controllable_ids if p not in self.pending]
            for pid in missing:
                self.pending[pid] = Command(pid, self.sim.epoch, 0.0, 0.0)
            self.counters.count("command_timeouts", max(1, len(missing)))
            self.get_logger().warning(
                f"epoch {self.sim.epoch}: no command for {missing} after {self.timeout} s; "
                "holding course"
            )
        for pid in self.sim.controllable_ids:
            self.apply(self.pending[pid])
        self.step()

    def step(self) -> None:
        if self.selection is not None and self.selection_epoch == self.sim.epoch:
            self.sim.apply_selection(self.selection)
        self.pending.clear()
        measurements = self.sim.advance()
        self.publish_epoch(measurements)
        self.epoch_started = time.monotonic()

    # --- outputs -------------------------------------------------------------------------

    def publish_epoch(self, measurements) -> None:
        t = self.sim.time
        k = self.sim.epoch
        self.clock_pub.publish(Clock(clock=Time(seconds=t).to_msg()))
        pv = self.sim.truth_pv()
        self.truth_pub.publish(
            GroundTruth(
                header=_stamp(t),
                target_id=self.scenario.target.id,
                epoch=k,
                state_names=list(self.sim.model.state_names),
                state=[float(v) for v in self.sim.truth],
                position=Point(x=float(pv[0]), y=float(pv[2])),
                velocity=Vector3(x=float(pv[1]), y=float(pv[3])),
            )
        )
        for m in measurements:
            self.publish_measurement(m, k, t, len(measurements))
        for s in self.sim.platform_snapshots():
            self.platform_pub.publish(
                PlatformState(
                    header=_stamp(t),
                    platform_id=s.platform_id,
                    epoch=k,
                    sensor_id=",".join(s.sensor_ids),
                    sensor_kind=",".join(s.sensor_kinds),
                    position=Point(x=float(s.pv[0]), y=float(s.pv[2])),
                    velocity=Vector3(x=float(s.pv[1]), y=float(s.pv[3])),
                    heading=s.heading,
                    speed=s.speed,
                    epoch_measurement_count=len(measurements),
                )
            )
        self.counters.count("epochs_published")
        self.publish_markers(t)
        self.publish_diagnostics()

    def publish_measurement(self, m, epoch: int, t: float, count: int) -> None:
        platform_id = self.sim.sensors[m.sensor_id][0]
        s = m.sensor_state
        common = dict(
            header=_stamp(t),
            platform_id=platform_id,
            sensor_id=m.sensor_id,
            epoch=epoch,
            epoch_measurement_count=count,
            sensor_position=Point(x=float(s[0]), y=float(s[2])),
            sensor_velocity=Vector3(x=float(s[1]), y=float(s[3])),
            detected=m.z is not None,
        )
        sensor = m.sensor
        z = dict(zip(sensor.components, m.z, strict=True)) if m.z is not None else {}
        if sensor.kind in BEARING_KINDS:
            self.bearing_pub.publish(
                BearingMeasurement(
                    **common,
                    bearing=float(z.get("bearing", 0.0)),
                    sigma=float(sensor.sigma),
                    ambiguous=sensor.kind == "ambiguous_bearing",
                )
            )
        else:
            self.polar_pub.publish(
                PolarMeasurement(
                    **common,
                    range=float(z.get("range", 0.0)),
                    bearing=float(z.get("bearing", 0.0)),
                    has_range_rate="range_rate" in sensor.components,
                    range_rate=float(z.get("range_rate", 0.0)),
                    covariance=[float(v) for v in sensor.R.ravel()],
                )
            )
        self.counters.count("measurements_published")
        if m.z is None:
            self.counters.count("missed_detections")

    def publish_markers(self, t: float) -> None:
        """Each platform's path so far as a line strip (namespace ``platforms``)."""
        array = MarkerArray()
        for i, (pid, p) in enumerate(self.sim.platforms.items()):
            self.paths[pid].append(Point(x=float(p.pv[0]), y=float(p.pv[2])))
            m = Marker(header=_stamp(t), ns="platforms", id=i, type=Marker.LINE_STRIP)
            m.action = Marker.ADD
            m.pose.orientation.w = 1.0
            m.scale.x = 20.0  # line width, m
            m.color = ColorRGBA(r=0.1, g=0.4, b=0.9, a=1.0)
            m.points = list(self.paths[pid])
            array.markers.append(m)
        self.marker_pub.publish(array)

    def publish_diagnostics(self, finished: bool = False) -> None:
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN if self.counters.total_rejected else DiagnosticStatus.OK,
            name="activetrack/sim_node",
            hardware_id=self.scenario.name,
            message="finished" if finished else f"epoch {self.sim.epoch}/{self.scenario.steps}",
            values=[KeyValue(key=k, value=v) for k, v in self.counters.as_pairs()],
        )
        self.diag_pub.publish(DiagnosticArray(header=_stamp(self.sim.time), status=[status]))


def main(args=None):
    rclpy.init(args=args)
    try:
        node = SimNode()
    except ValueError as exc:  # a bad scenario or parameter fails before anything starts
        print(f"sim_node: {exc}")
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    try:
        exit_when_done = bool(node.get_parameter("exit_when_done").value)
        while rclpy.ok() and not (exit_when_done and node.done):
            rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
