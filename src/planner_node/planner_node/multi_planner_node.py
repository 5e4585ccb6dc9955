"""multi_planner_node: manoeuvres and beam pointings against every track of a multi-target
scenario (activetrack.multitarget.MultiTargetPlanner).

Answers each track array (epoch k) with a ManoeuvreCommand per controllable platform, a
BeamCommand per steerable sensor and a PlanReport (per-track costs), once it also holds every
platform's state of epoch k. Only the graph's own tracker and simulator count
(activetrack_ros.trust); bad messages are rejected, counted and logged; the node keeps running.
"""

from diagnostic_msgs.msg import DiagnosticArray

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.data import PlatformSnapshot
from activetrack.multitarget.data import TrackSet
from activetrack.multitarget.planner import MultiTargetPlanner
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from activetrack_ros.convert import header, platform_from_msg, report_msg
from activetrack_ros.convert_multi import beam_msg, track_array_from_msg
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import FRAME_ID, RUN, SCENARIO
from activetrack_ros.spin import spin_node
from msgs_defs.msg import BeamCommand, ManoeuvreCommand, PlanReport, PlatformState, TrackArray
from planner_node.planner_node import STATE_WINDOW, command_msg


class MultiPlannerNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("multi_planner_node", **kwargs)
        p = self.declare_params((SCENARIO, RUN, FRAME_ID))
        self.scenario = load_scenario(p["scenario"])
        self.use_scenario(self.scenario, multi_target=True)
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[2]
        self.core = MultiTargetPlanner(self.scenario, rng)
        self.platform_ids = {p.id for p in self.scenario.platforms}
        self.tracks: TrackSet | None = None
        self.platforms: dict[int, dict[str, PlatformSnapshot]] = {}
        self.last_decided = -1

        self.command_pub = self.publisher(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS)
        self.beam_pub = self.publisher(BeamCommand, topics.BEAM_COMMANDS)
        self.report_pub = self.publisher(PlanReport, topics.PLAN_REPORT)
        self.diag_pub = self.publisher(DiagnosticArray, topics.DIAGNOSTICS)
        self.subscribe(TrackArray, topics.TRACKS, self.on_tracks)
        self.subscribe(PlatformState, topics.PLATFORM_STATES, self.on_platform)

    def on_tracks(self, msg: TrackArray) -> None:
        tracks = track_array_from_msg(msg, self.scenario)
        latest = self.tracks.epoch if self.tracks is not None else -1
        if tracks.epoch <= self.last_decided or tracks.epoch < latest:
            return self.ignore("old_tracks")  # history replayed to a late joiner
        if tracks.epoch == latest:
            raise Rejected("duplicate", f"second track array of epoch {tracks.epoch}")
        self.tracks = tracks
        self.try_decide()

    def on_platform(self, msg: PlatformState) -> None:
        snap = platform_from_msg(msg, self.scenario, self.platform_ids)
        if snap.epoch <= self.last_decided:
            return self.ignore("old_state")
        states = self.platforms.setdefault(snap.epoch, {})
        if snap.platform_id in states:
            raise Rejected("duplicate", f"second state of {snap.platform_id!r} at {snap.epoch}")
        states[snap.platform_id] = snap
        while len(self.platforms) > STATE_WINDOW:  # a late joiner's replayed history: bounded
            del self.platforms[min(self.platforms)]
            self.ignore("evicted_states")
        self.try_decide()

    def try_decide(self) -> None:
        if self.tracks is None:
            return
        k = self.tracks.epoch
        states = self.platforms.get(k, {})
        if (
            k <= self.last_decided
            or k >= self.scenario.steps
            or len(states) < len(self.platform_ids)
        ):
            return
        ordered = [states[p.id] for p in self.scenario.platforms]
        decision = self.core.decide(k, self.tracks, ordered)
        self.last_decided = k
        for e in [e for e in self.platforms if e <= k]:
            del self.platforms[e]
        hdr = header(k * self.scenario.dt, self.frame_id)
        for c in decision.commands:
            self.command_pub.publish(command_msg(c, hdr))
        for beam in decision.beams:
            self.beam_pub.publish(beam_msg(beam, self.scenario, self.frame_id))
        if decision.report is not None:
            self.report_pub.publish(report_msg(decision.report, hdr))
        self.counters.count("decisions")
        confirmed = len(self.tracks.confirmed)
        self.diag_pub.publish(
            self.diagnostics_array(
                hdr,
                "activetrack/planner_node",
                self.scenario.name,
                f"decided epoch {k} for {confirmed} confirmed tracks",
            )
        )


def main(args=None):
    spin_node(MultiPlannerNode, args)


if __name__ == "__main__":
    main()
