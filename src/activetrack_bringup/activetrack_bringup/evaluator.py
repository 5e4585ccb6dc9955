"""The run's evaluator: the only reader of ground truth; rebuilds the run record from the
graph's own outputs (the same trust filter and validation as the nodes) and keeps per-epoch
arrays sized by the scenario once, never messages, so its memory does not grow with a run.

As each epoch closes it publishes the run's figures so far (``RunMetrics``: RMSE and the PCRLB
along the flown paths, the summary's numbers) and markers of what only it knows or nobody
draws (target truth and its path, the sensors that measured, each platform's planned next
leg): what Foxglove shows live and from a bag (docs/live-view.md). Publishing reads nothing
the result depends on."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.batch import PathBound, RunRecord, component_rngs
from activetrack.closed_loop.data import PlanReportData
from activetrack.planning.manoeuvre import step_platform
from activetrack.scenarios import load_scenario
from activetrack.scenarios.build import build_motion_model
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    MAX_COORDINATE,
    MAX_SPEED,
    MAX_STATE_VALUE,
    TrackChecker,
    check_epoch_stamp,
    finite,
    header,
    marker,
    platform_from_msg,
    report_from_msg,
)
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import FRAME_ID, RUN, SCENARIO, ParamSpec
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    ManoeuvreCommand,
    Measurement,
    PlanReport,
    PlatformState,
    PolarMeasurement,
    RunMetrics,
    TrackEstimate,
)

NODE_NAMES = ("sim", "tracker", "planner")


class EpochTable:
    """One row per epoch (or, with ``slots``, per epoch and slot, e.g. platform) of a
    preallocated array, each filled once: a second value for a row is a duplicate."""

    def __init__(self, epochs: int, shape: tuple[int, ...], slots: int | None = None):
        lead = (epochs,) if slots is None else (epochs, slots)
        # Zeros, not NaN: calloc'd pages are only resident once a row is written.
        self.values = np.zeros((*lead, *shape))
        self.filled = np.zeros(lead, dtype=bool)

    def put(self, k: int, value, what: str, slot: int | None = None) -> None:
        row = k if slot is None else (k, slot)
        if self.filled[row]:
            raise Rejected("duplicate", f"second {what}")  # e.g. a replayed genuine message
        self.values[row] = value
        self.filled[row] = True

    def __contains__(self, k: int) -> bool:
        return 0 <= k < len(self.filled) and bool(np.all(self.filled[k]))

    def __len__(self) -> int:
        filled = self.filled if self.filled.ndim == 1 else self.filled.all(axis=1)
        return int(filled.sum())

    def rows(self, last: int) -> np.ndarray:
        """Epochs 0..last."""
        return self.values[: last + 1]


TRUTH_RGBA = (0.1, 0.75, 0.2, 1.0)
LEG_RGBA = (1.0, 0.55, 0.0, 1.0)
MEASURED_RGBA = (1.0, 0.85, 0.1, 0.45)


def evaluator_params(scenario_given: bool, report_grace_s: float) -> tuple[ParamSpec, ...]:
    """An evaluator's parameters (what ``ros2 param describe`` shows of it). ``scenario`` is
    required unless the runner hands the node its scenario (and names the file)."""
    return (
        replace(SCENARIO, required=not scenario_given),
        RUN,
        FRAME_ID,
        ParamSpec(
            "report_grace", float(report_grace_s),
            "seconds to wait for missing plan reports once the sim has finished",
            low=0.0, high=3600.0,
        ),
        ParamSpec(
            "summary", "",
            "standalone evaluator (activetrack_evaluator): write the run's summary.json here "
            "when it completes (empty: none; under activetrack run the runner writes it)",
        ),
        ParamSpec(
            "exit_when_done", False,
            "standalone evaluator: exit once the run is complete (changeable)", read_only=False,
        ),
    )  # fmt: skip


class ResultNode(GraphNode):
    """What every run evaluator shares: the graph's result messages checked as faults, the
    nodes' counters from /diagnostics, and when the sim said it finished.

    ``scenario``: the run's scenario, or None to load the file its ``scenario`` parameter
    names (a standalone evaluator)."""

    def __init__(self, node_name: str, scenario, *, report_grace_s: float = 1.0, **kwargs):
        super().__init__(node_name, **kwargs)
        changes = {"exit_when_done": self._set_exit_when_done}
        p = self.declare_params(evaluator_params(scenario is not None, report_grace_s), changes)
        self.scenario = scenario if scenario is not None else load_scenario(p["scenario"])
        self.run_index = None if p["run"] < 0 else p["run"]
        self.report_grace_s = p["report_grace"]
        self.summary_path = p["summary"]
        self.exit_when_done = p["exit_when_done"]
        self.diagnostics: dict[str, dict[str, int]] = {}  # latest counters per node
        self.diagnostics_order: dict[str, tuple] = {}
        self.sim_finished_at: float | None = None
        self.faults: list[str] = []  # the graph's own result messages that failed validation
        self.subscribe(DiagnosticArray, topics.DIAGNOSTICS, self.on_diagnostics)

    def _set_exit_when_done(self, value: bool) -> None:
        self.exit_when_done = value

    def _result_input(self, check, msg) -> None:
        """Run ``check(msg)``; a message of the graph's own that fails it (other than as a
        duplicate) is a fault of the graph: the runner stops the run instead of waiting."""
        try:
            check(msg)
        except Rejected as r:
            if self.graph_key is not None and r.reason != "duplicate":
                self.faults.append(f"{type(msg).__name__} epoch {msg.epoch}: {r}")
            raise

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        """Counters of the graph's nodes (only the graph's own statuses arrive with a key)."""
        for status in msg.status:
            node = status.name.rsplit("/", 1)[-1].removesuffix("_node")
            if not status.name.startswith("activetrack/") or node not in NODE_NAMES:
                self.ignore("other_diagnostics")
                continue
            counts = {kv.key: int(kv.value) for kv in status.values if kv.value.isdigit()}
            # Counters only grow: an older status (a replay, a late delivery) is not news.
            order = (msg.header.stamp.sec, msg.header.stamp.nanosec, sum(counts.values()))
            if order < self.diagnostics_order.get(node, (-1,)):
                self.ignore("stale_diagnostics")
                continue
            self.diagnostics_order[node] = order
            self.diagnostics[node] = counts
            if node == "sim" and status.message == "finished" and self.sim_finished_at is None:
                self.sim_finished_at = time.monotonic()

    # Plan reports may be missing for good (a planner that died); once the sim has finished
    # and the reports stopped coming for report_grace_s, the run is complete without them.
    # Between processes the runner gives more: a DDS participant that missed the planner's
    # first announcements only learns of it at the next periodic one (about 3 s later).

    def _reports_given_up(self) -> bool:
        t = self.sim_finished_at
        return t is not None and time.monotonic() - t > self.report_grace_s


class EvaluatorNode(ResultNode):
    """Collects truth, tracks, platform states and plan reports per epoch."""

    def __init__(self, scenario, *, report_grace_s: float = 1.0, **kwargs):
        super().__init__("activetrack_evaluator", scenario, report_grace_s=report_grace_s, **kwargs)
        scenario = self.scenario
        self.size_history(scenario)  # its metrics are per-epoch: a late viewer gets them all
        K = scenario.steps
        self.platform_index = {p.id: i for i, p in enumerate(scenario.platforms)}
        self.sensor_index = {
            s.id: i for i, s in enumerate(s for p in scenario.platforms for s in p.sensors)
        }
        self.check_track = TrackChecker(scenario)
        n = self.check_track.n
        self.truth = EpochTable(K + 1, (4,))
        self.means = EpochTable(K + 1, (n,))
        self.covs = EpochTable(K + 1, (n, n))
        self.platforms = EpochTable(K + 1, (4,), slots=len(scenario.platforms))  # pv
        self.looked = np.zeros((K + 1, len(self.sensor_index)), dtype=bool)
        self.reports: dict[int, PlanReportData] = {}
        # The live view's inputs (docs/live-view.md): per-epoch metrics and markers.
        self.kinematics = build_motion_model(scenario.tracker.motion or scenario.target.motion)
        # The summary's bound generator for one run (batch.summarize), drawn as it draws.
        self.bound = PathBound(scenario, component_rngs(scenario.seed, None)[3])
        self.announced = np.zeros(K + 1, dtype=int)  # measurements the sim announced per epoch
        self.metrics_epoch = 1  # the next epoch to publish figures of
        self.sums = np.zeros(4)  # rmse_x, rmse_y, bound_x, bound_y over epochs so far
        self.last_metrics: RunMetrics | None = None
        self.command_epoch: dict[str, int] = {}  # the latest command's epoch per platform
        self.undrawn: dict[tuple, ManoeuvreCommand] = {}  # (platform, epoch): awaits its state
        self.marker_size = _marker_size(scenario)
        self.metrics_pub = self.publisher(RunMetrics, topics.METRICS)
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        self.subscribe(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command)
        for msg_type, topic, callback in (
            (GroundTruth, topics.GROUND_TRUTH, self.on_truth),
            (TrackEstimate, topics.TRACK, self.on_track),
            (PlatformState, topics.PLATFORM_STATES, self.on_platform),
            (PlanReport, topics.PLAN_REPORT, self.on_report),
        ):
            self.subscribe(msg_type, topic, lambda m, cb=callback: self._result_input(cb, m))
        self.subscribe(BearingMeasurement, topics.BEARING_MEASUREMENTS, self.on_measurement)
        self.subscribe(PolarMeasurement, topics.POLAR_MEASUREMENTS, self.on_measurement)
        self.subscribe(Measurement, topics.MEASUREMENTS, self.on_measurement)

    @property
    def tracks(self) -> EpochTable:
        """Epochs with a track (``k in evaluator.tracks``, ``len(evaluator.tracks)``)."""
        return self.means

    # --- inputs ---------------------------------------------------------------------------

    def on_truth(self, msg: GroundTruth) -> None:
        check_epoch_stamp(msg, self.scenario, "truth")
        pv = [msg.position.x, msg.velocity.x, msg.position.y, msg.velocity.y]
        self.truth.put(msg.epoch, finite(pv, "truth", MAX_STATE_VALUE), f"truth of {msg.epoch}")
        self._close_epochs()

    def on_track(self, msg: TrackEstimate) -> None:
        t = self.check_track(msg)
        if t.epoch in self.means:
            raise Rejected("duplicate", f"second track of epoch {t.epoch}")
        self.means.put(t.epoch, t.mean, "track")
        self.covs.put(t.epoch, t.cov, "track")
        self._close_epochs()

    def on_platform(self, msg: PlatformState) -> None:
        s = platform_from_msg(msg, self.scenario, self.platform_index)
        what = f"state of {s.platform_id!r} at {s.epoch}"
        self.platforms.put(s.epoch, s.pv, what, slot=self.platform_index[s.platform_id])
        self.announced[s.epoch] = max(self.announced[s.epoch], msg.epoch_measurement_count)
        self._close_epochs()
        if (s.platform_id, s.epoch) in self.undrawn:
            self._draw_leg(self.undrawn.pop((s.platform_id, s.epoch)))

    def on_report(self, msg: PlanReport) -> None:
        report = report_from_msg(msg, self.scenario)
        if report.epoch in self.reports:
            raise Rejected("duplicate", f"second plan report of epoch {report.epoch}")
        self.reports[report.epoch] = report

    def on_measurement(self, msg) -> None:
        i = self.sensor_index.get(msg.sensor_id)
        if i is None or not 1 <= msg.epoch <= self.scenario.steps:
            raise Rejected("bad_field", f"measurement of {msg.sensor_id!r} at {msg.epoch}")
        self.looked[msg.epoch, i] = True
        self._close_epochs()

    def on_command(self, msg: ManoeuvreCommand) -> None:
        """A platform's planned next leg, drawn from its state at the command's epoch (now, or
        when that state arrives)."""
        what = f"command for {msg.platform_id!r}"
        if msg.platform_id not in self.platform_index or not 0 <= msg.epoch <= self.scenario.steps:
            raise Rejected("bad_field", f"{what} at {msg.epoch}")
        finite((msg.commanded_heading,), f"{what} heading", 4 * math.pi)
        finite((msg.commanded_speed,), f"{what} speed", MAX_SPEED)
        finite((msg.waypoint.x, msg.waypoint.y), f"{what} waypoint", MAX_COORDINATE)
        if self.command_epoch.get(msg.platform_id, -1) >= msg.epoch:
            return self.ignore("stale_command")  # a replay or a late delivery: not news
        self.command_epoch[msg.platform_id] = msg.epoch
        self._draw_leg(msg)

    # --- what the live view shows (docs/live-view.md) --------------------------------------

    def _epoch_closed(self, k: int) -> bool:
        """Truth, track and every platform state of epoch k are in, and every measurement the
        sim announced for it (or the tracker has moved on past it)."""
        if k not in self.truth or k - 1 not in self.truth:  # k - 1: the path's last leg
            return False
        if k not in self.means or k not in self.platforms:
            return False
        return int(self.looked[k].sum()) >= self.announced[k] or k + 1 in self.means

    def _close_epochs(self) -> None:
        """Publish the figures and markers of each newly closed epoch, in order (the bound's
        recursion runs epoch by epoch)."""
        while self.metrics_epoch <= self.scenario.steps and self._epoch_closed(self.metrics_epoch):
            k = self.metrics_epoch
            self.metrics_epoch += 1
            hdr = header(k * self.scenario.dt, self.frame_id)
            self.last_metrics = self._metrics(k, hdr)
            self.metrics_pub.publish(self.last_metrics)
            self.marker_pub.publish(self._epoch_markers(k, hdr))

    def _metrics(self, k: int, hdr) -> RunMetrics:
        truth = self.truth.values[k]
        est = self.kinematics.kinematics(self.means.values[k])
        rmse = np.sqrt((est - truth) ** 2)[[0, 2]]  # summarize's RMSE of one run
        try:
            B = self.bound.step(self.platforms.values[k], self.looked[k])
            bound = (math.sqrt(B[0, 0]), math.sqrt(B[2, 2]))  # std bound in x and y
        except (ValueError, np.linalg.LinAlgError) as exc:  # e.g. an information not finite
            self.counters.count("bound_unavailable")
            self.log_limited("warning", "bound", f"no PCRLB at epoch {k}: {exc}")
            bound = (math.nan, math.nan)
        self.sums += (*rmse, *bound)
        means = self.sums / k
        return RunMetrics(
            header=hdr,
            epoch=k,
            steps=self.scenario.steps,
            truth_position=Point(x=float(truth[0]), y=float(truth[2])),
            estimate_position=Point(x=float(est[0]), y=float(est[2])),
            rmse_x=float(rmse[0]),
            rmse_y=float(rmse[1]),
            position_error=math.hypot(*rmse),
            bound_x=bound[0],
            bound_y=bound[1],
            position_bound=math.hypot(*bound),
            mean_rmse_x=float(means[0]),
            mean_rmse_y=float(means[1]),
            mean_bound_x=float(means[2]),
            mean_bound_y=float(means[3]),
            measured_sensor_ids=[s for s, i in self.sensor_index.items() if self.looked[k, i]],
        )

    def _epoch_markers(self, k: int, hdr) -> MarkerArray:
        """The target's true position and path, and a disc under each platform whose sensors
        measured at epoch k (the sensor selection's effect; removed when none did)."""
        size = self.marker_size
        now, before = self.truth.values[k][[0, 2]], self.truth.values[k - 1][[0, 2]]
        truth = marker(hdr, "truth", 0, Marker.SPHERE, TRUTH_RGBA)
        truth.pose.position = Point(x=float(now[0]), y=float(now[1]))
        truth.scale.x = truth.scale.y = truth.scale.z = 2.0 * size
        path = marker(hdr, "truth_path", k, Marker.LINE_STRIP, TRUTH_RGBA, (before, now))
        path.scale.x = 0.5 * size  # line width
        markers = [truth, path]
        for j, p in enumerate(self.scenario.platforms):
            disc = marker(hdr, "measured", j, Marker.CYLINDER, MEASURED_RGBA)
            if not any(self.looked[k, self.sensor_index[s.id]] for s in p.sensors):
                disc.action = Marker.DELETE
            pv = self.platforms.values[k, j]
            disc.pose.position = Point(x=float(pv[0]), y=float(pv[2]))
            disc.scale.x = disc.scale.y = 6.0 * size
            disc.scale.z = 0.1 * size
            markers.append(disc)
        return MarkerArray(markers=markers)

    def _draw_leg(self, msg: ManoeuvreCommand) -> None:
        """The leg a command plans: from the platform's position at the command's epoch, at
        the commanded heading and speed for one epoch (and its waypoint, if it has one)."""
        j = self.platform_index[msg.platform_id]
        if not self.platforms.filled[msg.epoch, j]:
            self.undrawn[msg.platform_id, msg.epoch] = msg  # drawn when that state arrives
            return
        pv = self.platforms.values[msg.epoch, j]
        end, _ = step_platform(
            pv, msg.commanded_heading, (0.0, msg.commanded_speed), self.scenario.dt
        )
        hdr = header(msg.epoch * self.scenario.dt, self.frame_id)
        size = self.marker_size
        leg = marker(hdr, "next_leg", j, Marker.ARROW, LEG_RGBA, (pv[[0, 2]], end[[0, 2]]))
        leg.scale.x, leg.scale.y, leg.scale.z = 0.5 * size, 1.5 * size, 2.0 * size
        markers = [leg]
        if msg.has_waypoint:
            wp = marker(hdr, "waypoint", j, Marker.SPHERE, LEG_RGBA)
            wp.pose.position = Point(x=msg.waypoint.x, y=msg.waypoint.y)
            wp.scale.x = wp.scale.y = wp.scale.z = 1.5 * size
            markers.append(wp)
        self.marker_pub.publish(MarkerArray(markers=markers))

    # --- completion ---------------------------------------------------------------------------

    @property
    def expects_reports(self) -> bool:
        """The planner reports a decision per epoch when it commands any platform."""
        return self.scenario.planner.enabled and any(
            p.controllable for p in self.scenario.platforms
        )

    @property
    def complete(self) -> bool:
        K = self.scenario.steps
        if len(self.means) <= K or len(self.truth) <= K:  # cheap test first: called often
            return False
        return not self.missing()

    def missing(self) -> str:
        """What the evaluator still lacks (for a timeout message)."""
        K = self.scenario.steps
        lacks = {
            "truth": [k for k in range(K + 1) if k not in self.truth],
            "track": [k for k in range(K + 1) if k not in self.means],
            "platforms": [k for k in range(K + 1) if k not in self.platforms],
            "plan report": [k for k in range(K) if k not in self.reports]
            if self.expects_reports and not self._reports_given_up()
            else [],
        }
        return lacks_text(lacks)

    def completed_epochs(self) -> int:
        """The last epoch K' such that truth, track and platform states of 0..K' are all here."""
        k = -1
        while k + 1 in self.truth and k + 1 in self.means and k + 1 in self.platforms:
            k += 1
        return k

    def record(self, wall_time_s: float, last_epoch: int | None = None) -> RunRecord:
        K = self.scenario.steps if last_epoch is None else last_epoch
        reports = [self.reports[k] for k in sorted(self.reports) if k < max(K, 1)]
        return RunRecord(
            truth=self.truth.rows(K).copy(),
            estimate=self.means.rows(K).copy(),
            estimate_cov=self.covs.rows(K).copy(),
            platform_paths=self.platforms.rows(K).copy(),
            platform_ids=tuple(self.platform_index),
            decisions=reports,
            measured=self.looked[1 : K + 1].copy(),
            wall_time_s=wall_time_s,
            planning_time_s=sum(r.wall_time_s for r in reports),
            evaluations=sum(r.evaluations for r in reports),
        )


def _marker_size(scenario) -> float:
    """A marker size for the scenario's scale: 1 % of the distance from the target's prior
    mean to the farthest platform (Hernandez: ~20 m; Valverde: ~0.5 m), at least 0.1 m."""
    model = build_motion_model(scenario.target.motion)
    mean = model.kinematics(np.array(scenario.target.prior.mean))  # pv, whatever the state
    far = max(
        math.hypot(p.initial_state[0] - mean[0], p.initial_state[2] - mean[2])
        for p in scenario.platforms
    )
    return max(0.01 * far, 0.1)


def lacks_text(lacks: dict[str, list[int]]) -> str:
    """'truth missing at epochs 3-5, track missing at epochs 7' (what -> epochs lacking)."""
    return ", ".join(f"{what} missing at epochs {_ranges(ks)}" for what, ks in lacks.items() if ks)


def _ranges(ks: list[int]) -> str:
    """[1, 2, 3, 7] -> '1-3, 7' (a missing-epochs list can be long)."""
    out, start = [], None
    for i, k in enumerate(ks):
        if start is None:
            start = k
        if i + 1 == len(ks) or ks[i + 1] != k + 1:
            out.append(str(start) if start == k else f"{start}-{k}")
            start = None
    return ", ".join(out)
