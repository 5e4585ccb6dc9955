"""The run's evaluator, the only reader of ground truth: it rebuilds the run's
:class:`~activetrack.closed_loop.record.RunRecord` from the graph's own outputs, each checked as
the nodes check them, so that the runner scores it with the batch loop's code
(:func:`~activetrack.closed_loop.evaluation.evaluate_run`): in lockstep, `activetrack run` equals
`activetrack batch` bit for bit. What the sim does not publish is rebuilt from what it does:
which sensors scanned (the scans), and which had which alive target in view (each scan's field
of view and the truth, with the simulator's own test); the detections' labels stay in the sim.

As each epoch closes it publishes the figures so far (``RunMetrics``) and the markers only it
knows (truth, sensors that scanned, planned legs) for the live view (docs/live-view.md);
publishing reads nothing the result depends on."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.components import component_rngs, scene_sensors, scene_targets
from activetrack.closed_loop.evaluation import (
    EpochAssessor,
    TargetBound,
    bound_counts,
    bound_sensors,
)
from activetrack.closed_loop.record import RunRecord
from activetrack.data import (
    BeamCommand,
    Command,
    Decision,
    PlanReportData,
    Scan,
    TrackSet,
    heading_speed,
)
from activetrack.planning.manoeuvre import step_platform
from activetrack.scenarios import load_scenario
from activetrack.scenarios.build import build_motion_model
from activetrack_bringup.refetch import TICK_S, Refetcher
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    MAX_COORDINATE,
    MAX_SPEED,
    TrackArrayChecker,
    beam_from_msg,
    check_epoch_stamp,
    finite,
    header,
    marker,
    platform_from_msg,
    report_from_msg,
    scan_from_msg,
    selection_from_msg,
    truth_array_from_msg,
)
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import FRAME_ID, RUN, SCENARIO, ParamSpec
from msgs_defs.msg import BeamCommand as BeamCommandMsg
from msgs_defs.msg import (
    GroundTruthArray,
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    RunMetrics,
    SensorSelection,
    TrackArray,
)
from msgs_defs.msg import Scan as ScanMsg

NODE_NAMES = ("sim", "tracker", "planner")
# The answers that make an epoch's decision (a plan report is its account, not part of it).
DECISION_TOPICS = (topics.MANOEUVRE_COMMANDS, topics.BEAM_COMMANDS, topics.SENSOR_SELECTION)
# Seconds after the sim and the tracker finished that a missing message the result needs may
# still come (late at its writer) before the run ends without it: the graph itself waits as
# long (the tracker's default epoch_timeout) for a late scan or state.
LOST_GRACE_S = 5.0
# What the evaluator needs of every epoch to score it (the others: the decisions, given up).
DATA_TOPICS = (topics.GROUND_TRUTH, topics.PLATFORM_STATES, topics.SCANS, topics.TRACKS)
SIM_TOPICS = (topics.GROUND_TRUTH, topics.PLATFORM_STATES, topics.SCANS)
TRUTH_RGBA = (0.1, 0.75, 0.2, 1.0)
LEG_RGBA = (1.0, 0.55, 0.0, 1.0)
MEASURED_RGBA = (1.0, 0.85, 0.1, 0.45)


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


def evaluator_params(
    scenario_given: bool, report_grace_s: float, lost_grace_s: float = LOST_GRACE_S
) -> tuple[ParamSpec, ...]:
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
            "lost_grace", float(lost_grace_s),
            "seconds to wait, once the sim and the tracker have finished, for a missing truth "
            "array, platform state, scan or track array (late at its writer) before giving it "
            "up: the run ends messages_lost",
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


class EvaluatorNode(GraphNode):
    """Collects a run per epoch (module docstring); ``record()`` gives it. ``scenario``: the
    run's, or None to load the file of its ``scenario`` parameter (a standalone evaluator)."""

    def __init__(
        self, scenario, *, report_grace_s: float = 1.0, lost_grace_s: float = LOST_GRACE_S, **kw
    ):
        super().__init__("activetrack_evaluator", **kw)
        changes = {"exit_when_done": self._set_exit_when_done}
        specs = evaluator_params(scenario is not None, report_grace_s, lost_grace_s)
        p = self.declare_params(specs, changes)
        if scenario is None:
            scenario = load_scenario(p["scenario"])
        self.scenario = scenario
        self.run_index = None if p["run"] < 0 else p["run"]
        self.report_grace_s = p["report_grace"]
        self.lost_grace_s = p["lost_grace"]
        self.summary_path = p["summary"]
        self.exit_when_done = p["exit_when_done"]
        self.diagnostics: dict[str, dict[str, int]] = {}  # latest counters per node
        self.diagnostics_order: dict[str, tuple] = {}
        self.sim_finished_at: float | None = None  # its "finished" status, or epoch K came
        self.tracker_done_at: float | None = None  # its track array of K came, or was counted
        self.gave_up: str | None = None  # what was still missing when it gave up (lost)
        self.faults: list[str] = []  # the graph's own result messages that failed validation
        self.size_history(scenario)  # its metrics are per-epoch: a late viewer gets them all
        K = scenario.steps
        targets = scene_targets(scenario)
        self.target_ids = tuple(t.id for t in targets)
        self.target_index = {tid: i for i, tid in enumerate(self.target_ids)}
        self.platform_index = {p.id: i for i, p in enumerate(scenario.platforms)}
        self.sensors = scene_sensors(scenario)
        self.sensor_index = {sid: i for i, sid in enumerate(self.sensors)}
        self.steerable = tuple(sid for sid, (_, s) in self.sensors.items() if s.steerable)
        self.controllable = tuple(p.id for p in scenario.platforms if p.controllable)
        self.selects = scenario.planner.enabled and scenario.planner.selection.enabled
        self.check_tracks = TrackArrayChecker(scenario)
        self.truth = EpochTable(K + 1, (len(self.target_ids), 4))
        self.platforms = EpochTable(K + 1, (4,), slots=len(scenario.platforms))
        self.tracks: dict[int, TrackSet] = {}
        self.scans: dict[int, dict[str, Scan]] = {}
        self.announced = np.zeros(K + 1, dtype=int)  # scans the sim announced per epoch
        self.commands: dict[int, dict[str, Command]] = {}
        self.beams: dict[int, dict[str, BeamCommand]] = {}
        self.selections: dict[int, tuple[str, ...]] = {}
        self.reports: dict[int, PlanReportData] = {}
        # The live view's figures: the summary's bound, its generator drawn as evaluate_run's.
        self.assess = EpochAssessor(scenario)
        rng = component_rngs(scenario.seed, None)[3]
        self.bound_sensors, self.bound_columns = bound_sensors(scenario)
        self.bounds = [TargetBound(t, self.bound_sensors, scenario.dt, rng) for t in targets]
        self.metrics_epoch = 1  # the next epoch to publish figures of
        self.sums = np.zeros((4, len(targets)))  # error x, y (where held), bound x, y
        self.held_epochs = np.zeros(len(targets))
        self.bound_epochs = np.zeros(len(targets))
        self.gospa_sum = 0.0
        self.command_epoch: dict[str, int] = {}  # the latest command's epoch per platform
        self.undrawn: dict[tuple, ManoeuvreCommand] = {}  # (platform, epoch): awaits its state
        self.marker_size = _marker_size(scenario)
        self.metrics_pub = self.publisher(RunMetrics, topics.METRICS)
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        self.subscribe(DiagnosticArray, topics.DIAGNOSTICS, self.on_diagnostics)
        inputs = {}
        for msg_type, topic, callback in (
            (GroundTruthArray, topics.GROUND_TRUTH, self.on_truth),
            (TrackArray, topics.TRACKS, self.on_tracks),
            (PlatformState, topics.PLATFORM_STATES, self.on_platform),
            (ScanMsg, topics.SCANS, self.on_scan),
            (ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command),
            (BeamCommandMsg, topics.BEAM_COMMANDS, self.on_beam),
            (SensorSelection, topics.SENSOR_SELECTION, self.on_selection),
            (PlanReport, topics.PLAN_REPORT, self.on_report),
        ):
            check = lambda m, cb=callback, t=topic: self._result_input(cb, m, t)  # noqa: E731
            self.subscribe(msg_type, topic, lambda m, c=check, t=topic: self._own_input(c, m, t))
            inputs[topic] = (msg_type, check)
        # A message lost to a reader here is fetched again from its writer's history
        # (refetch.py); the last epoch of each topic: K, or K - 1 for the decisions.
        last = {t: K if t in DATA_TOPICS else K - 1 for t in inputs}
        self.refetcher = Refetcher(self, inputs, self._has, last)
        self.guarded_timer(TICK_S, self._on_tick)

    def _set_exit_when_done(self, value: bool) -> None:
        self.exit_when_done = value

    def _result_input(self, check, msg, topic: str | None = None) -> None:
        """Run ``check(msg)``; a message of the graph's own that fails it (other than as a
        duplicate) is a fault of the graph: the runner stops the run instead of waiting.
        ``topic``: its topic (the last epoch of the sim's or the tracker's says it finished)."""
        try:
            check(msg)
        except Rejected as r:
            if self.graph_key is not None and r.reason != "duplicate":
                self.faults.append(f"{type(msg).__name__} epoch {msg.epoch}: {r}")
            raise
        K = self.scenario.steps
        if msg.epoch == K and self.sim_finished_at is None and topic in SIM_TOPICS:
            self.sim_finished_at = time.monotonic()  # its last epoch: nothing more will come
        if msg.epoch == K and self.tracker_done_at is None and topic == topics.TRACKS:
            self.tracker_done_at = time.monotonic()

    def _own_input(self, check, msg, topic: str) -> None:
        """A message on the evaluator's own reader: its epoch is the topic's news (a gap
        below it is lost to this reader: refetch.py); a copy of one a fresh reader fetched
        first is ignored, not a duplicate."""
        self.refetcher.saw(topic, msg.epoch)
        try:
            check(msg)
        except Rejected as r:
            if r.reason != "duplicate" or not self.refetcher.filled_before(topic, msg.epoch):
                raise
            self.ignore("refetched_before")

    def _has(self, topic: str, k: int) -> bool:
        """Epoch k's messages of ``topic`` are all here."""
        if topic == topics.GROUND_TRUTH:
            return k in self.truth
        if topic == topics.PLATFORM_STATES:
            return k in self.platforms
        if topic == topics.TRACKS:
            return k in self.tracks
        if topic == topics.SCANS:
            return k == 0 or self._scans_in(k)
        if topic == topics.MANOEUVRE_COMMANDS:
            return all(p in self.commands.get(k, {}) for p in self.controllable)
        if topic == topics.BEAM_COMMANDS:
            return all(s in self.beams.get(k, {}) for s in self.steerable)
        if topic == topics.SENSOR_SELECTION:
            return not self.selects or k in self.selections
        return not self.expects_reports or k in self.reports  # PLAN_REPORT

    def _on_tick(self) -> None:
        """Fetch lost messages again (refetch.py). report_grace after the sim finished, a
        sweep of everything missing (then the decisions still missing are given up);
        lost_grace after the tracker finished too, another, then give up what is still
        missing (never sent: the run ends, not complete)."""
        now = time.monotonic()
        updates = self.diagnostics.get("tracker", {}).get("updates", 0)
        if self.tracker_done_at is None and updates >= self.scenario.steps:
            self.tracker_done_at = now  # its track array of K: lost, or coming
        sim, tracker = self.sim_finished_at, self.tracker_done_at
        sweeps = 0
        if sim is not None and now - sim > self.report_grace_s:
            sweeps = 1 + (tracker is not None and now - max(sim, tracker) > self.lost_grace_s)
        self.refetcher.tick(sweeps)
        lost = self.refetcher.passes == 2 and not self.refetcher.busy()
        if self.gave_up is None and lost and not self.complete:
            self.gave_up = self.missing()
            self.log_limited("warning", "gave_up", f"gave up: {self.gave_up}")

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        """Counters of the graph's nodes (only the graph's own statuses arrive with a key). A
        message none of whose statuses is news is ignored once (each message ends in one
        counter): ``other_diagnostics`` if none is a graph node's, else ``stale_diagnostics``."""
        ours = news = 0
        for status in msg.status:
            node = status.name.rsplit("/", 1)[-1].removesuffix("_node")
            if not status.name.startswith("activetrack/") or node not in NODE_NAMES:
                continue
            ours += 1
            counts = {kv.key: int(kv.value) for kv in status.values if kv.value.isdigit()}
            # Counters only grow: an older status (a replay, a late delivery) is not news.
            order = (msg.header.stamp.sec, msg.header.stamp.nanosec, sum(counts.values()))
            if order < self.diagnostics_order.get(node, (-1,)):
                continue
            news += 1
            self.diagnostics_order[node] = order
            self.diagnostics[node] = counts
            if node == "sim" and status.message == "finished" and self.sim_finished_at is None:
                self.sim_finished_at = time.monotonic()
        if not news:
            self.ignore("stale_diagnostics" if ours else "other_diagnostics")

    def on_truth(self, msg: GroundTruthArray) -> None:
        truth = truth_array_from_msg(msg, self.scenario)
        pv = truth_rows(truth, self.target_index)
        self.truth.put(truth.epoch, pv, f"truth array of {truth.epoch}")
        self._close_epochs()

    def on_tracks(self, msg: TrackArray) -> None:
        tracks = self.check_tracks(msg)
        # Without the planner's posterior samples: a run keeps results, not messages (a PF
        # track's samples are kB an epoch; the record and the figures never read them).
        what = f"track array of epoch {tracks.epoch}"
        _put_once(self.tracks, tracks.epoch, tracks.without_samples(), what)
        self._close_epochs()

    def on_platform(self, msg: PlatformState) -> None:
        s = platform_from_msg(msg, self.scenario, self.platform_index)
        what = f"state of {s.platform_id!r} at {s.epoch}"
        self.platforms.put(s.epoch, s.pv, what, slot=self.platform_index[s.platform_id])
        self.announced[s.epoch] = max(self.announced[s.epoch], msg.epoch_scan_count)
        self._close_epochs()
        if (s.platform_id, s.epoch) in self.undrawn:
            self._draw_leg(self.undrawn.pop((s.platform_id, s.epoch)))

    def on_scan(self, msg: ScanMsg) -> None:
        scan = scan_from_msg(msg, self.scenario, self.sensors)
        what = f"scan of {scan.sensor_id!r} at {scan.epoch}"
        _put_once(self.scans.setdefault(scan.epoch, {}), scan.sensor_id, scan, what)
        self._close_epochs()

    def on_command(self, msg: ManoeuvreCommand) -> None:
        what = f"command for {msg.platform_id!r}"
        if msg.platform_id not in self.controllable or msg.epoch >= self.scenario.steps:
            raise Rejected("bad_field", f"{what} at {msg.epoch}")
        check_epoch_stamp(msg, self.scenario, what)
        finite((msg.heading_change,), f"{what} heading_change", math.pi + 1e-9)
        finite((msg.speed_change,), f"{what} speed_change", MAX_SPEED)
        # NaN: not given (a command to hold course, Command's default); else a real value.
        if not math.isnan(msg.commanded_heading):
            finite((msg.commanded_heading,), f"{what} heading", 4 * math.pi)
        if not math.isnan(msg.commanded_speed):
            finite((msg.commanded_speed,), f"{what} speed", MAX_SPEED)
        finite((msg.waypoint.x, msg.waypoint.y), f"{what} waypoint", MAX_COORDINATE)
        command = Command(
            msg.platform_id,
            msg.epoch,
            msg.heading_change,
            msg.speed_change,
            msg.commanded_heading,
            msg.commanded_speed,
            msg.take_measurement if msg.gate_measurement else None,
            (msg.waypoint.x, msg.waypoint.y) if msg.has_waypoint else None,
        )
        commands = self.commands.setdefault(msg.epoch, {})
        _put_once(commands, msg.platform_id, command, f"{what} at {msg.epoch}")
        if self.command_epoch.get(msg.platform_id, -1) < msg.epoch:
            self.command_epoch[msg.platform_id] = msg.epoch
            self._draw_leg(msg)

    def on_beam(self, msg: BeamCommandMsg) -> None:
        beam = beam_from_msg(msg, self.scenario)
        what = f"beam of {beam.sensor_id!r} at {beam.epoch}"
        _put_once(self.beams.setdefault(beam.epoch, {}), beam.sensor_id, beam, what)

    def on_selection(self, msg: SensorSelection) -> None:
        ids = selection_from_msg(msg, self.scenario, self.sensors)
        if msg.epoch >= self.scenario.steps or msg.epoch in self.selections:
            raise Rejected("duplicate", f"second selection of epoch {msg.epoch}")
        self.selections[msg.epoch] = ids

    def on_report(self, msg: PlanReport) -> None:
        report = report_from_msg(msg, self.scenario)
        _put_once(self.reports, report.epoch, report, f"plan report of epoch {report.epoch}")

    # --- what the live view shows (docs/live-view.md) --------------------------------------

    def _scans_in(self, k: int) -> bool:
        return len(self.scans.get(k, {})) >= self.announced[k]

    def _epoch_closed(self, k: int) -> bool:
        """Truth (of k and k - 1: the path's last leg), tracks, every platform state and every
        scan the sim announced of epoch k are in (or the tracker has moved on past it)."""
        ready = k in self.truth and k - 1 in self.truth and k in self.tracks and k in self.platforms
        return ready and (self._scans_in(k) or k + 1 in self.tracks)

    def _close_epochs(self) -> None:
        """Publish the figures and markers of each newly closed epoch, in order (the bound's
        recursion runs epoch by epoch)."""
        while self.metrics_epoch <= self.scenario.steps and self._epoch_closed(self.metrics_epoch):
            k = self.metrics_epoch
            self.metrics_epoch += 1
            hdr = header(k * self.scenario.dt, self.frame_id)
            self.metrics_pub.publish(self._metrics(k, hdr))
            self.marker_pub.publish(self._epoch_markers(k, hdr))

    def _looked(self, k: int) -> np.ndarray:
        looked = np.zeros(len(self.sensors), dtype=bool)
        for sid in self.scans.get(k, {}):
            looked[self.sensor_index[sid]] = True
        return looked

    def _metrics(self, k: int, hdr) -> RunMetrics:
        truth = self.truth.values[k]
        tracks = self.tracks[k]
        a = self.assess(truth, tracks, k)
        est = held_estimates(a, tracks, truth)
        error = np.abs(est - truth)[:, [0, 2]]  # the summary's RMSE of one run
        looked = self._looked(k)
        counts = bound_counts(self.bound_sensors, looked, self._observed_at(k))
        paths = self.platforms.values[k][self.bound_columns]
        bound = np.full((len(self.target_ids), 2), math.nan)
        for n, b in enumerate(self.bounds):
            try:
                B = b.step(paths, counts[:, n])
                bound[n] = math.sqrt(B[0, 0]), math.sqrt(B[2, 2])
            except (ValueError, np.linalg.LinAlgError) as exc:  # e.g. an information not finite
                self.counters.count("bound_unavailable")
                self.log_limited("warning", "bound", f"no PCRLB at epoch {k}: {exc}")
        held = ~np.isnan(error[:, 0])
        self.held_epochs += held
        self.sums[:2] += np.where(held[None], error.T, 0.0)
        has_bound = ~np.isnan(bound[:, 0])
        self.bound_epochs += has_bound
        self.sums[2:] += np.where(has_bound[None], bound.T, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            avg_error = self.sums[:2] / self.held_epochs
            avg_bound = self.sums[2:] / self.bound_epochs
        self.gospa_sum += a.gospa
        return RunMetrics(
            header=hdr,
            epoch=k,
            steps=self.scenario.steps,
            target_ids=list(self.target_ids),
            truth_positions=[Point(x=float(x), y=float(y)) for x, y in truth[:, [0, 2]]],
            estimate_positions=[Point(x=float(x), y=float(y)) for x, y in est[:, [0, 2]]],
            error_x=error[:, 0].tolist(),
            error_y=error[:, 1].tolist(),
            position_error=np.hypot(error[:, 0], error[:, 1]).tolist(),
            bound_x=bound[:, 0].tolist(),
            bound_y=bound[:, 1].tolist(),
            position_bound=np.hypot(bound[:, 0], bound[:, 1]).tolist(),
            time_avg_rmse_x=avg_error[0].tolist(),
            time_avg_rmse_y=avg_error[1].tolist(),
            time_avg_bound_x=avg_bound[0].tolist(),
            time_avg_bound_y=avg_bound[1].tolist(),
            gospa=float(a.gospa),
            localisation=float(a.localisation),
            missed_targets=int(a.missed),
            false_tracks=int(a.false),
            mean_gospa=self.gospa_sum / k,
            measured_sensor_ids=[s for s, i in self.sensor_index.items() if looked[i]],
        )

    def _epoch_markers(self, k: int, hdr) -> MarkerArray:
        """Each alive target's true position and path (removed when it is gone), and a disc
        under each platform whose sensors scanned at epoch k (the sensor selection's effect;
        removed when none did)."""
        size = self.marker_size
        markers = []
        for n in range(len(self.target_ids)):
            now, before = self.truth.values[k, n][[0, 2]], self.truth.values[k - 1, n][[0, 2]]
            truth = marker(hdr, "truth", n, Marker.SPHERE, TRUTH_RGBA)
            if np.isnan(now[0]):
                truth.action = Marker.DELETE
            else:
                truth.pose.position = Point(x=float(now[0]), y=float(now[1]))
                truth.scale.x = truth.scale.y = truth.scale.z = 2.0 * size
            markers.append(truth)
            if not (np.isnan(now[0]) or np.isnan(before[0])):
                path = marker(
                    hdr, f"truth_path/{self.target_ids[n]}", k, Marker.LINE_STRIP, TRUTH_RGBA,
                    (before, now),
                )  # fmt: skip
                path.scale.x = 0.5 * size  # line width
                markers.append(path)
        looked = self._looked(k)
        for j, p in enumerate(self.scenario.platforms):
            disc = marker(hdr, "measured", j, Marker.CYLINDER, MEASURED_RGBA)
            if not any(looked[self.sensor_index[s.id]] for s in p.sensors):
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
        heading, speed = msg.commanded_heading, msg.commanded_speed
        if math.isnan(heading) or math.isnan(speed):  # not given: the changes say where
            now_heading, now_speed = heading_speed(pv)
            heading = now_heading + msg.heading_change if math.isnan(heading) else heading
            speed = now_speed + msg.speed_change if math.isnan(speed) else speed
        end, _ = step_platform(pv, heading, (0.0, speed), self.scenario.dt)
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

    # Plan reports (and commands, beams, selections) may be missing for good (a planner that
    # died); once the sim has finished, report_grace_s has passed and a last fetch from the
    # writers' histories ended, the run is complete without them. Between
    # processes the runner gives more: a DDS participant that missed the planner's first
    # announcements only learns of it at the next periodic one.

    def _reports_given_up(self) -> bool:
        return self.refetcher.passes >= 1 and not self.refetcher.busy()

    @property
    def expects_reports(self) -> bool:
        """The planner reports a decision per epoch when it commands a platform or a beam, or
        selects sensors."""
        return self.scenario.planner.enabled and bool(
            self.controllable or self.steerable or self.selects
        )

    def _decided(self, k: int) -> bool:
        return all(self._has(t, k) for t in DECISION_TOPICS)

    @property
    def complete(self) -> bool:
        K = self.scenario.steps
        if len(self.tracks) <= K or len(self.truth) <= K:  # cheap test first: called often
            return False
        return not self.missing()

    def missing(self) -> str:
        """What the evaluator still lacks (for a timeout message)."""
        K = self.scenario.steps
        given_up = self._reports_given_up()
        lacks = {
            "truth": [k for k in range(K + 1) if k not in self.truth],
            "track array": [k for k in range(K + 1) if k not in self.tracks],
            "platforms": [k for k in range(K + 1) if k not in self.platforms],
            "scans": [k for k in range(1, K + 1) if k in self.platforms and not self._scans_in(k)],
            "commands, beams or selection": []
            if given_up
            else [k for k in range(K) if not self._decided(k)],
            "plan report": []
            if given_up or not self.expects_reports
            else [k for k in range(K) if k not in self.reports],
        }
        return ", ".join(
            f"{what} missing at epochs {_ranges(ks)}" for what, ks in lacks.items() if ks
        )

    def completed_epochs(self) -> int:
        """The last epoch K' such that truth, tracks, platform states and scans of 0..K' are
        all here (once the evaluator gave up: scans lost for good do not end it, the record
        holds the scans that came, as the tracker did)."""
        k = -1
        while (
            k + 1 in self.truth
            and k + 1 in self.tracks
            and k + 1 in self.platforms
            and (k + 1 == 0 or self._scans_in(k + 1) or self.gave_up is not None)
        ):
            k += 1
        return k

    def record(self, wall_time_s: float, last_epoch: int | None = None) -> RunRecord:
        """The run's record over epochs 0..last_epoch (default: all)."""
        K = self.scenario.steps if last_epoch is None else last_epoch
        truth = self.truth.rows(K).copy()
        order = self.sensor_index
        scans = [
            sorted(self.scans.get(k, {}).values(), key=lambda s: order[s.sensor_id])
            for k in range(1, K + 1)
        ]
        decisions = [self._decision(k) for k in range(K)]
        looked = np.array([self._looked(k) for k in range(1, K + 1)], dtype=bool)
        detected = np.zeros_like(looked)
        for k, epoch_scans in enumerate(scans):
            for scan in epoch_scans:
                detected[k, order[scan.sensor_id]] = len(scan.Z) > 0
        reports = [d.report for d in decisions if d.report is not None]
        return RunRecord(
            target_ids=self.target_ids,
            sensor_ids=tuple(self.sensors),
            platform_ids=tuple(self.platform_index),
            truth=truth,
            tracks=[self.tracks[k] for k in range(K + 1)],
            platform_paths=self.platforms.rows(K).copy(),
            scans=scans,
            looked=looked.reshape(K, len(self.sensors)),
            detected=detected.reshape(K, len(self.sensors)),
            observed=np.array([self._observed_at(k) for k in range(1, K + 1)], dtype=bool).reshape(
                K, len(self.sensors), len(self.target_ids)
            ),
            decisions=decisions,
            clamps=int(self.diagnostics.get("sim", {}).get("commands_clamped", 0)),
            wall_time_s=wall_time_s,
            planning_time_s=sum(r.wall_time_s for r in reports),
            evaluations=sum(r.evaluations for r in reports),
        )

    def _decision(self, k: int) -> Decision:
        commands = self.commands.get(k, {})
        beams = self.beams.get(k, {})
        return Decision(
            k,
            commands=tuple(commands[p] for p in self.controllable if p in commands),
            beams=tuple(beams[s] for s in self.steerable if s in beams),
            selected_sensor_ids=self.selections.get(k),
            report=self.reports.get(k),
        )

    def _observed_at(self, k: int) -> np.ndarray:
        """``(S, N)``: the scan of sensor s at epoch k had alive target n in its field of view
        and range (the simulator's test, on the scan's own field of view and sensor position)."""
        truth = self.truth.values[k]
        out = np.zeros((len(self.sensors), len(self.target_ids)), dtype=bool)
        alive = ~np.isnan(truth[:, 0])
        for scan in self.scans.get(k, {}).values():
            sensor = self.sensors[scan.sensor_id][1]
            x, pv = truth[alive], np.asarray(scan.sensor_pv)
            seen = alive.copy()
            seen[alive] = scan.fov.contains(x, pv) & sensor.in_range(x, pv)
            out[self.sensor_index[scan.sensor_id]] = seen
        return out


def _put_once(table: dict, key, value, what: str) -> None:
    """``table[key] = value``; a second value for ``key`` is a duplicate (e.g. a replay)."""
    if key in table:
        raise Rejected("duplicate", f"second {what}")
    table[key] = value


def truth_rows(truth, target_index: dict[str, int]) -> np.ndarray:
    """``(N, 4)``: a truth array's pv rows in the scenario's target order (NaN: absent)."""
    pv = np.full((len(target_index), 4), math.nan)
    for tid, row in zip(truth.ids, truth.pv, strict=True):
        pv[target_index[tid]] = row
    return pv


def held_estimates(assessment, tracks: TrackSet, truth: np.ndarray) -> np.ndarray:
    """``(N, 4)``: the mean of the reported track that holds each target (NaN: none)."""
    means = {t.track_id: np.asarray(t.mean) for t in tracks.reported}
    est = np.full_like(truth, math.nan)
    for n, track_id in enumerate(assessment.held):
        if track_id in means:
            est[n] = means[int(track_id)]
    return est


def _marker_size(scenario) -> float:
    """A marker size for the scenario's scale: 1 % of the distance from the first target's
    prior mean to the farthest platform (Hernandez: ~20 m; Valverde: ~0.5 m), at least 0.1 m."""
    target = scene_targets(scenario)[0]
    model = build_motion_model(target.motion)
    mean = model.kinematics(np.array(target.prior.mean))  # pv, whatever the state
    far = max(
        math.hypot(p.initial_state[0] - mean[0], p.initial_state[2] - mean[2])
        for p in scenario.platforms
    )
    return max(0.01 * far, 0.1)


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
