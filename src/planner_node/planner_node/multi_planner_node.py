"""multi_planner_node: manoeuvres and beam pointings against every track of a multi-target
scenario (activetrack.multitarget.MultiTargetPlanner).

Answers each track array (epoch k) with a ManoeuvreCommand per controllable platform, a
BeamCommand per steerable sensor and a PlanReport (per-track costs), once it also holds every
platform's state of epoch k. Only the graph's own tracker and simulator count
(activetrack_ros.trust); bad messages are rejected, counted and logged; the node keeps running.
"""

from diagnostic_msgs.msg import DiagnosticArray

from activetrack.closed_loop.batch import component_rngs
from activetrack.multitarget.data import TrackSet
from activetrack.multitarget.planner import MultiTargetPlanner
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from activetrack_ros.convert import header, report_msg
from activetrack_ros.convert_multi import beam_msg, track_array_from_msg
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import FRAME_ID, RUN, SCENARIO
from activetrack_ros.spin import spin_node
from msgs_defs.msg import BeamCommand, ManoeuvreCommand, PlanReport, PlatformState, TrackArray
from planner_node.planner_node import AwaitedStates, command_msg


class MultiPlannerNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("multi_planner_node", **kwargs)
        p = self.declare_params((SCENARIO, RUN, FRAME_ID))
        self.scenario = load_scenario(p["scenario"])
        self.use_scenario(self.scenario, multi_target=True)
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[2]
        self.core = MultiTargetPlanner(self.scenario, rng)
        self.tracks: TrackSet | None = None
        self.platforms = AwaitedStates(self, self.scenario)
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
        if self.platforms.add(msg, self.last_decided):
            self.try_decide()

    def try_decide(self) -> None:
        if self.tracks is None:
            return
        k = self.tracks.epoch
        ordered = self.platforms.complete(k)
        if k <= self.last_decided or k >= self.scenario.steps or ordered is None:
            return
        decision = self.core.decide(k, self.tracks, ordered)
        self.last_decided = k
        self.platforms.decided(k)
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
