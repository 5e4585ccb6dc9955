"""Run the node graph on a scenario: in one process (default) or one OS process per node.

The evaluator node (here, not in the graph's nodes) is the only reader of ground truth; it
rebuilds the run record from the topics and summarises it with the same code as the batch
loop, so `activetrack run` and `activetrack batch` report comparable figures (and, in lockstep
mode, identical ones).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter

from activetrack.closed_loop.batch import RunRecord, summarize
from activetrack.scenarios import load_scenario
from activetrack_bringup.bag import BagRecorder
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_ros import graph as topics
from activetrack_ros.graph import reader_qos
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    PlanReport,
    PlatformState,
    PolarMeasurement,
    TrackEstimate,
)
from planner_node.planner_node import PlannerNode
from sim_node.sim_node import SimNode
from tracker_node.tracker_node import TrackerNode


class EvaluatorNode(Node):
    """Collects truth, tracks, platform states and plan reports per epoch."""

    def __init__(self, scenario, **kwargs):
        super().__init__("activetrack_evaluator", **kwargs)
        self.scenario = scenario
        self.truth: dict[int, np.ndarray] = {}
        self.tracks: dict[int, TrackEstimate] = {}
        self.platforms: dict[int, dict[str, np.ndarray]] = {}
        self.reports: dict[int, PlanReport] = {}
        self.looked: dict[int, set[str]] = {}  # sensors that measured at each epoch
        self.diagnostics: dict[str, dict[str, int]] = {}  # latest counters per node
        self.sim_finished_at: float | None = None
        self.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, self.on_diagnostics, 100)
        for msg_type, topic, cb in (
            (GroundTruth, topics.GROUND_TRUTH, self.on_truth),
            (TrackEstimate, topics.TRACK, self.on_track),
            (PlatformState, topics.PLATFORM_STATES, self.on_platform),
            (PlanReport, topics.PLAN_REPORT, self.on_report),
            (BearingMeasurement, topics.BEARING_MEASUREMENTS, self.on_measurement),
            (PolarMeasurement, topics.POLAR_MEASUREMENTS, self.on_measurement),
        ):
            self.create_subscription(msg_type, topic, cb, reader_qos(topic))

    def on_truth(self, msg):
        self.truth[msg.epoch] = np.array(
            [msg.position.x, msg.velocity.x, msg.position.y, msg.velocity.y]
        )

    def on_track(self, msg):
        self.tracks[msg.epoch] = msg

    def on_platform(self, msg):
        pv = np.array([msg.position.x, msg.velocity.x, msg.position.y, msg.velocity.y])
        self.platforms.setdefault(msg.epoch, {})[msg.platform_id] = pv

    def on_report(self, msg):
        self.reports[msg.epoch] = msg

    def on_measurement(self, msg):
        self.looked.setdefault(msg.epoch, set()).add(msg.sensor_id)

    def on_diagnostics(self, msg):
        for status in msg.status:
            node = status.name.rsplit("/", 1)[-1].removesuffix("_node")
            self.diagnostics[node] = {kv.key: int(kv.value) for kv in status.values}
            if node == "sim" and status.message == "finished" and self.sim_finished_at is None:
                self.sim_finished_at = time.monotonic()

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
        if len(self.tracks) <= K or len(self.truth) <= K:  # cheap test first: called often
            return False
        return not self.missing()

    def missing(self) -> str:
        """What the evaluator still lacks (for a timeout message)."""
        K = self.scenario.steps
        n_platforms = len(self.scenario.platforms)
        lacks = {
            "truth": [k for k in range(K + 1) if k not in self.truth],
            "track": [k for k in range(K + 1) if k not in self.tracks],
            "platforms": [k for k in range(K + 1) if len(self.platforms.get(k, {})) < n_platforms],
            "plan report": [k for k in range(K) if k not in self.reports]
            if self.expects_reports and not self._reports_given_up()
            else [],
        }
        return ", ".join(f"{what} missing at epochs {ks}" for what, ks in lacks.items() if ks)

    def _reports_given_up(self) -> bool:
        t = self.sim_finished_at
        return t is not None and time.monotonic() - t > self.REPORT_GRACE_S

    def record(self, wall_time_s: float) -> RunRecord:
        K = self.scenario.steps
        ids = tuple(p.id for p in self.scenario.platforms)
        n = len(self.tracks[0].state)
        reports = [self.reports[k] for k in sorted(self.reports)]
        return RunRecord(
            truth=np.stack([self.truth[k] for k in range(K + 1)]),
            estimate=np.stack([np.array(self.tracks[k].state) for k in range(K + 1)]),
            estimate_cov=np.stack(
                [np.array(self.tracks[k].covariance).reshape(n, n) for k in range(K + 1)]
            ),
            platform_paths=np.stack(
                [np.stack([self.platforms[k][i] for i in ids]) for k in range(K + 1)]
            ),
            platform_ids=ids,
            decisions=reports,
            measured=np.array(
                [
                    [
                        s.id in self.looked.get(k, ())
                        for p in self.scenario.platforms
                        for s in p.sensors
                    ]
                    for k in range(1, K + 1)
                ],
                dtype=bool,
            ),
            wall_time_s=wall_time_s,
            planning_time_s=sum(r.planning_wall_time for r in reports),
            evaluations=sum(r.evaluations for r in reports),
        )


@dataclass
class GraphRun:
    summary: object
    run_dir: Path | None
    bag: Path | None
    wall_time_s: float
    real_time_factor: float
    diagnostics: dict = field(default_factory=dict)
    files: list = field(default_factory=list)

    def to_json(self) -> dict:
        d = self.summary.to_json()
        d.update(
            wall_time_s=self.wall_time_s,
            real_time_factor=self.real_time_factor,
            bag=str(self.bag) if self.bag else None,
            run_dir=str(self.run_dir) if self.run_dir else None,
            diagnostics=self.diagnostics,
        )
        return d


def _node_params(scenario_path: str, run: int | None, mode: str, extra: dict | None = None):
    params = {"scenario": str(scenario_path), "run": -1 if run is None else int(run), "mode": mode}
    params.update(extra or {})
    return params


def default_run_dir(scenario_name: str) -> Path:
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S-%f")
    return Path("runs") / f"{scenario_name}-{stamp}"


def run_graph(
    scenario_path: str | Path,
    *,
    run: int | None = None,
    mode: str = "lockstep",
    processes: bool = False,
    run_dir: str | Path | None = None,
    record: bool = True,
    plots: bool = True,
    timeout: float = 600.0,
    sim_params: dict | None = None,
    before_spin=None,
    during_spin=None,
) -> GraphRun:
    """Bring the graph up on a scenario, run it to the end, summarise and save the run folder.

    ``before_spin(graph)`` may add nodes to the in-process graph before it runs, and
    ``during_spin(graph)`` is called between executor steps (fault-injection tests).
    """
    scenario = load_scenario(scenario_path)  # fails before anything starts
    run_dir = Path(run_dir) if run_dir else default_run_dir(scenario.name)
    run_dir.mkdir(parents=True, exist_ok=True)
    bag_path = run_dir / "bag" if record else None
    if bag_path is not None and bag_path.exists():
        raise FileExistsError(f"{bag_path} exists already: choose another run folder (--out)")
    start = time.monotonic()
    children = []
    if processes:
        # Same domain as the node processes, with discovery on this host (tests switch it off).
        os.environ["ROS_DOMAIN_ID"] = str(_domain_id())
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    with InProcessGraph() as graph:
        ctx = graph.context
        # No parameter services in one process: nobody can call them, and they cost imports at
        # start and entities in every executor wait.
        quiet = {"context": ctx, "start_parameter_services": False}
        evaluator = graph.add(EvaluatorNode(scenario, **quiet))
        recorder = graph.add(BagRecorder(bag_path, **quiet)) if record else None
        params = _node_params(scenario_path, run, mode)
        nodes = {}
        if processes:
            children = _spawn_nodes(params, sim_params)
        else:

            def options(p):
                return {
                    **quiet,
                    "parameter_overrides": [Parameter(k, value=v) for k, v in p.items()],
                }

            nodes["tracker"] = graph.add(TrackerNode(**options(params)))
            nodes["planner"] = graph.add(PlannerNode(**options(params)))
            nodes["sim"] = graph.add(SimNode(**options({**params, **(sim_params or {})})))
        if before_spin is not None:
            before_spin(graph)
        try:

            def finished() -> bool:
                if during_spin is not None:
                    during_spin(graph)
                return evaluator.complete

            ok = graph.spin_until(finished, timeout=timeout)
            if not ok:
                raise TimeoutError(
                    f"scenario {scenario.name} did not complete within {timeout} s: "
                    f"{evaluator.missing()}"
                )
            if recorder is not None:  # let the last messages (diagnostics, markers) be recorded
                graph.spin_until_quiet(lambda: recorder.count)
        finally:
            for child in children:
                child.terminate()
            for child in children:
                try:
                    child.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    child.kill()
            if recorder is not None:
                recorder.close()
        wall = time.monotonic() - start
        # Counters straight from the nodes in one process, else their last /diagnostics.
        diagnostics = {name: dict(node.counters.counts) for name, node in nodes.items()}
        diagnostics = diagnostics or dict(evaluator.diagnostics)
        summary = summarize(scenario, [evaluator.record(wall)], wall)
    result = GraphRun(
        summary=summary,
        run_dir=run_dir,
        bag=bag_path,
        wall_time_s=wall,
        real_time_factor=scenario.duration / wall,
        diagnostics=diagnostics,
    )
    if plots:
        from activetrack.plots import plot_run  # matplotlib: 0.7 s of imports, only for plots

        result.files = plot_run(summary, run_dir)
    (run_dir / "summary.json").write_text(json.dumps(result.to_json(), indent=2))
    return result


def _domain_id() -> int:
    return int(os.environ.get("ROS_DOMAIN_ID", str(100 + os.getpid() % 100)))


def _spawn_nodes(params: dict, sim_params: dict | None) -> list[subprocess.Popen]:
    """Each node as its own OS process (its console entry point), talking over DDS."""
    env = dict(os.environ)
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    env["ROS_DOMAIN_ID"] = str(_domain_id())
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    bin_dir = Path(sys.executable).parent
    procs = []
    for name, extra in (("tracker_node", {}), ("planner_node", {}), ("sim_node", sim_params or {})):
        args = [str(bin_dir / name), "--ros-args"]
        for k, v in {**params, **extra}.items():
            args += ["-p", f"{k}:={v}"]
        procs.append(subprocess.Popen(args, env=env))
    return procs
