"""planner_node: PCRLB / modified-Riccati manoeuvre planning and sensor selection
(activetrack.closed_loop.PlannerCore).

Answers each track (epoch k) with a ManoeuvreCommand per controllable platform, a
SensorSelection (when the scenario selects sensors) and a PlanReport. Renewal mode: every
decision starts from the track's posterior. Bad messages are rejected, counted and logged.
"""

import math

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.time import Time
from std_msgs.msg import Header

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.counters import NodeCounters
from activetrack.closed_loop.data import PlatformSnapshot, TrackSnapshot
from activetrack.closed_loop.planner import PlannerCore
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from msgs_defs.msg import (
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    SensorSelection,
    TrackEstimate,
)

LATCHED = topics.writer_qos(topics.TRACK)


class PlannerNode(Node):
    def __init__(self, **kwargs):
        super().__init__("planner_node", **kwargs)
        self.declare_parameter("scenario", "")
        self.declare_parameter("run", -1)
        path = self.get_parameter("scenario").value
        if not path:
            raise ValueError("parameter 'scenario' must name a scenario YAML file")
        self.scenario = load_scenario(path)
        run = int(self.get_parameter("run").value)
        rng = component_rngs(self.scenario.seed, None if run < 0 else run)[2]
        self.core = PlannerCore(self.scenario, rng)
        self.platform_ids = {p.id for p in self.scenario.platforms}
        self.counters = NodeCounters()
        self.track: TrackSnapshot | None = None
        self.platforms: dict[int, dict[str, PlatformSnapshot]] = {}
        self.last_decided = -1

        self.command_pub = self.create_publisher(
            ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, LATCHED
        )
        self.selection_pub = self.create_publisher(
            SensorSelection, topics.SENSOR_SELECTION, LATCHED
        )
        self.report_pub = self.create_publisher(PlanReport, topics.PLAN_REPORT, LATCHED)
        self.diag_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS, 10)
        self.create_subscription(TrackEstimate, topics.TRACK, self.on_track, LATCHED)
        self.create_subscription(PlatformState, topics.PLATFORM_STATES, self.on_platform, LATCHED)

    def _reject(self, reason: str, detail: str) -> None:
        self.counters.rejected(reason)
        self.get_logger().warning(f"rejected {reason}: {detail}")

    def on_track(self, msg: TrackEstimate) -> None:
        self.counters.received("TrackEstimate")
        n = len(msg.state)
        values = np.array(msg.state, dtype=float)
        if n == 0 or len(msg.covariance) != n * n or len(msg.state_names) != n:
            return self._reject("malformed", f"track with {n} states, {len(msg.covariance)} cov")
        P = np.array(msg.covariance, dtype=float).reshape(n, n)
        samples = np.array(msg.particle_samples, dtype=float)
        if not (
            np.all(np.isfinite(values)) and np.all(np.isfinite(P)) and np.all(np.isfinite(samples))
        ):
            return self._reject("non_finite", f"track epoch {msg.epoch}")
        if not np.allclose(P, P.T) or np.any(np.linalg.eigvalsh(P) <= 0):
            return self._reject("bad_covariance", f"track epoch {msg.epoch}")
        if msg.sample_count and samples.size != msg.sample_count * n:
            return self._reject("malformed", f"{samples.size} sample values for {msg.sample_count}")
        if msg.epoch > self.scenario.steps:
            return self._reject("future_epoch", f"track epoch {msg.epoch}")
        if msg.epoch <= self.last_decided or (self.track and msg.epoch < self.track.epoch):
            # History replayed to a late joiner, not bad input: the latest track is what counts.
            self.counters.count("old_tracks_ignored")
            return
        self.track = TrackSnapshot(
            epoch=msg.epoch,
            time=Time.from_msg(msg.header.stamp).nanoseconds * 1e-9,
            filter_kind=msg.filter_kind,
            motion_model=msg.motion_model,
            state_names=tuple(msg.state_names),
            mean=values,
            cov=P,
            samples=samples.reshape(msg.sample_count, n) if msg.sample_count else None,
            update_count=msg.update_count,
            missed_detections=msg.missed_detections,
            nis=msg.nis,
            ess=msg.ess,
            particle_count=msg.particle_count,
        )
        self.try_decide()

    def on_platform(self, msg: PlatformState) -> None:
        self.counters.received("PlatformState")
        if msg.platform_id not in self.platform_ids:
            return self._reject("unknown_platform", repr(msg.platform_id))
        pv = np.array([msg.position.x, msg.velocity.x, msg.position.y, msg.velocity.y])
        if not (
            np.all(np.isfinite(pv)) and math.isfinite(msg.heading) and math.isfinite(msg.speed)
        ):
            return self._reject("non_finite", f"platform {msg.platform_id!r}")
        if msg.epoch <= self.last_decided:
            return  # a latched state already planned for (late joiners get history)
        snap = PlatformSnapshot(
            msg.platform_id,
            msg.epoch,
            Time.from_msg(msg.header.stamp).nanoseconds * 1e-9,
            pv,
            msg.heading,
            msg.speed,
        )
        self.platforms.setdefault(msg.epoch, {})[msg.platform_id] = snap
        self.try_decide()

    def try_decide(self) -> None:
        if self.track is None:
            return
        k = self.track.epoch
        states = self.platforms.get(k, {})
        if (
            k <= self.last_decided
            or k >= self.scenario.steps
            or len(states) < len(self.platform_ids)
        ):
            return
        ordered = [states[p.id] for p in self.scenario.platforms]
        decision = self.core.decide(k, self.track, ordered)
        self.last_decided = k
        for e in [e for e in self.platforms if e <= k]:
            del self.platforms[e]
        header = Header(stamp=Time(seconds=k * self.scenario.dt).to_msg(), frame_id="world")
        for c in decision.commands:
            msg = ManoeuvreCommand(
                header=header,
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
            self.command_pub.publish(msg)
        if decision.selected_sensor_ids is not None:
            self.selection_pub.publish(
                SensorSelection(
                    header=header,
                    epoch=k,
                    selected_sensor_ids=list(decision.selected_sensor_ids),
                    candidate_sensor_ids=list(decision.candidate_sensor_ids),
                    predicted_cost=[float(v) for v in decision.selection_costs],
                    criterion=decision.selection_criterion,
                )
            )
        r = decision.report
        if r is not None:
            self.report_pub.publish(
                PlanReport(
                    header=header,
                    epoch=k,
                    cost_kind=r.cost_kind,
                    criterion=r.criterion,
                    search=r.search,
                    horizon=r.horizon,
                    cost_names=list(r.cost_names),
                    predicted_costs=[float(v) for v in r.predicted_costs],
                    evaluations=r.evaluations,
                    planning_wall_time=r.wall_time_s,
                )
            )
        self.counters.count("decisions")
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN if self.counters.total_rejected else DiagnosticStatus.OK,
            name="activetrack/planner_node",
            hardware_id=self.scenario.name,
            message=f"decided epoch {k}",
            values=[KeyValue(key=key, value=v) for key, v in self.counters.as_pairs()],
        )
        self.diag_pub.publish(DiagnosticArray(header=header, status=[status]))


def main(args=None):
    rclpy.init(args=args)
    try:
        node = PlannerNode()
    except ValueError as exc:
        print(f"planner_node: {exc}")
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
