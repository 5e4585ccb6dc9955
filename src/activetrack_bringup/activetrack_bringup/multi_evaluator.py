"""The evaluator of a multi-target run: the only reader of the targets' truth; rebuilds the
run's :class:`~activetrack.multitarget.data.MultiRunRecord` from the graph's own outputs
(truth arrays, scans, track arrays, platform states, commands, beams and plan reports, each
checked as the nodes check them), so that the runner scores it with the batch loop's code
(:func:`activetrack.multitarget.evaluation.evaluate_run`): in lockstep, `activetrack run`
equals `activetrack batch` bit for bit.

What the sim knows and does not publish is rebuilt from what it does: which sensor had which
alive target in its field of view (the per-target bound's ``observed``) from each scan's field
of view and the truth, with the simulator's own test. The detections' labels stay in the sim,
so a run's plot shows the detections unlabelled.
"""

from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.data import Command, PlanReportData
from activetrack.multitarget.data import (
    BeamCommand,
    MultiDecision,
    MultiRunRecord,
    Scan,
    TrackSet,
)
from activetrack_bringup.evaluator import TRUTH_RGBA, EpochTable, ResultNode, lacks_text
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    MAX_SPEED,
    check_epoch_stamp,
    finite,
    header,
    marker,
    platform_from_msg,
    report_from_msg,
)
from activetrack_ros.convert_multi import (
    beam_from_msg,
    scan_from_msg,
    scan_sensors,
    track_array_from_msg,
    truth_array_from_msg,
)
from activetrack_ros.node_base import Rejected
from msgs_defs.msg import (
    BeamCommand as BeamCommandMsg,
)
from msgs_defs.msg import (
    GroundTruthArray,
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    TrackArray,
)
from msgs_defs.msg import Scan as ScanMsg


