"""Run the node graph on a scenario: in one process (default) or one OS process per node.

Each run makes a fresh graph key (activetrack_ros.trust): the nodes, the evaluator and the
recorder count only messages written by the run's own nodes. The evaluator node (here, not in
the graph's nodes) is the only reader of ground truth; it keeps per-epoch results (not
messages) and summarises them with the same code as the batch loop, so `activetrack run` and
`activetrack batch` report comparable figures (and, in lockstep mode, identical ones).

A run that cannot finish (Ctrl-C, SIGTERM, a node process that died, the timeout) still closes
its bag and writes ``summary.json`` marked incomplete, with the epochs it completed, then
raises :class:`RunIncomplete`.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from rclpy.parameter import Parameter

from activetrack.closed_loop.batch import summarize
from activetrack.scenarios import load_scenario
from activetrack_bringup import interrupts
from activetrack_bringup.bag import BagRecorder
from activetrack_bringup.evaluator import EvaluatorNode
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.run_folder import run_dir_for
from activetrack_bringup.supervisor import NodeDied, Supervisor
from activetrack_ros.trust import KEY_ENV, GraphKey
from planner_node.planner_node import PlannerNode
from sim_node.sim_node import SimNode
from tracker_node.tracker_node import TrackerNode


class GraphFault(RuntimeError):
    """One of the graph's own messages that the result needs failed validation (e.g. a
    diverged filter's non-finite track): the run cannot complete, so it stops at once."""


class RunIncomplete(RuntimeError):
    """The run stopped before its last epoch; ``result`` holds the partial run (its summary
    covers the epochs completed) and ``exit_code`` what the command line returns."""

    def __init__(self, message: str, result: GraphRun, exit_code: int):
        super().__init__(message)
        self.result = result
        self.exit_code = exit_code


@dataclass
class GraphRun:
    summary: object | None
    run_dir: Path | None
    bag: Path | None
    wall_time_s: float
    real_time_factor: float
    diagnostics: dict = field(default_factory=dict)
    files: list = field(default_factory=list)
    complete: bool = True
    # complete | interrupted (SIGINT/SIGTERM) | node_died | graph_fault | timeout, or, for a
    # run that finished: node_errors (exceptions in callbacks) | non_finite (metrics)
    status: str = "complete"
    detail: str = ""
    epochs_completed: int = 0
    foreign: dict = field(default_factory=dict)  # node -> foreign messages dropped
    restarts: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        d = self.summary.to_json() if self.summary is not None else {}
        d.update(
            complete=self.complete,
            status=self.status,
            detail=self.detail,
            epochs_completed=self.epochs_completed,
            wall_time_s=self.wall_time_s,
            real_time_factor=self.real_time_factor,
            bag=str(self.bag) if self.bag else None,
            run_dir=str(self.run_dir) if self.run_dir else None,
            diagnostics=self.diagnostics,
            foreign_messages_dropped=self.foreign,
            restarts=self.restarts,
        )
        return _json_safe(d)


