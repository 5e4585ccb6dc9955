"""The run's evaluator: the only reader of ground truth; rebuilds the run record from the
graph's own outputs (the same trust filter and validation as the nodes) and keeps per-epoch
arrays sized by the scenario once, never messages, so its memory does not grow with a run."""

from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray

from activetrack.closed_loop.batch import RunRecord
from activetrack.closed_loop.data import PlanReportData
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    MAX_STATE_VALUE,
    TrackChecker,
    check_epoch_stamp,
    finite,
    platform_from_msg,
    report_from_msg,
)
from activetrack_ros.node_base import GraphNode, Rejected
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    Measurement,
    PlanReport,
    PlatformState,
    PolarMeasurement,
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


class EvaluatorNode(GraphNode):
    """Collects truth, tracks, platform states and plan reports per epoch."""

    def __init__(self, scenario, **kwargs):
        super().__init__("activetrack_evaluator", **kwargs)
        self.scenario = scenario
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
        self.diagnostics: dict[str, dict[str, int]] = {}  # latest counters per node
        self.diagnostics_order: dict[str, tuple] = {}
        self.sim_finished_at: float | None = None
        self.faults: list[str] = []  # the graph's own result messages that failed validation
        self.subscribe(DiagnosticArray, topics.DIAGNOSTICS, self.on_diagnostics)
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

    def _result_input(self, check, msg) -> None:
        """Run ``check(msg)``; a message of the graph's own that fails it (other than as a
        duplicate) is a fault of the graph: the runner stops the run instead of waiting."""
        try:
            check(msg)
        except Rejected as r:
            if self.graph_key is not None and r.reason != "duplicate":
                self.faults.append(f"{type(msg).__name__} epoch {msg.epoch}: {r}")
            raise

    # --- inputs ---------------------------------------------------------------------------

    def on_truth(self, msg: GroundTruth) -> None:
        check_epoch_stamp(msg, self.scenario, "truth")
        pv = [msg.position.x, msg.velocity.x, msg.position.y, msg.velocity.y]
        self.truth.put(msg.epoch, finite(pv, "truth", MAX_STATE_VALUE), f"truth of {msg.epoch}")

    def on_track(self, msg: TrackEstimate) -> None:
        t = self.check_track(msg)
        if t.epoch in self.means:
            raise Rejected("duplicate", f"second track of epoch {t.epoch}")
        self.means.put(t.epoch, t.mean, "track")
        self.covs.put(t.epoch, t.cov, "track")

    def on_platform(self, msg: PlatformState) -> None:
        s = platform_from_msg(msg, self.scenario, self.platform_index)
        what = f"state of {s.platform_id!r} at {s.epoch}"
        self.platforms.put(s.epoch, s.pv, what, slot=self.platform_index[s.platform_id])

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

    # --- completion ---------------------------------------------------------------------------

    # Plan reports may be missing for good (a planner that died); once the sim has finished
    # and the reports stopped coming for this long, the run is complete without them.
    REPORT_GRACE_S = 1.0

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
        return ", ".join(
            f"{what} missing at epochs {_ranges(ks)}" for what, ks in lacks.items() if ks
        )

    def _reports_given_up(self) -> bool:
        t = self.sim_finished_at
        return t is not None and time.monotonic() - t > self.REPORT_GRACE_S

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