class MultiEvaluatorNode(ResultNode):
    """Collects a multi-target run per epoch (module docstring); ``record()`` gives it."""

    def __init__(self, scenario, *, report_grace_s: float = 1.0, **kwargs):
        super().__init__("activetrack_evaluator", scenario, report_grace_s=report_grace_s, **kwargs)
        scenario = self.scenario
        self.size_history(scenario)
        K = scenario.steps
        self.target_ids = tuple(t.id for t in scenario.targets)
        self.target_index = {tid: i for i, tid in enumerate(self.target_ids)}
        self.platform_index = {p.id: i for i, p in enumerate(scenario.platforms)}
        self.sensors = scan_sensors(scenario)
        self.sensor_index = {sid: i for i, sid in enumerate(self.sensors)}
        self.steerable = tuple(
            s.id for p in scenario.platforms for s in p.sensors if s.beam_width is not None
        )
        self.controllable = tuple(p.id for p in scenario.platforms if p.controllable)
        self.truth = EpochTable(K + 1, (len(self.target_ids), 4))
        self.platforms = EpochTable(K + 1, (4,), slots=len(scenario.platforms))
        self.tracks: dict[int, TrackSet] = {}
        self.scans: dict[int, dict[str, Scan]] = {}
        self.announced = np.zeros(K + 1, dtype=int)  # scans the sim announced per epoch
        self.commands: dict[int, dict[str, Command]] = {}
        self.beams: dict[int, dict[str, BeamCommand]] = {}
        self.reports: dict[int, PlanReportData] = {}
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        for msg_type, topic, callback in (
            (GroundTruthArray, topics.GROUND_TRUTH_ARRAY, self.on_truth),
            (TrackArray, topics.TRACKS, self.on_tracks),
            (PlatformState, topics.PLATFORM_STATES, self.on_platform),
            (ScanMsg, topics.SCANS, self.on_scan),
            (ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command),
            (BeamCommandMsg, topics.BEAM_COMMANDS, self.on_beam),
            (PlanReport, topics.PLAN_REPORT, self.on_report),
        ):
            self.subscribe(msg_type, topic, lambda m, cb=callback: self._result_input(cb, m))

    # --- inputs ---------------------------------------------------------------------------

    def on_truth(self, msg: GroundTruthArray) -> None:
        truth = truth_array_from_msg(msg, self.scenario)
        pv = np.full((len(self.target_ids), 4), math.nan)
        for tid, row in zip(truth.ids, truth.pv, strict=True):
            pv[self.target_index[tid]] = row
        self.truth.put(truth.epoch, pv, f"truth array of {truth.epoch}")
        self.publish_truth(truth.epoch, truth.ids, pv)

    def on_tracks(self, msg: TrackArray) -> None:
        tracks = track_array_from_msg(msg, self.scenario)
        if tracks.epoch in self.tracks:
            raise Rejected("duplicate", f"second track array of epoch {tracks.epoch}")
        self.tracks[tracks.epoch] = tracks

    def on_platform(self, msg: PlatformState) -> None:
        s = platform_from_msg(msg, self.scenario, self.platform_index)
        what = f"state of {s.platform_id!r} at {s.epoch}"
        self.platforms.put(s.epoch, s.pv, what, slot=self.platform_index[s.platform_id])
        self.announced[s.epoch] = max(self.announced[s.epoch], msg.epoch_measurement_count)

    def on_scan(self, msg: ScanMsg) -> None:
        scan = scan_from_msg(msg, self.scenario, self.sensors)
        scans = self.scans.setdefault(scan.epoch, {})
        if scan.sensor_id in scans:
            raise Rejected("duplicate", f"second scan of {scan.sensor_id!r} at {scan.epoch}")
        scans[scan.sensor_id] = scan

    def on_command(self, msg: ManoeuvreCommand) -> None:
        what = f"command for {msg.platform_id!r}"
        if msg.platform_id not in self.controllable or msg.epoch >= self.scenario.steps:
            raise Rejected("bad_field", f"{what} at {msg.epoch}")
        check_epoch_stamp(msg, self.scenario, what)
        finite((msg.heading_change,), f"{what} heading_change", math.pi + 1e-9)
        finite((msg.speed_change,), f"{what} speed_change", MAX_SPEED)
        commands = self.commands.setdefault(msg.epoch, {})
        if msg.platform_id in commands:
            raise Rejected("duplicate", f"second {what} at {msg.epoch}")
        commands[msg.platform_id] = Command(
            msg.platform_id,
            msg.epoch,
            msg.heading_change,
            msg.speed_change,
            msg.commanded_heading,
            msg.commanded_speed,
        )

    def on_beam(self, msg: BeamCommandMsg) -> None:
        beam = beam_from_msg(msg, self.scenario)
        beams = self.beams.setdefault(beam.epoch, {})
        if beam.sensor_id in beams:
            raise Rejected("duplicate", f"second beam of {beam.sensor_id!r} at {beam.epoch}")
        beams[beam.sensor_id] = beam

    def on_report(self, msg: PlanReport) -> None:
        report = report_from_msg(msg, self.scenario)
        if report.epoch in self.reports:
            raise Rejected("duplicate", f"second plan report of epoch {report.epoch}")
        self.reports[report.epoch] = report

    # --- what the live view shows ---------------------------------------------------------

    def publish_truth(self, k: int, ids, pv: np.ndarray) -> None:
        """A sphere on each alive target's true position (ns ``truth``, id = its index);
        removed when it is gone."""
        hdr = header(k * self.scenario.dt, self.frame_id)
        markers = []
        for i, row in enumerate(pv):
            m = marker(hdr, "truth", i, Marker.SPHERE, TRUTH_RGBA)
            if np.isnan(row[0]):
                m.action = Marker.DELETE
            else:
                m.pose.position = Point(x=float(row[0]), y=float(row[2]))
                m.scale.x = m.scale.y = m.scale.z = 40.0
            markers.append(m)
        self.marker_pub.publish(MarkerArray(markers=markers))

    # --- completion ---------------------------------------------------------------------------

    def _scans_in(self, k: int) -> bool:
        return len(self.scans.get(k, {})) >= self.announced[k]

    def _decided(self, k: int) -> bool:
        commands = self.commands.get(k, {})
        beams = self.beams.get(k, {})
        return all(p in commands for p in self.controllable) and all(
            s in beams for s in self.steerable
        )

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
            "commands or beams": [] if given_up else [k for k in range(K) if not self._decided(k)],
            "plan report": [] if given_up else [k for k in range(K) if k not in self.reports],
        }
        return lacks_text(lacks)

    def completed_epochs(self) -> int:
        """The last epoch K' such that truth, tracks, platform states and scans of 0..K' are
        all here."""
        k = -1
        while (
            k + 1 in self.truth
            and k + 1 in self.tracks
            and k + 1 in self.platforms
            and (k + 1 == 0 or self._scans_in(k + 1))
        ):
            k += 1
        return k

    def record(self, wall_time_s: float, last_epoch: int | None = None) -> MultiRunRecord:
        """The run's record over epochs 0..last_epoch (default: all)."""
        K = self.scenario.steps if last_epoch is None else last_epoch
        truth = self.truth.rows(K).copy()
        order = {sid: i for i, sid in enumerate(self.sensors)}
        scans = [
            sorted(self.scans.get(k, {}).values(), key=lambda s: order[s.sensor_id])
            for k in range(1, K + 1)
        ]
        decisions = [self._decision(k) for k in range(K)]
        return MultiRunRecord(
            target_ids=self.target_ids,
            sensor_ids=tuple(self.sensors),
            platform_ids=tuple(self.platform_index),
            truth=truth,
            tracks=[self.tracks[k] for k in range(K + 1)],
            platform_paths=self.platforms.rows(K).copy(),
            scans=scans,
            observed=self._observed(truth, scans),
            decisions=decisions,
            clamps=int(self.diagnostics.get("sim", {}).get("commands_clamped", 0)),
            wall_time_s=wall_time_s,
            planning_time_s=sum(d.report.wall_time_s for d in decisions if d.report is not None),
        )

    def _decision(self, k: int) -> MultiDecision:
        commands = self.commands.get(k, {})
        beams = self.beams.get(k, {})
        return MultiDecision(
            k,
            tuple(commands[p] for p in self.controllable if p in commands),
            tuple(beams[s] for s in self.steerable if s in beams),
            self.reports.get(k),
        )

    def _observed(self, truth: np.ndarray, scans: list[list[Scan]]) -> np.ndarray:
        """``(K, S, N)``: scan s of epoch k had alive target n in its field of view and range
        (the simulator's test, on the scan's own field of view and sensor position)."""
        out = np.zeros((len(scans), len(self.sensors), len(self.target_ids)), dtype=bool)
        for k, epoch_scans in enumerate(scans, start=1):
            alive = ~np.isnan(truth[k, :, 0])
            for scan in epoch_scans:
                sensor = self.sensors[scan.sensor_id][1]
                x, pv = truth[k][alive], np.asarray(scan.sensor_pv)
                seen = alive.copy()
                seen[alive] = scan.fov.contains(x, pv) & sensor.in_range(x, pv)
                out[k - 1, self.sensor_index[scan.sensor_id]] = seen
        return out