def _json_safe(value):
    """NaN and infinities as null: summary.json stays strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def _node_params(scenario_path: str, run: int | None, mode: str, extra: dict | None = None):
    params = {"scenario": str(scenario_path), "run": -1 if run is None else int(run), "mode": mode}
    params.update(extra or {})
    return params


def default_run_dir(scenario_name: str) -> Path:
    return run_dir_for(scenario_name)


@contextmanager
def _environment(**values: str):
    """Set environment variables for the block only (rclpy reads them at context init)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


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
    restartable: tuple[str, ...] | None = None,
    graph_key: GraphKey | None = None,
) -> GraphRun:
    """Bring the graph up on a scenario, run it to the end, summarise and save the run folder.

    ``before_spin(graph)`` may add nodes to the in-process graph before it runs, and
    ``during_spin(graph)`` is called between executor steps (fault-injection tests).
    ``restartable``: node names ("planner") that may be restarted when their process dies
    (default: the scenario's ``graph.restartable``). Raises RunIncomplete when the run stops
    early, ScenarioError / FileExistsError before anything starts.
    """
    scenario = load_scenario(scenario_path)  # fails before anything starts
    if restartable is None:
        restartable = tuple(scenario.graph.restartable)
    run_dir = Path(run_dir) if run_dir else default_run_dir(scenario.name)
    bag_path = run_dir / "bag" if record else None
    if bag_path is not None and bag_path.exists():
        raise FileExistsError(f"{bag_path} exists already: choose another run folder (--out)")
    run_dir.mkdir(parents=True, exist_ok=True)
    key = graph_key or GraphKey.generate()
    start = time.monotonic()
    supervisor = None
    status, detail, exit_code = "complete", "", 0
    ros_env = {}
    if processes:
        # Same domain as the node processes, with discovery on this host (tests switch it off).
        ros_env = {
            "ROS_DOMAIN_ID": str(_domain_id()),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        }
    with _environment(**ros_env):
        graph = InProcessGraph()
    recorder = None
    nodes = {}
    with interrupts.raising(), graph:
        ctx = graph.context
        # No parameter services in one process: nobody can call them, and they cost imports at
        # start and entities in every executor wait.
        quiet = {"context": ctx, "start_parameter_services": False}
        evaluator = graph.add(EvaluatorNode(scenario, graph_key=key, **quiet))

        def progress() -> int:
            counted = sum(n.counters.total("received.") for n in (evaluator, *nodes.values()))
            return counted + (recorder.count if recorder is not None else 0)

        try:
            if record:  # the run's record: only the graph's own per-epoch messages
                recorder = graph.add(BagRecorder(bag_path, graph_key=key, **quiet))
            params = _node_params(scenario_path, run, mode)
            if processes:
                supervisor = _start_processes(
                    params, sim_params, key, ros_env, restartable, scenario.graph.max_restarts
                )
                graph.supervisor = supervisor  # for during_spin hooks (fault-injection tests)
            else:

                def options(p):
                    return {
                        **quiet,
                        "graph_key": key,
                        "parameter_overrides": [Parameter(k, value=v) for k, v in p.items()],
                    }

                nodes["tracker"] = graph.add(TrackerNode(**options(params)))
                nodes["planner"] = graph.add(PlannerNode(**options(params)))
                nodes["sim"] = graph.add(SimNode(**options({**params, **(sim_params or {})})))
            if before_spin is not None:
                before_spin(graph)

            def finished() -> bool:
                if supervisor is not None:
                    supervisor.poll()
                if evaluator.faults:
                    raise GraphFault("; ".join(evaluator.faults[:3]))
                if during_spin is not None:
                    during_spin(graph)
                return evaluator.complete

            if not graph.spin_until(finished, timeout=timeout):
                status, exit_code = "timeout", 1
                detail = f"did not complete within {timeout} s: {evaluator.missing()}"
            else:  # let the last messages be recorded and counted: the counters are final
                graph.spin_until_quiet(progress)
        except (KeyboardInterrupt, interrupts.Terminated) as exc:
            status, exit_code = "interrupted", interrupts.exit_code(exc)
            detail = "SIGINT" if exit_code == 130 else "SIGTERM"
        except NodeDied as exc:
            status, detail, exit_code = "node_died", str(exc), 1
        except GraphFault as exc:
            status, detail, exit_code = "graph_fault", f"the graph published invalid {exc}", 1
        finally:
            with interrupts.deferred():  # a second Ctrl-C must not leave the bag open
                if status != "complete":  # take in what was delivered: a fuller partial run
                    graph.spin_until_quiet(progress, quiet=0.05, timeout=0.3)
                if supervisor is not None:
                    supervisor.stop()
                if recorder is not None:
                    recorder.close()
        with interrupts.deferred():
            result = _conclude(
                scenario,
                evaluator,
                recorder=recorder,
                nodes=nodes,
                supervisor=supervisor,
                status=status,
                detail=detail,
                wall=time.monotonic() - start,
                run_dir=run_dir,
                bag_path=bag_path,
                plots=plots and status == "complete",
            )
    if exit_code == 0 and result.status != "complete":
        exit_code = 1  # the run finished, but not well (non-finite metrics, node errors)
    if exit_code:
        raise RunIncomplete(
            f"scenario {scenario.name}: {result.status}: {result.detail}", result, exit_code
        )
    return result


