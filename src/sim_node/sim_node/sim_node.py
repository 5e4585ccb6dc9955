"""sim_node: simulated target and sensor platforms (activetrack.closed_loop.Simulator).

Publishes /clock, ground truth (evaluators only), platform states and measurements: bearing and
polar ones typed, those of any other sensor kind (a plugin's, docs/extending.md) as the generic
``Measurement``; obeys ManoeuvreCommand (clamped to each platform's limits, logged and counted)
and SensorSelection from the graph's planner (activetrack_ros.trust).

Modes (parameter ``mode``):
- ``lockstep`` (default): epoch k+1 is simulated only when every controllable platform's
  command for epoch k has arrived, so a run is deterministic for a seed; a command missing
  after ``command_timeout`` wall seconds means hold course (warned and counted).
- ``free``: sim time runs at ``rate`` x wall time; commands apply to the current leg when they
  arrive.
"""

import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, Vector3
from rosgraph_msgs.msg import Clock
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.data import Command
from activetrack.closed_loop.simulator import Simulator
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    MAX_SPEED,
    check_epoch_stamp,
    finite,
    header,
    marker,
    measurement_topic,
)
from activetrack_ros.frames import planar_transform, platform_frame, sensor_frame, truth_frame
from activetrack_ros.hold import WAIT_FOR, FirstEpochHold
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import COMMON, ParamSpec
from activetrack_ros.spin import spin_node
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    ManoeuvreCommand,
    Measurement,
    PlatformState,
    PolarMeasurement,
    SensorSelection,
    TrackEstimate,
)

PATH_CHUNK = 64  # points per path marker: each epoch republishes only the newest chunk


PARAMS = (
    *COMMON,
    ParamSpec(
        "rate", 1.0, "free mode: simulated seconds per wall second (changeable while running)",
        read_only=False, low=1e-3, high=1e6,
    ),
    ParamSpec(
        "command_timeout", 5.0,
        "lockstep: wall seconds to wait for a platform's command before it holds course "
        "(changeable while running)",
        read_only=False, low=1e-3, high=3600.0,
    ),
    ParamSpec(
        "tick", 0.01, "wall seconds between timeout checks (free mode: between clock ticks)",
        low=1e-3, high=1.0,
    ),
    ParamSpec(
        "exit_when_done", False,
        "exit after the last epoch (else keep serving the latched topics; changeable)",
        read_only=False,
    ),
    *WAIT_FOR,
)  # fmt: skip


class SimNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("sim_node", **kwargs)
        changes: dict = {}  # filled below, once the mode is known
        p = self.declare_params(PARAMS, changes)
        self.scenario = load_scenario(p["scenario"])
        self.use_scenario(self.scenario)
        self.mode = p["mode"]
        self.rate = p["rate"]
        self.timeout = p["command_timeout"]
        self.exit_when_done = p["exit_when_done"]
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[0]
        self.sim = Simulator(self.scenario, rng)
        changes.update(
            command_timeout=self._set_timeout,
            exit_when_done=self._set_exit_when_done,
            rate=self._set_rate
            if self.mode == "free"
            else "parameter 'rate' applies in free "
            "mode only (this node runs lockstep: each epoch waits for the planner)",
        )
        self.tf_pub = self.publisher(TFMessage, topics.TF)
        self.tf_static_pub = self.publisher(TFMessage, topics.TF_STATIC)

        self.clock_pub = self.publisher(Clock, topics.CLOCK)
        self.truth_pub = self.publisher(GroundTruth, topics.GROUND_TRUTH)
        self.platform_pub = self.publisher(PlatformState, topics.PLATFORM_STATES)
        self.bearing_pub = self.publisher(BearingMeasurement, topics.BEARING_MEASUREMENTS)
        self.polar_pub = self.publisher(PolarMeasurement, topics.POLAR_MEASUREMENTS)
        self.generic_pub = self.publisher(Measurement, topics.MEASUREMENTS)
        self.diag_pub = self.publisher(DiagnosticArray, topics.DIAGNOSTICS)
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        self.paths: dict[str, list[Point]] = {pid: [] for pid in self.sim.platforms}
        self.path_chunk = dict.fromkeys(self.sim.platforms, 0)
        self.subscribe(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command)
        self.subscribe(SensorSelection, topics.SENSOR_SELECTION, self.on_selection)
        self.subscribe(TrackEstimate, topics.TRACK, self.on_track)

        self.pending: dict[str, Command] = {}
        self.selection: tuple[str, ...] | None = None
        self.selection_epoch = -1
        # Lockstep: with selection on, epoch k+1 also waits for the selection decided at k.
        planner = self.scenario.planner
        self.expects_selection = planner.enabled and planner.selection.enabled
        self.last_track_epoch = -1
        self.done = False
        self.epoch_started = time.monotonic()
        self.clock_origin = (time.monotonic(), 0.0)  # free mode: (wall, sim) at the last rate
        self.publish_static_frames()
        self.hold = FirstEpochHold(self, p, self._first_epoch, changes)
        self.guarded_timer(p["tick"], self.on_tick)

    def _first_epoch(self) -> None:
        """Epoch 0, now (at start-up, or when a held first epoch is released)."""
        self.clock_origin = (time.monotonic(), self.sim.time)
        self.publish_epoch([])
        self.epoch_started = time.monotonic()

    # --- run-time parameter changes (activetrack_ros.params) -------------------------------

    def _set_rate(self, rate: float) -> None:
        """Sim time stays continuous: the new rate counts from now."""
        self.clock_origin = (time.monotonic(), self.sim_time_now())
        self.rate = rate

    def _set_timeout(self, seconds: float) -> None:
        self.timeout = seconds

    def _set_exit_when_done(self, value: bool) -> None:
        self.exit_when_done = value

    def sim_time_now(self) -> float:
        wall, sim = self.clock_origin
        return sim + (time.monotonic() - wall) * self.rate

    # --- inputs --------------------------------------------------------------------------

    def _check_epoch(self, epoch: int, what: str) -> None:
        if self.mode == "lockstep":
            check_lockstep_epoch(epoch, self.sim.epoch, what)

    def on_command(self, msg: ManoeuvreCommand) -> None:
        cmd = command_from_msg(msg, self.scenario, self.sim)
        what = f"command for {msg.platform_id!r}"
        self._check_epoch(msg.epoch, what)
        if self.mode == "lockstep" and msg.platform_id in self.pending:
            raise Rejected("duplicate", f"second {what} at epoch {msg.epoch}")
        if self.mode == "free":
            self.apply(cmd)
        else:
            self.pending[msg.platform_id] = cmd
            if self.ready():
                self.on_tick()  # the last command of the epoch: step now, not at the next tick

    def on_selection(self, msg: SensorSelection) -> None:
        if not self.expects_selection:
            raise Rejected("unexpected_selection", "the scenario does not select sensors")
        check_epoch_stamp(msg, self.scenario, "selection")
        ids = list(msg.selected_sensor_ids)
        unknown = [s for s in ids if s not in self.sim.sensors]
        if unknown:
            raise Rejected("unknown_sensor", f"selection names {unknown[:5]}")
        count = self.scenario.planner.selection.count
        if len(set(ids)) != len(ids) or not 1 <= len(ids) <= count:
            raise Rejected("bad_selection", f"selection must name 1..{count} distinct sensors")
        self._check_epoch(msg.epoch, "selection")
        if self.mode == "lockstep" and self.selection_epoch == msg.epoch:
            raise Rejected("duplicate", f"second selection at epoch {msg.epoch}")
        self.selection = tuple(ids)
        self.selection_epoch = msg.epoch
        if self.mode == "lockstep" and self.ready():
            self.on_tick()

    def on_track(self, msg: TrackEstimate) -> None:
        # Only a lockstep signal when no platform is commanded: the sim never reads the estimate.
        check_epoch_stamp(msg, self.scenario, "track")
        if msg.epoch > self.sim.epoch:
            raise Rejected("future_epoch", f"track of epoch {msg.epoch} > sim {self.sim.epoch}")
        self.last_track_epoch = max(self.last_track_epoch, msg.epoch)
        if self.mode == "lockstep" and not self.sim.controllable_ids and self.ready():
            self.on_tick()

    # --- stepping ------------------------------------------------------------------------

    def apply(self, cmd: Command) -> None:
        result = self.sim.apply_command(cmd)
        self.counters.count("commands_applied")
        if result.clamped:
            self.counters.count("commands_clamped")
            self.log_limited(
                "warning", "clamped", f"command for {cmd.platform_id!r} clamped: {result.message}"
            )

    def ready(self) -> bool:
        k = self.sim.epoch
        if self.expects_selection and self.selection_epoch != k:
            return False
        if not self.sim.controllable_ids:
            return self.last_track_epoch >= k
        return all(pid in self.pending for pid in self.sim.controllable_ids)

    def on_tick(self) -> None:
        if self.done or self.hold.waiting:
            return
        if self.sim.finished:
            self.done = True
            self.publish_diagnostics(finished=True)
            self.get_logger().info(f"scenario {self.scenario.name} finished")
            return
        if self.mode == "free":
            sim_time = self.sim_time_now()
            self.clock_pub.publish(Clock(clock=header(sim_time, self.frame_id).stamp))
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
        self.clock_pub.publish(Clock(clock=header(t, self.frame_id).stamp))
        pv = self.sim.truth_pv()
        self.truth_pub.publish(
            GroundTruth(
                header=header(t, self.frame_id),
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
        for msg in platform_state_msgs(self.sim, len(measurements), self.frame_id):
            self.platform_pub.publish(msg)
        self.counters.count("epochs_published")
        self.publish_frames(t, pv)
        self.publish_markers(t)
        self.publish_diagnostics()

    def publish_frames(self, t: float, target_pv) -> None:
        """Platforms and the target's truth in the fixed frame (activetrack_ros.frames)."""
        hdr = header(t, self.frame_id)
        transforms = [
            planar_transform(hdr, platform_frame(s.platform_id), s.pv[0], s.pv[2], s.heading)
            for s in self.sim.platform_snapshots()
        ]
        course = math.atan2(target_pv[3], target_pv[1])
        target = truth_frame(self.scenario.target.id)
        transforms.append(planar_transform(hdr, target, target_pv[0], target_pv[2], course))
        self.tf_pub.publish(TFMessage(transforms=transforms))

    def publish_static_frames(self) -> None:
        self.tf_static_pub.publish(static_frames(self.scenario))

    def publish_measurement(self, m, epoch: int, t: float, count: int) -> None:
        platform_id = self.sim.sensors[m.sensor_id][0]
        s = m.sensor_state
        common = dict(
            header=header(t, self.frame_id),
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
        topic = measurement_topic(sensor.kind)
        if topic == topics.BEARING_MEASUREMENTS:
            self.bearing_pub.publish(
                BearingMeasurement(
                    **common,
                    bearing=float(z.get("bearing", 0.0)),
                    sigma=float(sensor.sigma),
                    ambiguous=sensor.kind == "ambiguous_bearing",
                )
            )
        elif topic == topics.POLAR_MEASUREMENTS:
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
        else:  # any other kind: z in the order of sensor.components
            self.generic_pub.publish(
                Measurement(
                    **common,
                    sensor_kind=sensor.kind,
                    z=[] if m.z is None else [float(v) for v in m.z],
                    covariance=[float(v) for v in sensor.R.ravel()],
                )
            )
        self.counters.count("measurements_published")
        if m.z is None:
            self.counters.count("missed_detections")

    def publish_markers(self, t: float) -> None:
        """Each platform's path as line strips of PATH_CHUNK points (namespace
        ``platforms/<id>``, marker id = chunk index): only the newest chunk is republished, so
        a long run costs linear, not quadratic, bytes; chunks share their end points."""
        array = MarkerArray()
        for pid, p in self.sim.platforms.items():
            path = self.paths[pid]
            if len(path) == PATH_CHUNK:  # chunk full: the next one starts where it ended
                self.path_chunk[pid] += 1
                del path[:-1]
            path.append(Point(x=float(p.pv[0]), y=float(p.pv[2])))
            hdr = header(t, self.frame_id)
            chunk = self.path_chunk[pid]
            m = marker(hdr, f"platforms/{pid}", chunk, Marker.LINE_STRIP, (0.1, 0.4, 0.9, 1.0))
            m.scale.x = 20.0  # line width, m
            m.points = list(path)
            array.markers.append(m)
        self.marker_pub.publish(array)

    def publish_diagnostics(self, finished: bool = False) -> None:
        self.diag_pub.publish(sim_diagnostics(self, finished))


def check_lockstep_epoch(epoch: int, current: int, what: str) -> None:
    """Lockstep: an answer must be of the sim's current epoch (Rejected otherwise)."""
    if epoch < current:
        raise Rejected("stale_epoch", f"{what} for epoch {epoch} < {current}")
    if epoch > current:
        raise Rejected("future_epoch", f"{what} for epoch {epoch} > {current}")


def static_frames(scenario) -> TFMessage:
    """Each sensor at its platform's origin (tf_static, one message)."""
    transforms = [
        planar_transform(header(0.0, platform_frame(p.id)), sensor_frame(s.id), 0, 0, 0)
        for p in scenario.platforms
        for s in p.sensors
    ]
    return TFMessage(transforms=transforms)


def sim_diagnostics(node, finished: bool) -> DiagnosticArray:
    """A sim node's status: its epoch (or finished) and its counters."""
    sim, scenario = node.sim, node.scenario
    message = "finished" if finished else f"epoch {sim.epoch}/{scenario.steps}"
    hdr = header(sim.time, node.frame_id)
    return node.diagnostics_array(hdr, "activetrack/sim_node", scenario.name, message)


def command_from_msg(msg: ManoeuvreCommand, scenario, sim: Simulator) -> Command:
    """A ManoeuvreCommand for one of ``sim``'s controllable platforms as a Command of the
    current epoch, every field checked (Rejected naming it); the epoch itself is the mode's
    business."""
    what = f"command for {msg.platform_id!r}"
    if msg.platform_id not in sim.controllable_ids:
        raise Rejected(
            "unknown_platform", f"{msg.platform_id!r} is not one of {list(sim.controllable_ids)}"
        )
    check_epoch_stamp(msg, scenario, what)
    # A heading change beyond half a turn or a speed change beyond the platform's whole speed
    # range is not a command to clamp but garbage: reject it.
    finite((msg.heading_change,), f"{what} heading_change", math.pi + 1e-9)
    v_max = next(p for p in scenario.platforms if p.id == msg.platform_id).limits.v_max
    finite((msg.speed_change,), f"{what} speed_change", min(v_max, MAX_SPEED))
    return Command(
        msg.platform_id,
        sim.epoch,
        msg.heading_change,
        msg.speed_change,
        take_measurement=msg.take_measurement if msg.gate_measurement else None,
    )


def platform_state_msgs(sim: Simulator, count: int, frame_id: str) -> list[PlatformState]:
    """Every platform's state at the sim's epoch; ``count``: what the sim published at it
    (measurements, or scans of a multi-target run)."""
    hdr = header(sim.time, frame_id)
    return [
        PlatformState(
            header=hdr,
            platform_id=s.platform_id,
            epoch=sim.epoch,
            sensor_ids=list(s.sensor_ids),
            sensor_kinds=list(s.sensor_kinds),
            position=Point(x=float(s.pv[0]), y=float(s.pv[2])),
            velocity=Vector3(x=float(s.pv[1]), y=float(s.pv[3])),
            heading=s.heading,
            speed=s.speed,
            epoch_measurement_count=count,
        )
        for s in sim.platform_snapshots()
    ]


def main(args=None):
    spin_node(SimNode, args, done=lambda node: node.exit_when_done and node.done)


if __name__ == "__main__":
    main()
