"""multi_sim_node: the targets and sensor platforms of a multi-target scenario
(activetrack.multitarget.MultiTargetSimulator).

Publishes /clock, every alive target's truth (``GroundTruthArray``, evaluators only), platform
states and one ``Scan`` of unlabelled detections per looking sensor and epoch; obeys the
planner's ManoeuvreCommand (clamped to each platform's limits, logged and counted) and
BeamCommand (a steerable sensor's pointing for the next epoch).

Lockstep only (the deterministic mode, equal to ``activetrack batch`` bit for bit): epoch k+1
is simulated once every controllable platform's command and every steerable sensor's beam of
epoch k have arrived (with neither, once the track array of epoch k has); one missing after
``command_timeout`` wall seconds means hold course or keep the beam (warned and counted).
"""

import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock
from tf2_msgs.msg import TFMessage

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.data import Command
from activetrack.multitarget.data import BeamCommand, TruthSet
from activetrack.multitarget.simulator import MultiTargetSimulator
from activetrack.scenarios import load_scenario
from activetrack.scenarios.build import build_scan_sensors
from activetrack_ros import graph as topics
from activetrack_ros.convert import check_epoch_stamp, header
from activetrack_ros.convert_multi import beam_from_msg, scan_msg, truth_array_msg
from activetrack_ros.frames import planar_transform, platform_frame, truth_frame
from activetrack_ros.hold import FirstEpochHold
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.spin import spin_node
from msgs_defs.msg import (
    BeamCommand as BeamCommandMsg,
)
from msgs_defs.msg import (
    GroundTruthArray,
    ManoeuvreCommand,
    PlatformState,
    Scan,
    TrackArray,
)
from sim_node.sim_node import (
    PARAMS,
    check_lockstep_epoch,
    command_from_msg,
    platform_state_msgs,
    sim_diagnostics,
    static_frames,
)

# The single-target sim's parameters but its free-mode rate (multi-target runs are lockstep).
MULTI_PARAMS = tuple(p for p in PARAMS if p.name != "rate")


class MultiSimNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("multi_sim_node", **kwargs)
        changes = {"command_timeout": self._set_timeout, "exit_when_done": self._set_exit}
        p = self.declare_params(MULTI_PARAMS, changes)
        self.scenario = load_scenario(p["scenario"])
        self.use_scenario(self.scenario, multi_target=True, mode=p["mode"])
        self.timeout = p["command_timeout"]
        self.exit_when_done = p["exit_when_done"]
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[0]
        self.sim = MultiTargetSimulator(self.scenario, rng)
        self.sensors = build_scan_sensors(self.scenario)
        self.steerable = tuple(self.sim.pointing)

        self.clock_pub = self.publisher(Clock, topics.CLOCK)
        self.truth_pub = self.publisher(GroundTruthArray, topics.GROUND_TRUTH_ARRAY)
        self.platform_pub = self.publisher(PlatformState, topics.PLATFORM_STATES)
        self.scan_pub = self.publisher(Scan, topics.SCANS)
        self.diag_pub = self.publisher(DiagnosticArray, topics.DIAGNOSTICS)
        self.tf_pub = self.publisher(TFMessage, topics.TF)
        self.tf_static_pub = self.publisher(TFMessage, topics.TF_STATIC)
        self.subscribe(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command)
        self.subscribe(BeamCommandMsg, topics.BEAM_COMMANDS, self.on_beam)
        self.subscribe(TrackArray, topics.TRACKS, self.on_tracks)

        self.pending: dict[str, Command] = {}
        self.beams: dict[str, BeamCommand] = {}
        self.last_track_epoch = -1
        self.done = False
        self.epoch_started = time.monotonic()
        self.publish_static_frames()
        self.hold = FirstEpochHold(self, p, self._first_epoch, changes)
        self.guarded_timer(p["tick"], self.on_tick)

    def _first_epoch(self) -> None:
        """Epoch 0, now (at start-up, or when a held first epoch is released)."""
        self.publish_epoch([])
        self.epoch_started = time.monotonic()

    def _set_timeout(self, seconds: float) -> None:
        self.timeout = seconds

    def _set_exit(self, value: bool) -> None:
        self.exit_when_done = value

    # --- inputs --------------------------------------------------------------------------

    def _check_epoch(self, epoch: int, what: str) -> None:
        check_lockstep_epoch(epoch, self.sim.epoch, what)

    def on_command(self, msg: ManoeuvreCommand) -> None:
        cmd = command_from_msg(msg, self.scenario, self.sim)
        what = f"command for {msg.platform_id!r}"
        self._check_epoch(msg.epoch, what)
        if msg.platform_id in self.pending:
            raise Rejected("duplicate", f"second {what} at epoch {msg.epoch}")
        self.pending[msg.platform_id] = cmd
        self.step_if_ready()

    def on_beam(self, msg: BeamCommandMsg) -> None:
        beam = beam_from_msg(msg, self.scenario)
        what = f"beam command of {beam.sensor_id!r}"
        self._check_epoch(beam.epoch, what)
        if beam.sensor_id in self.beams:
            raise Rejected("duplicate", f"second {what} at epoch {beam.epoch}")
        self.beams[beam.sensor_id] = beam
        self.step_if_ready()

    def on_tracks(self, msg: TrackArray) -> None:
        # Only a lockstep signal when nothing is commanded: the sim never reads the tracks.
        check_epoch_stamp(msg, self.scenario, "track array")
        if msg.epoch > self.sim.epoch:
            raise Rejected("future_epoch", f"track array of epoch {msg.epoch} > {self.sim.epoch}")
        self.last_track_epoch = max(self.last_track_epoch, msg.epoch)
        self.step_if_ready()

    # --- stepping ------------------------------------------------------------------------

    def ready(self) -> bool:
        if not self.sim.controllable_ids and not self.steerable:
            return self.last_track_epoch >= self.sim.epoch
        commands = all(pid in self.pending for pid in self.sim.controllable_ids)
        return commands and all(sid in self.beams for sid in self.steerable)

    def step_if_ready(self) -> None:
        if not self.done and not self.sim.finished and self.ready():
            self.on_tick()  # the epoch's last answer: step now, not at the next tick

    def on_tick(self) -> None:
        if self.done or self.hold.waiting:
            return
        if self.sim.finished:
            self.done = True
            self.publish_diagnostics(finished=True)
            self.get_logger().info(f"scenario {self.scenario.name} finished")
            return
        if not self.ready():
            if time.monotonic() - self.epoch_started < self.timeout:
                return
            self.hold_missing()
        # The batch loop's order (activetrack.multitarget.loop): commands, then beams.
        for pid in self.sim.controllable_ids:
            result = self.sim.apply_command(self.pending[pid])
            self.counters.count("commands_applied")
            if result.clamped:
                self.counters.count("commands_clamped")
                self.log_limited(
                    "warning", "clamped", f"command for {pid!r} clamped: {result.message}"
                )
        for sid in self.steerable:
            if sid in self.beams:
                self.sim.apply_beam(self.beams[sid])
        self.pending.clear()
        self.beams.clear()
        self.publish_epoch(self.sim.advance())
        self.epoch_started = time.monotonic()

    def hold_missing(self) -> None:
        """Past the timeout: hold course, keep the beams where they point (warned, counted)."""
        k = self.sim.epoch
        missing = [p for p in self.sim.controllable_ids if p not in self.pending]
        for pid in missing:
            self.pending[pid] = Command(pid, k, 0.0, 0.0)
        beams = [s for s in self.steerable if s not in self.beams]
        self.counters.count("command_timeouts", max(1, len(missing) + len(beams)))
        self.get_logger().warning(
            f"epoch {k}: no command for {missing} and no beam for {beams} after "
            f"{self.timeout} s; holding course, beams kept"
        )

    # --- outputs -------------------------------------------------------------------------

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
        for msg in platform_state_msgs(self.sim, len(scans), self.frame_id):
            self.platform_pub.publish(msg)
        self.counters.count("epochs_published")
        self.publish_frames(t, truth)
        self.publish_diagnostics()

    def publish_frames(self, t: float, truth: TruthSet) -> None:
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
        self.tf_static_pub.publish(static_frames(self.scenario))

    def publish_diagnostics(self, finished: bool = False) -> None:
        self.diag_pub.publish(sim_diagnostics(self, finished))


def main(args=None):
    spin_node(MultiSimNode, args, done=lambda node: node.exit_when_done and node.done)


if __name__ == "__main__":
    main()