def _conclude(
    scenario,
    evaluator,
    *,
    recorder,
    nodes,
    supervisor,
    status,
    detail,
    wall,
    run_dir,
    bag_path,
    plots,
) -> GraphRun:
    """Summarise what the evaluator holds (the completed epochs of an incomplete run) and
    write summary.json (and the plots of a complete run)."""
    # Counters straight from the nodes in one process, else their last /diagnostics.
    diagnostics = {name: dict(node.counters.counts) for name, node in nodes.items()}
    diagnostics = diagnostics or dict(evaluator.diagnostics)
    diagnostics["evaluator"] = dict(evaluator.counters.counts)
    if recorder is not None:
        diagnostics["recorder"] = {"recorded": recorder.count, "foreign": recorder.foreign}
    complete = status == "complete"
    last = scenario.steps if complete else evaluator.completed_epochs()
    partial = scenario if complete else scenario.model_copy(update={"steps": max(last, 0)})
    summary = summarize(partial, [evaluator.record(wall, last)], wall) if last >= 1 else None
    result = GraphRun(
        summary=summary,
        run_dir=run_dir,
        bag=bag_path,
        wall_time_s=wall,
        real_time_factor=partial.duration / wall,
        diagnostics=diagnostics,
        complete=complete,
        status=status,
        detail=detail,
        epochs_completed=max(last, 0),
        foreign={
            n: sum(v for k, v in c.items() if k.startswith("foreign."))
            for n, c in diagnostics.items()
        },
        restarts=supervisor.restarts if supervisor is not None else {},
    )
    errors = sum(v for c in diagnostics.values() for k, v in c.items() if k.startswith("errors."))
    if complete and errors:
        result.status = "node_errors"
        result.detail = f"{errors} unexpected exceptions in node callbacks (logged, counted)"
    if complete and summary is not None and not _finite_metrics(summary):
        result.status = "non_finite"
        result.detail = "a metric is not finite: the track diverged or was corrupted"
    if plots and complete and summary is not None:
        from activetrack.plots import plot_run  # matplotlib: 0.7 s of imports, only for plots

        result.files = plot_run(summary, run_dir)
    (run_dir / "summary.json").write_text(json.dumps(result.to_json(), indent=2))
    return result


def _finite_metrics(summary) -> bool:
    """RMSEs must be finite; bounds may be NaN only where none is computed (nonlinear
    motion models), never infinite."""
    rmse_ok = all(math.isfinite(v) for v in (summary.rmse_x, summary.rmse_y))
    bounds_ok = not any(math.isinf(v) for v in (summary.mean_bound_x, summary.mean_bound_y))
    return rmse_ok and bounds_ok


def _domain_id() -> int:
    return int(os.environ.get("ROS_DOMAIN_ID", str(100 + os.getpid() % 100)))


def _start_processes(
    params, sim_params, key: GraphKey, ros_env, restartable, max_restarts: int
) -> Supervisor:
    """Each node as its own OS process (its console entry point), talking over DDS."""
    env = dict(os.environ)
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    env.update(ros_env)
    env[KEY_ENV] = key.hex()  # the environment, not a parameter: parameters are readable
    supervisor = Supervisor(
        env, max_restarts, log=lambda text: print(f"activetrack: {text}", file=sys.stderr)
    )
    for name, extra in (("tracker", {}), ("planner", {}), ("sim", sim_params or {})):
        supervisor.add(f"{name}_node", {**params, **extra}, restartable=name in restartable)
    supervisor.start()
    return supervisor
