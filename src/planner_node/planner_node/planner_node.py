"""planner_node: the scenario's planner (activetrack.closed_loop.components.build_planner).

Answers each track array (epoch k) with a ManoeuvreCommand per controllable platform, a
BeamCommand per steerable sensor, a SensorSelection (when the scenario selects sensors) and a
PlanReport, once it also holds every platform's state of epoch k. Renewal mode: every decision
starts from the tracks' posteriors.
"""

from activetrack.closed_loop.components import build_planner, component_rngs
from activetrack.data import PlatformSnapshot, TrackSet
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    TrackArrayChecker,
    beam_msg,
    command_msg,
    header,
    platform_from_msg,
    report_msg,
    selection_msg,
)
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import FRAME_ID, RUN, SCENARIO
from activetrack_ros.spin import spin_node
from msgs_defs.msg import (
    BeamCommand,
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    SensorSelection,
    TrackArray,
)

# Epochs whose platform states are kept while their track array is awaited (oldest evicted).
STATE_WINDOW = 64


class PlannerNode(GraphNode):
    """Platform states are kept by epoch until decided: one of a decided epoch is ignored (a
    latched state replayed), a second one for a platform and epoch rejected, and at most
    STATE_WINDOW epochs kept (a late joiner's replayed history, oldest evicted first)."""

    def __init__(self, **kwargs):
        super().__init__("planner_node", **kwargs)
        p = self.declare_params((SCENARIO, RUN, FRAME_ID))  # no mode: it plans alike in both
        self.use_scenario(load_scenario(p["scenario"]))
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[2]
        self.core = build_planner(self.scenario, rng)
        self.check_tracks = TrackArrayChecker(self.scenario)
        self.tracks: TrackSet | None = None
        self.platform_ids = {p.id for p in self.scenario.platforms}
        self.states: dict[int, dict[str, PlatformSnapshot]] = {}  # by epoch
        self.last_decided = -1

        self.command_pub = self.publisher(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS)
        self.beam_pub = self.publisher(BeamCommand, topics.BEAM_COMMANDS)
        self.selection_pub = self.publisher(SensorSelection, topics.SENSOR_SELECTION)
        self.report_pub = self.publisher(PlanReport, topics.PLAN_REPORT)
        self.subscribe(TrackArray, topics.TRACKS, self.on_tracks)
        self.subscribe(PlatformState, topics.PLATFORM_STATES, self.on_platform)

    def on_tracks(self, msg: TrackArray) -> None:
        tracks = self.check_tracks(msg)
        latest = self.tracks.epoch if self.tracks is not None else -1
        if tracks.epoch <= self.last_decided or tracks.epoch < latest:
            # History replayed to a late joiner, not bad input: the latest tracks count.
            return self.ignore("old_tracks")
        if tracks.epoch == latest:
            raise Rejected("duplicate", f"second track array of epoch {tracks.epoch}")
        self.tracks = tracks
        self.try_decide()

    def on_platform(self, msg: PlatformState) -> None:
        snap = platform_from_msg(msg, self.scenario, self.platform_ids)
        if snap.epoch <= self.last_decided:
            return self.ignore("old_state")
        states = self.states.setdefault(snap.epoch, {})
        if snap.platform_id in states:
            raise Rejected("duplicate", f"second state of {snap.platform_id!r} at {snap.epoch}")
        states[snap.platform_id] = snap
        while len(self.states) > STATE_WINDOW:
            evicted = self.states.pop(min(self.states))
            self.ignore_taken("PlatformState", "evicted_states", len(evicted))
        self.try_decide()

    def try_decide(self) -> None:
        if self.tracks is None:
            return
        k = self.tracks.epoch
        states = self.states.get(k, {})
        if (
            k <= self.last_decided
            or k >= self.scenario.steps
            or len(states) < len(self.platform_ids)
        ):
            return
        ordered = [states[p.id] for p in self.scenario.platforms]
        decision = self.core.decide(k, self.tracks, ordered)
        self.last_decided = k
        for e in [e for e in self.states if e <= k]:
            del self.states[e]
        dt, frame = self.scenario.dt, self.frame_id
        for c in decision.commands:
            self.command_pub.publish(command_msg(c, dt, frame))
        for beam in decision.beams:
            self.beam_pub.publish(beam_msg(beam, dt, frame))
        if decision.selected_sensor_ids is not None:
            self.selection_pub.publish(selection_msg(k, dt, frame, decision))
        hdr = header(k * dt, frame)
        if decision.report is not None:
            self.report_pub.publish(report_msg(decision.report, hdr))
        self.counters.count("decisions")
        confirmed = len(self.tracks.confirmed)
        self.publish_diagnostics(hdr, f"decided epoch {k} for {confirmed} confirmed track(s)")


def main(args=None):
    spin_node(PlannerNode, args)
