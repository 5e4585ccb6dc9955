"""sim_node: the simulated targets and sensor platforms of a scenario
(activetrack.simulation.Simulator).

Publishes /clock, every alive target's truth (evaluators only), platform states and one
``Scan`` per looking sensor and epoch; obeys the planner's ManoeuvreCommand (clamped to each
platform's limits, counted), BeamCommand and SensorSelection. ``lockstep`` mode: epoch k+1 is
simulated once every command, beam and (with selection on) the selection of epoch k have
arrived (with none to await, the track array of epoch k), so a run is deterministic for a
seed. While the tracker has not answered epoch k (its track array) the epoch's messages are
still in the graph and the sim waits (up to ``tracks_timeout``); from the track array on, an
answer missing after ``command_timeout`` wall seconds means hold course, keep the beam and
the selection (warned, counted, recorded as ``timeout.<k>.*``; docs/robustness.md,
"Lockstep"). ``free`` mode: sim time runs at ``rate`` x wall time and answers apply at once.
"""

import math
import time

from geometry_msgs.msg import Point
from rosgraph_msgs.msg import Clock
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.components import build_simulator, component_rngs, scene_sensors
from activetrack.data import BeamCommand, Command
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    beam_from_msg,
    check_epoch_stamp,
    command_from_msg,
    header,
    marker,
    platform_state_msg,
    scan_msg,
    selection_from_msg,
    truth_array_msg,
)
from activetrack_ros.frames import planar_transform, platform_frame, sensor_frame, truth_frame
from activetrack_ros.hold import WAIT_FOR, FirstEpochHold
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import COMMON, ParamSpec
from activetrack_ros.spin import spin_node
from msgs_defs.msg import BeamCommand as BeamCommandMsg
from msgs_defs.msg import (
    GroundTruthArray,
    ManoeuvreCommand,
    PlatformState,
    Scan,
    SensorSelection,
    TrackArray,
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
        "lockstep: wall seconds to wait for a platform's command (or a beam, or the selection) "
        "after the epoch's track array before it holds course (changeable while running)",
        read_only=False, low=1e-3, high=3600.0,
    ),
    ParamSpec(
        "tracks_timeout", 30.0,
        "lockstep: wall seconds to wait for the tracker's track array of an epoch (it closes an "
        "incomplete epoch after its epoch_timeout) before holding course (changeable)",
        read_only=False, low=1e-3, high=3600.0,
    ),
    ParamSpec(
        "expect_tracker", False,
        "lockstep: a tracker belongs to this graph (the graph runner sets it), so the sim waits "
        "tracks_timeout for its track array even while its writer is not yet discovered (a "
        "tracker process still starting); false: no track array writer on the graph after "
        "command_timeout means the sim runs alone",
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
        self.use_scenario(load_scenario(p["scenario"]))
        self.rate = p["rate"]
        self.timeout = p["command_timeout"]
        self.tracks_timeout = p["tracks_timeout"]
        self.expect_tracker = p["expect_tracker"]
        self.exit_when_done = p["exit_when_done"]
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[0]
        self.sim = build_simulator(self.scenario, rng)
        self.sensors = scene_sensors(self.scenario)
        changes.update(
            command_timeout=self.setter("timeout"),
            tracks_timeout=self.setter("tracks_timeout"),
            exit_when_done=self.setter("exit_when_done"),
            rate=self._set_rate
            if self.mode == "free"
            else "parameter 'rate' applies in free "
            "mode only (this node runs lockstep: each epoch waits for the planner)",
        )
        self.tf_pub = self.publisher(TFMessage, topics.TF)
        self.tf_static_pub = self.publisher(TFMessage, topics.TF_STATIC)
        self.clock_pub = self.publisher(Clock, topics.CLOCK)
        self.truth_pub = self.publisher(GroundTruthArray, topics.GROUND_TRUTH)
        self.platform_pub = self.publisher(PlatformState, topics.PLATFORM_STATES)
        self.scan_pub = self.publisher(Scan, topics.SCANS)
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        self.paths: dict[str, list[Point]] = {pid: [] for pid in self.sim.platforms}
        self.path_chunk = dict.fromkeys(self.sim.platforms, 0)
        self.subscribe(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command)
        self.subscribe(BeamCommandMsg, topics.BEAM_COMMANDS, self.on_beam)
        self.subscribe(SensorSelection, topics.SENSOR_SELECTION, self.on_selection)
        self.subscribe(TrackArray, topics.TRACKS, self.on_tracks)

        self.pending: dict[str, Command] = {}
        self.beams: dict[str, BeamCommand] = {}
        self.selection: tuple[str, ...] | None = None
        self.selection_epoch = -1
        # Lockstep: with selection on, epoch k+1 also waits for the selection decided at k.
        planner = self.scenario.planner
        self.expects_selection = planner.enabled and planner.selection.enabled
        self.last_track_epoch = -1
        self.done = False
        # Lockstep: the tracker has answered the current epoch (its track array, or an answer
        # of the epoch, which the planner gives only on it); the wait for answers starts then.
        self.answered = False
        self.epoch_started = time.monotonic()  # or, once answered, when the tracker answered
        self.clock_origin = (time.monotonic(), 0.0)  # free mode: (wall, sim) at the last rate
        self.publish_static_frames()
        self.hold = FirstEpochHold(self, p, self._first_epoch, changes)
        self.guarded_timer(p["tick"], self.on_tick)

    def _first_epoch(self) -> None:
        """Epoch 0, now (at start-up, or when a held first epoch is released)."""
        self.clock_origin = (time.monotonic(), self.sim.time)
        self.publish_epoch([])
        self._epoch_begins()

    def _set_rate(self, rate: float) -> None:
        """Sim time stays continuous: the new rate counts from now."""
        self.clock_origin = (time.monotonic(), self.sim_time_now())
        self.rate = rate

    def sim_time_now(self) -> float:
        wall, sim = self.clock_origin
        return sim + (time.monotonic() - wall) * self.rate

    def _check_epoch(self, epoch: int, what: str) -> None:
        """Lockstep: an answer must be of the sim's current epoch."""
        current = self.sim.epoch
        if self.mode == "lockstep" and epoch < current:
            raise Rejected("stale_epoch", f"{what} for epoch {epoch} < {current}")
        if self.mode == "lockstep" and epoch > current:
            raise Rejected("future_epoch", f"{what} for epoch {epoch} > {current}")

    def _answer(self, answers: dict, key: str, answer, epoch: int, what: str, apply) -> None:
        """Free mode: ``apply(answer)`` now; lockstep: keep it (one per ``key``) for the step."""
        self._check_epoch(epoch, what)
        if self.mode == "free":
            return apply(answer)
        if key in answers:
            raise Rejected("duplicate", f"second {what} at epoch {epoch}")
        answers[key] = answer
        self._tracker_answered()
        self.step_if_ready()

    def on_command(self, msg: ManoeuvreCommand) -> None:
        cmd = command_from_msg(msg, self.scenario, self.sim.epoch, self.sim.controllable_ids)
        what = f"command for {msg.platform_id!r}"
        self._answer(self.pending, msg.platform_id, cmd, msg.epoch, what, self.apply)

    def on_beam(self, msg: BeamCommandMsg) -> None:
        beam = beam_from_msg(msg, self.scenario)
        what = f"beam command of {beam.sensor_id!r}"
        self._answer(self.beams, beam.sensor_id, beam, beam.epoch, what, self._beam_now)

    def _beam_now(self, beam: BeamCommand) -> None:
        self.sim.apply_beam(BeamCommand(beam.sensor_id, self.sim.epoch, beam.bearing))

    def on_selection(self, msg: SensorSelection) -> None:
        if not self.expects_selection:
            raise Rejected("unexpected_selection", "the scenario does not select sensors")
        ids = selection_from_msg(msg, self.scenario, self.sim.sensors)
        self._check_epoch(msg.epoch, "selection")
        if self.mode == "lockstep" and self.selection_epoch == msg.epoch:
            raise Rejected("duplicate", f"second selection at epoch {msg.epoch}")
        self.selection = ids
        self.selection_epoch = msg.epoch
        self._tracker_answered()
        self.step_if_ready()

    def on_tracks(self, msg: TrackArray) -> None:
        # Only a lockstep signal when nothing is commanded: the sim never reads the tracks.
        check_epoch_stamp(msg, self.scenario, "track array")
        if msg.epoch > self.sim.epoch:
            raise Rejected("future_epoch", f"track array of epoch {msg.epoch} > {self.sim.epoch}")
        self.last_track_epoch = max(self.last_track_epoch, msg.epoch)
        if msg.epoch == self.sim.epoch:
            self._tracker_answered()
        self.step_if_ready()

    def _epoch_begins(self) -> None:
        self.epoch_started = time.monotonic()
        self.answered = self.last_track_epoch >= self.sim.epoch

    def _tracker_answered(self) -> None:
        """The epoch's messages have left the graph's tracker: the command timeout starts."""
        if not self.answered:
            self.answered = True
            self.epoch_started = time.monotonic()

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
        if not self.sim.controllable_ids and not self.sim.steerable_ids:
            return self.last_track_epoch >= k
        commands = all(pid in self.pending for pid in self.sim.controllable_ids)
        return commands and all(sid in self.beams for sid in self.sim.steerable_ids)

    def step_if_ready(self) -> None:
        if self.mode == "lockstep" and not self.done and not self.sim.finished and self.ready():
            self.on_tick()  # the epoch's last answer: step now, not at the next tick

    def on_tick(self) -> None:
        if self.done or self.hold.waiting:
            return
        if self.sim.finished:
            self.done = True
            self.publish_diagnostics(header(self.sim.time, self.frame_id), "finished")
            self.get_logger().info(f"scenario {self.scenario.name} finished")
            return
        if self.mode == "free":
            sim_time = self.sim_time_now()
            self.clock_pub.publish(Clock(clock=header(sim_time, self.frame_id).stamp))
            if sim_time >= self.sim.time + self.sim.dt:
                self.step()
            return
        if not self.ready():
            if not self.waited_out():
                return
            self.hold_missing()
        # The batch loop's order (activetrack.closed_loop.loop): commands, beams, selection.
        for pid in self.sim.controllable_ids:
            self.apply(self.pending[pid])
        for sid in self.sim.steerable_ids:
            if sid in self.beams:
                self.sim.apply_beam(self.beams[sid])
        self.step()

    def waited_out(self) -> bool:
        """Lockstep, epoch incomplete: has the wait for its answers run out? Until the tracker
        answers, the epoch's messages are still in the graph (a late scan the tracker waits
        for): the sim waits up to tracks_timeout, or command_timeout if no tracker is on the
        graph (the sim alone; never with expect_tracker); then command_timeout from the
        tracker's answer."""
        waited = time.monotonic() - self.epoch_started
        if self.answered:
            return waited >= self.timeout
        if waited >= self.tracks_timeout:
            return True
        alone = not self.expect_tracker and self.count_publishers(topics.TRACKS) == 0
        return waited >= self.timeout and alone

    def hold_missing(self) -> None:
        """Past the timeout: hold course, keep the beams and the selection (warned, counted,
        recorded for the epoch as ``timeout.<k>.*``)."""
        k = self.sim.epoch
        missing = [p for p in self.sim.controllable_ids if p not in self.pending]
        for pid in missing:
            self.pending[pid] = Command(pid, k, 0.0, 0.0)
        beams = [s for s in self.sim.steerable_ids if s not in self.beams]
        selection = self.expects_selection and self.selection_epoch != k
        self.counters.count("command_timeouts", max(1, len(missing) + len(beams) + selection))
        for what, n in (
            ("no_track_array", not self.answered),
            ("held_course", len(missing)),
            ("kept_beam", len(beams)),
            ("kept_selection", selection),
        ):
            if n:
                self.counters.count(f"timeout.{k}.{what}", int(n))
        waited = time.monotonic() - self.epoch_started  # (the sim alone: command_timeout)
        self.get_logger().warning(
            f"epoch {k}: {'' if self.answered else 'no track array, '}no command for "
            f"{missing}, no beam for {beams}{', no selection' if selection else ''} after "
            f"{waited:.1f} s; holding course"
        )

    def step(self) -> None:
        if self.selection is not None and self.selection_epoch == self.sim.epoch:
            self.sim.apply_selection(self.selection)
        self.pending.clear()
        self.beams.clear()
        self.publish_epoch(self.sim.advance())
        self._epoch_begins()

    def publish_epoch(self, scans) -> None:
        t = self.sim.time
        self.clock_pub.publish(Clock(clock=header(t, self.frame_id).stamp))
        truth = self.sim.truth_set()
        self.truth_pub.publish(truth_array_msg(truth, self.frame_id))
        for scan in scans:
            self.scan_pub.publish(
                scan_msg(scan, self.scenario, len(scans), self.frame_id, self.sensors)
            )
            self.counters.count("scans_published")
            self.counters.count("detections_published", len(scan.Z))
            if len(scan.Z) == 0:
                self.counters.count("empty_scans")
        for s in self.sim.platform_snapshots():
            self.platform_pub.publish(platform_state_msg(s, len(scans), self.frame_id))
        self.counters.count("epochs_published")
        if self.tf_pub.has_readers():  # a view (volatile): built for readers only
            self.publish_frames(t, truth)
        self.publish_markers(t)
        message = f"epoch {self.sim.epoch}/{self.scenario.steps}"
        self.publish_diagnostics(header(t, self.frame_id), message)

    def publish_frames(self, t: float, truth) -> None:
        """Platforms and each alive target's truth in the fixed frame (docs/frames.md)."""
        hdr = header(t, self.frame_id)
        transforms = [
            planar_transform(hdr, platform_frame(s.platform_id), s.pv[0], s.pv[2], s.heading)
            for s in self.sim.platform_snapshots()
        ]
        for target_id, pv in zip(truth.ids, truth.pv, strict=True):
            course = math.atan2(pv[3], pv[1])
            transforms.append(planar_transform(hdr, truth_frame(target_id), pv[0], pv[2], course))
        self.tf_pub.publish(TFMessage(transforms=transforms))

    def publish_static_frames(self) -> None:
        """Each sensor at its platform's origin (tf_static, one message)."""
        transforms = [
            planar_transform(header(0.0, platform_frame(p.id)), sensor_frame(s.id), 0, 0, 0)
            for p in self.scenario.platforms
            for s in p.sensors
        ]
        self.tf_static_pub.publish(TFMessage(transforms=transforms))

    def publish_markers(self, t: float) -> None:
        """Each platform's path as line strips of PATH_CHUNK points (``platforms/<id>``, id: the
        chunk's index) sharing end points: only the newest is republished (linear bytes).
        The paths grow whether or not the markers have a reader (one may join later)."""
        for pid, p in self.sim.platforms.items():
            path = self.paths[pid]
            if len(path) == PATH_CHUNK:  # chunk full: the next one starts where it ended
                self.path_chunk[pid] += 1
                del path[:-1]
            path.append(Point(x=float(p.pv[0]), y=float(p.pv[2])))
        if not self.marker_pub.has_readers():
            return
        array = MarkerArray()
        for pid, path in self.paths.items():
            hdr = header(t, self.frame_id)
            chunk = self.path_chunk[pid]
            m = marker(hdr, f"platforms/{pid}", chunk, Marker.LINE_STRIP, (0.1, 0.4, 0.9, 1.0))
            m.scale.x = 20.0  # line width, m
            m.points = list(path)
            array.markers.append(m)
        self.marker_pub.publish(array)


def main(args=None):
    spin_node(SimNode, args, done=lambda node: node.exit_when_done and node.done)
