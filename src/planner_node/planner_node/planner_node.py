"""planner_node: PCRLB / modified-Riccati manoeuvre planning and sensor selection
(activetrack.closed_loop.PlannerCore).

Answers each track (epoch k) with a ManoeuvreCommand per controllable platform, a
SensorSelection (when the scenario selects sensors) and a PlanReport, once it also holds every
platform's state of epoch k. Renewal mode: every decision starts from the track's posterior.
Only the graph's own tracker and simulator count (activetrack_ros.trust); bad messages are
rejected, counted and logged; the node keeps running.
"""

from diagnostic_msgs.msg import DiagnosticArray

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.data import Command, PlatformSnapshot, TrackSnapshot
from activetrack.closed_loop.planner import PlannerCore
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from activetrack_ros.convert import TrackChecker, header, platform_from_msg, report_msg
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import FRAME_ID, RUN, SCENARIO
from activetrack_ros.spin import spin_node
from msgs_defs.msg import (
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    SensorSelection,
    TrackEstimate,
)

# Epochs whose platform states are kept while their track is awaited (oldest evicted first).
STATE_WINDOW = 64


class PlannerNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("planner_node", **kwargs)
        p = self.declare_params((SCENARIO, RUN, FRAME_ID))  # no mode: it plans alike in both
        self.scenario = load_scenario(p["scenario"])
        self.use_scenario(self.scenario)
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[2]
        self.core = PlannerCore(self.scenario, rng)
        self.check_track = TrackChecker(self.scenario)
        self.track: TrackSnapshot | None = None
        self.platforms = AwaitedStates(self, self.scenario)
        self.last_decided = -1

        self.command_pub = self.publisher(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS)
        self.selection_pub = self.publisher(SensorSelection, topics.SENSOR_SELECTION)
        self.report_pub = self.publisher(PlanReport, topics.PLAN_REPORT)
        self.diag_pub = self.publisher(DiagnosticArray, topics.DIAGNOSTICS)
        self.subscribe(TrackEstimate, topics.TRACK, self.on_track)
        self.subscribe(PlatformState, topics.PLATFORM_STATES, self.on_platform)

    def on_track(self, msg: TrackEstimate) -> None:
        track = self.check_track(msg)
        if track.epoch <= self.last_decided or (self.track and track.epoch < self.track.epoch):
            # History replayed to a late joiner, not bad input: the latest track is what counts.
            return self.ignore("old_track")
        if self.track is not None and track.epoch == self.track.epoch:
            raise Rejected("duplicate", f"second track of epoch {track.epoch}")
        self.track = track
        self.try_decide()

    def on_platform(self, msg: PlatformState) -> None:
        if self.platforms.add(msg, self.last_decided):
            self.try_decide()

    def try_decide(self) -> None:
        if self.track is None:
            return
        k = self.track.epoch
        ordered = self.platforms.complete(k)
        if k <= self.last_decided or k >= self.scenario.steps or ordered is None:
            return
        decision = self.core.decide(k, self.track, ordered)
        self.last_decided = k
        self.platforms.decided(k)
        hdr = header(k * self.scenario.dt, self.frame_id)
        for c in decision.commands:
            self.command_pub.publish(command_msg(c, hdr))
        if decision.selected_sensor_ids is not None:
            self.selection_pub.publish(
                SensorSelection(
                    header=hdr,
                    epoch=k,
                    selected_sensor_ids=list(decision.selected_sensor_ids),
                    candidate_sensor_ids=list(decision.candidate_sensor_ids),
                    predicted_cost=[float(v) for v in decision.selection_costs],
                    criterion=decision.selection_criterion,
                )
            )
        if decision.report is not None:
            self.report_pub.publish(report_msg(decision.report, hdr))
        self.counters.count("decisions")
        self.diag_pub.publish(
            self.diagnostics_array(
                hdr, "activetrack/planner_node", self.scenario.name, f"decided epoch {k}"
            )
        )


class AwaitedStates:
    """Platform states by epoch, kept until the planner has decided for their epoch: a state
    of an epoch already decided is ignored (a latched state replayed), a second one for a
    platform and epoch rejected, and at most STATE_WINDOW epochs kept (a late joiner's
    replayed history, oldest evicted first)."""

    def __init__(self, node, scenario):
        self.node = node
        self.scenario = scenario
        self.platform_ids = {p.id for p in scenario.platforms}
        self.by_epoch: dict[int, dict[str, PlatformSnapshot]] = {}

    def add(self, msg: PlatformState, last_decided: int) -> bool:
        """Take a state; False when it is not news (counted as ignored)."""
        snap = platform_from_msg(msg, self.scenario, self.platform_ids)
        if snap.epoch <= last_decided:
            self.node.ignore("old_state")
            return False
        states = self.by_epoch.setdefault(snap.epoch, {})
        if snap.platform_id in states:
            raise Rejected("duplicate", f"second state of {snap.platform_id!r} at {snap.epoch}")
        states[snap.platform_id] = snap
        while len(self.by_epoch) > STATE_WINDOW:
            del self.by_epoch[min(self.by_epoch)]
            self.node.ignore("evicted_states")
        return True

    def complete(self, k: int) -> list[PlatformSnapshot] | None:
        """Every platform's state of epoch k in scenario order, or None while one is missing."""
        states = self.by_epoch.get(k, {})
        if len(states) < len(self.platform_ids):
            return None
        return [states[p.id] for p in self.scenario.platforms]

    def decided(self, k: int) -> None:
        """Drop the states of epochs up to k."""
        for e in [e for e in self.by_epoch if e <= k]:
            del self.by_epoch[e]


def command_msg(c: Command, hdr) -> ManoeuvreCommand:
    """A planner's Command as a ManoeuvreCommand stamped ``hdr`` (its decision epoch)."""
    msg = ManoeuvreCommand(
        header=hdr,
        platform_id=c.platform_id,
        epoch=c.epoch,
        heading_change=c.heading_change,
        speed_change=c.speed_change,
        commanded_heading=c.commanded_heading,
        commanded_speed=c.commanded_speed,
        gate_measurement=c.take_measurement is not None,
        take_measurement=bool(c.take_measurement),
        has_waypoint=c.waypoint is not None,
    )
    if c.waypoint is not None:
        msg.waypoint.x, msg.waypoint.y = (float(v) for v in c.waypoint)
    return msg


def main(args=None):
    spin_node(PlannerNode, args)


if __name__ == "__main__":
    main()
