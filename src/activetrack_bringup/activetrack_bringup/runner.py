"""Run the node graph on a scenario: in one process (default) or one OS process per node.

Each run makes a fresh graph key (activetrack_ros.trust): the nodes, the evaluator and the
recorder count only the run's own messages. A run that cannot finish (Ctrl-C, SIGTERM, a dead
node process, the timeout) still closes its bag and writes ``summary.json`` marked incomplete,
then raises :class:`RunIncomplete`.
"""

from __future__ import annotations

import importlib
import math
import os
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from rclpy.parameter import Parameter

from activetrack.closed_loop.batch import BatchSummary, summarize
from activetrack.closed_loop.components import component_rngs
from activetrack.closed_loop.evaluation import evaluate_run
from activetrack.scenarios import first_epochs, load_scenario
from activetrack.strict_json import json_safe
from activetrack_bringup import interrupts
from activetrack_bringup.bag import BagRecorder
from activetrack_bringup.evaluator import LOST_GRACE_S, EvaluatorNode
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.ros_network import RosNetwork, ros_network
from activetrack_bringup.run_folder import interrupted_before_start, run_dir_for, write_summary
from activetrack_bringup.supervisor import NodeDied, Supervisor
from activetrack_ros.graph import history_depth
from activetrack_ros.hold import MATCH_WAIT_S, SETTLE_S, WaitFor
from activetrack_ros.node_base import REPUBLISH_S
from activetrack_ros.trust import KEY_BYTES, KEY_ENV, GraphKey
from planner_node.planner_node import PlannerNode
from sim_node.sim_node import SimNode
from tracker_node.tracker_node import TrackerNode

NODES = {"sim": SimNode, "tracker": TrackerNode, "planner": PlannerNode}
NODE_NAMES = tuple(NODES)  # the graph's nodes, as ``nodes`` (RunOptions) names them

# How long the evaluator waits for missing plan reports after the sim finished, with node
# processes (DDS discovery between them): past one periodic discovery announcement.
REPORT_GRACE_PROCESSES_S = 5.0
# s the runner waits after a run for node processes' counters it has not had yet
COUNTERS_WAIT_S = 5.0


class GraphSetupError(ValueError):
    """The run cannot start as asked (e.g. node processes that could not discover each other)."""


class RemoteNodesMissing(RuntimeError):
    """Nodes meant to run on other hosts did not join the graph in time."""


class ViewersMissing(RuntimeError):
    """The outside subscribers ``--wait-for`` asked for did not join in time."""


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
    # run that finished: node_errors (exceptions in callbacks) | non_finite (metrics) |
    # lockstep_timeouts (a timeout decided an epoch: hold course, an epoch closed incomplete) |
    # messages_lost (the evaluator gave up messages never sent: the summary covers the epochs
    # before the first one lacking truth, tracks or a platform state; lost scans are left out)
    status: str = "complete"
    detail: str = ""
    epochs_completed: int = 0
    foreign: dict = field(default_factory=dict)  # node -> foreign messages dropped
    restarts: dict = field(default_factory=dict)
    network: RosNetwork | None = None  # the DDS domain and discovery range of the run
    # What a lockstep timeout decided, per epoch: epoch -> node -> what -> how many (e.g.
    # {3: {"sim": {"held_course": 1}, "tracker": {"closed_incomplete": 1, "missing_scans": 1}}})
    timeouts: dict = field(default_factory=dict)

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
            timeouts={str(k): v for k, v in self.timeouts.items()},
            ros=self.network.to_json() if self.network is not None else None,
        )
        return json_safe(d)


def check_namespace(namespace: str) -> str:
    """'' (none) or a ROS namespace like ``g1`` or ``/fleet/g1``, returned absolute."""
    ns = namespace.strip("/")
    if ns and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*", ns):
        raise GraphSetupError(
            f"namespace {namespace!r} is not a ROS namespace: names of letters, digits and "
            "underscores, not starting with a digit, separated by '/'"
        )
    return "/" + ns if ns else ""


def remote_nodes(nodes: tuple[str, ...] | None) -> tuple[str, ...]:
    """The graph's nodes that a runner starting the node processes ``nodes`` (None: all) does
    not start: they run on other hosts."""
    return () if nodes is None else tuple(n for n in NODE_NAMES if n not in nodes)


def remote_key(nodes: tuple[str, ...] | None) -> GraphKey | None:
    """The graph key of a run whose other nodes run on other hosts: ACTIVETRACK_GRAPH_KEY, the
    same on every host (GraphSetupError if unset or malformed); None when every node runs
    here (the run makes its own)."""
    remote = remote_nodes(nodes)
    if not remote:
        return None
    try:
        key = GraphKey.from_environment()
    except ValueError as exc:
        raise GraphSetupError(str(exc)) from None
    if key is None:
        raise GraphSetupError(
            f"the {' and '.join(remote)} node(s) run on another host: set {KEY_ENV} to the same "
            f"{2 * KEY_BYTES} hex digits on every host "
            "(e.g. python -c 'import secrets; print(secrets.token_hex(32))')"
        )
    return key


def _check_remote(opts: RunOptions, key: GraphKey | None) -> GraphKey | None:
    """Check ``nodes``. With nodes on other hosts the run shares their domain and graph key:
    ROS_DOMAIN_ID must be set explicitly and the key given or in ACTIVETRACK_GRAPH_KEY; returns
    the run's key (None: a fresh one)."""
    if opts.nodes is None:
        return key
    unknown = sorted(set(opts.nodes) - set(NODE_NAMES))
    if unknown:
        raise GraphSetupError(f"unknown nodes {unknown}: the graph's are {', '.join(NODE_NAMES)}")
    if not opts.processes:
        raise GraphSetupError("choosing the nodes to start here (--nodes) needs --processes")
    remote = remote_nodes(opts.nodes)
    if remote and not os.environ.get("ROS_DOMAIN_ID", "").strip():
        raise GraphSetupError(
            f"the {' and '.join(remote)} node(s) run on another host: set ROS_DOMAIN_ID, the "
            "same on every host"
        )
    return key or remote_key(opts.nodes)


@dataclass
class RunOptions:
    """How run_graph runs a scenario."""

    run: int | None = None  # Monte Carlo run index
    mode: str = "lockstep"  # or free
    processes: bool = False  # one OS process per node
    record: bool = True  # the bag
    plots: bool = True
    timeout: float = 600.0  # wall seconds
    sim_params: dict | None = None  # sim node parameters
    before_spin: object = None  # before_spin(graph): may add nodes to the in-process graph
    during_spin: object = None  # during_spin(graph): between executor steps (fault injection)
    restartable: tuple[str, ...] | None = None  # node names (default: the scenario's)
    namespace: str = ""  # of every node, the evaluator and the recorder
    nodes: tuple[str, ...] | None = None  # node processes started here (the others: remote)
    tracker_params: dict | None = None  # tracker node parameters
    wait_for: str | None = None  # N | TOPIC: hold the first epoch for outside subscribers
    wait_timeout: float = 60.0  # s, for wait_for
    announce: object = None  # announce(network): the run's RosNetwork, before the graph starts
    # s after the sim and the tracker finished before a missing truth, state, scan or track
    # array is given up (the run ends messages_lost); at least the report grace
    lost_grace: float = LOST_GRACE_S


def run_graph(
    scenario_path: str | Path,
    *,
    run_dir: str | Path | None = None,
    graph_key: GraphKey | None = None,
    **options,
) -> GraphRun:
    """Bring the graph up on a scenario (``options``: RunOptions), run it to the end, summarise
    and save the run folder. Raises RunIncomplete when the run stops early, ScenarioError,
    FileExistsError or GraphSetupError before anything starts.
    """
    started = time.monotonic()
    opts = RunOptions(**options)
    opts.namespace = check_namespace(opts.namespace)
    wait = _check_wait_for(opts)
    scenario = load_scenario(scenario_path)  # fails before anything starts
    if opts.processes and os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").upper() == "OFF":
        raise GraphSetupError(
            "--processes needs DDS discovery between processes on this host, but "
            "ROS_AUTOMATIC_DISCOVERY_RANGE is OFF: set it to LOCALHOST (or unset it)"
        )
    _check_filter(scenario, opts)
    graph_key = _check_remote(opts, graph_key) or GraphKey.generate()
    run_dir = Path(run_dir) if run_dir else run_dir_for(scenario.name)
    bag_path = run_dir / "bag" if opts.record else None
    if bag_path is not None and bag_path.exists():
        raise FileExistsError(f"{bag_path} exists already: choose another run folder (--out)")
    with interrupts.raising():  # from here on a signal at any moment leaves summary.json
        try:
            _import_lazy_modules()
            _make_run_dir(run_dir)
            runner = _GraphRunner(scenario, str(scenario_path), opts, graph_key, wait)
            if opts.announce is not None:
                opts.announce(runner.network)
        except (KeyboardInterrupt, interrupts.Terminated) as exc:
            code = interrupts.exit_code(exc)
            raise _interrupted_before_start(scenario, run_dir, code, started) from None
        result = runner.execute(run_dir, bag_path)
    if runner.exit_code:
        raise RunIncomplete(
            f"scenario {scenario.name}: {result.status}: {result.detail}", result, runner.exit_code
        )
    return result


# What the core imports on first use (the GOSPA assignment, the planner's searches and special
# functions, the tracker's k-d trees), imported before the graph starts: a signal inside one of
# these imports mid-run leaves its compiled modules half-registered, and the interrupted run's
# summary could then not import it again (seen: scipy.optimize's HiGHS wrapper, "type already
# registered", in the run's GOSPA). A signal during start-up ends the run before any of them
# is needed.
LAZY_MODULES = ("scipy.optimize", "scipy.special", "scipy.spatial")


def _import_lazy_modules() -> None:
    for name in LAZY_MODULES:
        importlib.import_module(name)


def _interrupted_before_start(scenario, run_dir: Path, code: int, started: float) -> RunIncomplete:
    """A signal while the graph was being built: summary.json says so (no epochs)."""
    wall = time.monotonic() - started
    data = interrupted_before_start(run_dir, code, wall)
    result = GraphRun(None, run_dir, None, wall, 0.0, complete=False, status="interrupted")
    result.detail = data["detail"]
    return RunIncomplete(f"scenario {scenario.name}: interrupted: {result.detail}", result, code)


def _make_run_dir(run_dir: Path) -> None:
    """Create the run folder; an --out that cannot be one is a GraphSetupError (one line)."""
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GraphSetupError(
            f"run folder {run_dir} cannot be created: {exc.strerror or exc}"
        ) from None


def _check_filter(scenario, opts: RunOptions) -> None:
    """A tracker ``filter`` must be registered once the scenario (and its plugins) loaded."""
    from activetrack.filters import filter_names

    name = (opts.tracker_params or {}).get("filter")
    if name is not None and name not in filter_names():
        raise GraphSetupError(f"--filter must be one of {list(filter_names())}, got {name!r}")


def _check_wait_for(opts: RunOptions) -> WaitFor | None:
    """``wait_for`` parsed; it needs the sim started here (GraphSetupError otherwise)."""
    try:
        wait = WaitFor.parse("" if opts.wait_for is None else str(opts.wait_for))
    except ValueError as exc:
        raise GraphSetupError(str(exc)) from None
    if wait is not None and opts.nodes is not None and "sim" not in opts.nodes:
        raise GraphSetupError(
            "--wait-for holds the first epoch of the sim started here: add sim to --nodes (a "
            "sim on another host holds with -p wait_for_subscribers:=N or wait_for_topic:=T)"
        )
    return wait


class _GraphRunner:
    """One run: the in-process graph (evaluator, recorder and, unless processes, the nodes),
    the supervised node processes, and how the run ended."""

    def __init__(self, scenario, scenario_path: str, opts: RunOptions, key: GraphKey, wait):
        self.scenario = scenario
        self.opts = opts
        self.key = key
        every = {"scenario": scenario_path, "run": -1 if opts.run is None else int(opts.run)}
        mode = {"mode": opts.mode}  # the planner plans alike in both modes: it has no mode
        self.params = {"sim": every | mode, "tracker": every | mode, "planner": dict(every)}
        # every graph run has a tracker (here or on another host): the sim waits for it
        self.params["sim"]["expect_tracker"] = True
        self.params["tracker"].update(opts.tracker_params or {})
        self.wait = wait  # --wait-for: the sim holds its first epoch (activetrack_ros.hold)
        self.sim_started = self.wait is None
        if self.wait is not None:
            self.params["sim"].update(self.wait.params())
        self.params["sim"].update(opts.sim_params or {})
        self.remote = remote_nodes(opts.nodes)  # started on other hosts, not here
        self.network = ros_network(opts.processes, not self.remote)
        # The node processes' domain; in one process the context needs no domain of its own.
        self.domain = self.network.domain_id if opts.processes else None
        self.graph = InProcessGraph(domain_id=self.domain)
        # Every node answers parameter services, in one process too (ROS tools see it there):
        # measured, +28 ms median of 3.5 s (default scenario), within the noise.
        self.common = {"context": self.graph.context, "namespace": opts.namespace or None}
        named = [Parameter(k, value=self.params["planner"][k]) for k in ("scenario", "run")]
        self.evaluator = self.graph.add(
            EvaluatorNode(
                scenario, graph_key=key, report_grace_s=REPORT_GRACE_PROCESSES_S
                if opts.processes else 1.0, lost_grace_s=opts.lost_grace,
                parameter_overrides=named, **self.common,
            )
        )  # fmt: skip
        self.graph.evaluator = self.evaluator  # for during_spin hooks (tests, benchmarks)
        self.recorder: BagRecorder | None = None
        self.nodes: dict = {}
        self.supervisor: Supervisor | None = None
        self.status, self.detail, self.exit_code = "complete", "", 0
        self.start = time.monotonic()

    def progress(self) -> int:
        """Messages taken so far (for waiting until the graph is quiet), node processes'
        included as their counters last reported them."""
        nodes = (self.evaluator, *self.nodes.values())
        counted = sum(n.counters.total("received.") for n in nodes)
        reported = sum(_total(c, "received.") for c in self.evaluator.diagnostics.values())
        return counted + reported + (self.recorder.count if self.recorder is not None else 0)

    def execute(self, run_dir: Path, bag_path: Path | None) -> GraphRun:
        """Run the graph, stop it, summarise, close it and write summary.json. A signal at
        any moment of it ends the same way, the summary marked interrupted: the first one is
        raised (and caught here), later ones and those in the held stretches are noted."""
        result = None
        try:
            try:
                self.run(bag_path)
            finally:
                with interrupts.held():  # the stop is not cut short
                    self._stop()
            result = self._summarize(run_dir, bag_path)
            self._plot(result, run_dir)
        except (KeyboardInterrupt, interrupts.Terminated):
            pass  # interrupts.received() has it
        finally:
            with interrupts.held():  # nor the teardown
                self.graph.close()
        with interrupts.held():
            if result is None:  # the signal came before the summary: take what the run held
                result = self._summarize(run_dir, bag_path)
            self._mark_signal(result)
            write_summary(run_dir, result.to_json())
        return result

    def run(self, bag_path: Path | None) -> None:
        """Start and spin to the end (or a failure, a signal); the outcome in status."""
        try:
            self._start(bag_path)
            self._spin()
        except (KeyboardInterrupt, interrupts.Terminated) as exc:
            code = interrupts.exit_code(exc)
            self._end("interrupted", interrupts.SIGNAL_NAMES[code], code)
        except NodeDied as exc:
            self._end("node_died", str(exc), 1)
        except GraphFault as exc:
            self._end("graph_fault", f"the graph published invalid {exc}", 1)
        except (RemoteNodesMissing, ViewersMissing) as exc:
            self._end("timeout", str(exc), 1)

    def _mark_signal(self, result: GraphRun) -> None:
        """A signal that came at any moment (raised or held) makes the exit code its own and,
        unless the run had failed already, the run interrupted."""
        code = interrupts.received()
        if code is None:
            if self.exit_code == 0 and result.status != "complete":
                self.exit_code = 1  # finished, but not well (node errors, timeouts, ...)
            return
        self.exit_code = code
        finished = (
            "complete", "interrupted", "node_errors", "non_finite", "messages_lost",
            "lockstep_timeouts",
        )  # fmt: skip
        if result.status in finished:
            result.complete = False
            result.status, result.detail = "interrupted", interrupts.SIGNAL_NAMES[code]
            result.files = []
        self.status, self.detail = result.status, result.detail

    def _end(self, status: str, detail: str, exit_code: int) -> None:
        self.status, self.detail, self.exit_code = status, detail, exit_code

    def _start(self, bag_path: Path | None) -> None:
        o, graph = self.opts, self.graph
        if bag_path is not None:  # the run's record: only the graph's own per-epoch messages
            self.recorder = graph.add(
                BagRecorder(
                    bag_path, graph_key=self.key, depth=history_depth(self.scenario),
                    clock_lead=2 * self.scenario.dt, **self.common,
                )
            )  # fmt: skip
        if o.processes:
            self._await_remote()
            self.supervisor = self._start_processes()
            graph.supervisor = self.supervisor  # for during_spin hooks (fault-injection tests)
        else:
            for name in ("tracker", "planner", "sim"):
                options = self._node_options(self.params[name])
                self.nodes[name] = graph.add(NODES[name](**options))
        if o.before_spin is not None:
            o.before_spin(graph)

    def _start_processes(self) -> Supervisor:
        """The node processes started here (``nodes``, default all), each its console entry
        point, talking over DDS in the run's domain: on this host only when it runs them all,
        else with the caller's discovery settings (ROS_AUTOMATIC_DISCOVERY_RANGE,
        ROS_STATIC_PEERS), which reach the other hosts. The caller's environment is not changed."""
        o = self.opts
        restartable = o.restartable or tuple(self.scenario.graph.restartable)
        env = dict(os.environ)
        env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
        env["ROS_DOMAIN_ID"] = str(self.domain)
        if not self.remote:
            env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        env[KEY_ENV] = self.key.hex()  # the environment, not a parameter: parameters are readable
        log = lambda text: print(f"activetrack: {text}", file=sys.stderr)  # noqa: E731
        supervisor = Supervisor(env, self.scenario.graph.max_restarts, log=log)
        for name in ("tracker", "planner", "sim"):
            if o.nodes is None or name in o.nodes:
                supervisor.add(f"{name}_node", self.params[name], name in restartable, o.namespace)
        supervisor.start()
        return supervisor

    def _check_started(self) -> None:
        """``--wait-for``: the held sim must start its first epoch within ``wait_timeout``
        seconds of the run's start, and the settling after they joined (ViewersMissing)."""
        if self.sim_started:
            return
        sim = self.nodes.get("sim")
        if sim is not None:
            self.sim_started = sim.hold.state == "started"
        else:  # a node process: its first platform states have reached the evaluator
            self.sim_started = self.evaluator.counters.counts.get("received.PlatformState", 0) > 0
        allowed = self.opts.wait_timeout + SETTLE_S + MATCH_WAIT_S
        if not self.sim_started and time.monotonic() - self.start > allowed:
            raise ViewersMissing(
                f"--wait-for: {self.wait.describe(self.opts.namespace)} did not join within "
                f"{self.opts.wait_timeout:g} s (--wait-timeout); the run did not start"
            )

    def _await_remote(self) -> None:
        """Nodes on other hosts: wait until each has joined the graph (DDS discovery) before
        starting ours, so that a lockstep sim here does not count its command timeout from
        before the planner existed; RemoteNodesMissing after the run's timeout."""
        if not self.remote:
            return
        namespace = self.opts.namespace or "/"
        wanted = {(f"{name}_node", namespace) for name in self.remote}

        def joined() -> bool:
            return wanted <= set(self.evaluator.get_node_names_and_namespaces())

        if not self.graph.spin_until(joined, timeout=self.opts.timeout, step=0.05):
            absent = sorted(wanted - set(self.evaluator.get_node_names_and_namespaces()))
            raise RemoteNodesMissing(
                f"the nodes {[name for name, _ in absent]} of other hosts did not join domain "
                f"{self.domain} within {self.opts.timeout} s (docs/multi-host.md)"
            )

    def _node_options(self, params: dict) -> dict:
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        return {**self.common, "graph_key": self.key, "parameter_overrides": overrides}

    def _finished(self) -> bool:
        interrupts.check()  # a signal whose exception something swallowed still stops the run
        if self.supervisor is not None:
            self.supervisor.poll()
        if self.evaluator.faults:
            raise GraphFault("; ".join(self.evaluator.faults[:3]))
        self._check_started()
        if self.opts.during_spin is not None:
            self.opts.during_spin(self.graph)
        return self.evaluator.complete or self.evaluator.gave_up is not None

    def _spin(self) -> None:
        timeout = self.opts.timeout
        if not self.graph.spin_until(self._finished, timeout=timeout):
            missing = self.evaluator.missing()
            self._end("timeout", f"did not complete within {timeout} s: {missing}", 1)
        else:
            if not self.evaluator.complete:  # messages never sent (nor in any history)
                grace = max(self.evaluator.lost_grace_s, self.evaluator.report_grace_s)
                when = f"given up {grace:g} s after the sim and the tracker finished"
                self._end("messages_lost", f"{self.evaluator.gave_up} ({when})", 1)
            # Let the last messages be recorded and counted: the counters are final
            # (0.1 s without a new message: a burst sent as the last epoch closes, e.g. by a
            # writer outside the graph, is still in flight after a 20 ms lull on a busy host;
            # node processes publish counters that changed REPUBLISH_S after their last epoch,
            # and a message may reach a busy node process a moment after the evaluator here)
            if self.supervisor is None:
                self.graph.spin_until_quiet(self.progress, quiet=0.1)
            else:
                # The supervisor is polled all along: a node that died as the last epoch came
                # in (the runner's poll came before the death) still fails the run at once
                # (it did not end as a complete graph's node), not after these waits.
                quiet = 4 * REPUBLISH_S
                self.graph.spin_until_quiet(self._polled_progress, quiet=quiet, timeout=10 * quiet)
                self._await_counters()
                self.supervisor.poll()

    def _polled_progress(self):
        """:meth:`progress` after a poll of the node processes (NodeDied for a dead one)."""
        assert self.supervisor is not None
        self.supervisor.poll()
        return self.progress()

    def _await_counters(self) -> None:
        """Node processes: until every one's counters came on /diagnostics (a short run can
        end before discovery matched the runner's reader to a node's writer; the node sends
        them again once it sees the reader), at most COUNTERS_WAIT_S; a node whose counters
        never came is counted on the evaluator (``diagnostics_missing.<node>``): its counts
        are then not in the summary."""
        supervisor = self.supervisor
        assert supervisor is not None
        nodes = [n.name.removesuffix("_node") for n in supervisor.nodes]
        have = self.evaluator.diagnostics

        def all_came() -> bool:
            supervisor.poll()  # a dead node sends nothing more: NodeDied now, not after the wait
            return all(n in have for n in nodes)

        self.graph.spin_until(all_came, timeout=COUNTERS_WAIT_S)
        for n in nodes:
            if n not in have:
                self.evaluator.counters.count(f"diagnostics_missing.{n}")

    def _stop(self) -> None:
        """Stop the node processes and close the bag (signals held by the caller)."""
        if self.status != "complete":  # take in what was delivered: a fuller partial run
            try:
                self.graph.spin_until_quiet(self.progress, quiet=0.05, timeout=0.3)
            except Exception as exc:  # an executor left mid-step by the signal: stop anyway
                print(f"activetrack: stopping: {type(exc).__name__}: {exc}", file=sys.stderr)
        if self.supervisor is not None:
            self.supervisor.stop()
        if self.recorder is not None:
            self.recorder.close()

    def diagnostics(self) -> dict:
        """Counters straight from the nodes in one process, else their last /diagnostics."""
        diagnostics = {name: dict(node.counters.counts) for name, node in self.nodes.items()}
        diagnostics = diagnostics or dict(self.evaluator.diagnostics)
        diagnostics["evaluator"] = dict(self.evaluator.counters.counts)
        if self.recorder is not None:
            diagnostics["recorder"] = dict(self.recorder.counters.counts)
        return diagnostics

    def _summarize(self, run_dir: Path, bag_path: Path | None) -> GraphRun:
        """The run's result from what the evaluator holds (the completed epochs of an
        incomplete run), computed with signals held (a partial summary needs it whole)."""
        with interrupts.held():
            code = interrupts.received()
            if code is not None and self.status == "complete":
                self._end("interrupted", interrupts.SIGNAL_NAMES[code], code)
            return self._result(run_dir, bag_path)

    def _result(self, run_dir: Path, bag_path: Path | None) -> GraphRun:
        wall = time.monotonic() - self.start
        scenario, evaluator = self.scenario, self.evaluator
        complete = self.status == "complete"
        last = scenario.steps if complete else evaluator.completed_epochs()
        record = evaluator.record(wall, last) if last >= 1 else None
        summary = None
        if record is not None:  # the epochs run (an interrupted run: the first ones)
            partial = scenario if complete else first_epochs(scenario, last)
            summary = run_summary(partial, record, wall, self.opts.run)
        diagnostics = self.diagnostics()
        result = GraphRun(
            summary=summary,
            run_dir=run_dir,
            bag=bag_path,
            wall_time_s=wall,
            real_time_factor=scenario.dt * max(last, 0) / wall,
            diagnostics=diagnostics,
            complete=complete,
            status=self.status,
            detail=self.detail,
            epochs_completed=max(last, 0),
            foreign={n: _total(c, "foreign.") for n, c in diagnostics.items()},
            restarts=self.supervisor.restarts if self.supervisor is not None else {},
            network=self.network,
            timeouts=epoch_timeouts(diagnostics),
        )
        if self.status == "messages_lost":
            K = scenario.steps
            covered = "all epochs" if last == K else f"epochs 0-{last} of {K}"
            result.detail += f"; the summary covers {covered}"
        _judge(result, lockstep=self.opts.mode == "lockstep")
        return result

    def _plot(self, result: GraphRun, run_dir: Path) -> None:
        """The figures of a complete run (matplotlib: seconds under load, so interruptible:
        a signal here ends the run interrupted, without figures)."""
        if self.opts.plots and result.status == "complete" and result.summary is not None:
            result.files = _plots(self.scenario, result.summary, run_dir)


def run_summary(scenario, record, wall: float, run: int | None) -> BatchSummary:
    """A run's summary with the batch loop's code: its evaluation (each target's error and
    bound, GOSPA, breaks, swaps) drawn from run ``run``'s evaluator generator, as
    ``run_batch`` draws it."""
    evaluation = evaluate_run(scenario, record, component_rngs(scenario.seed, run)[3])
    return summarize(scenario, [record], [evaluation], wall)


def _plots(scenario, summary: BatchSummary, run_dir: Path) -> list:
    """The run folder's figures (matplotlib: 0.7 s of imports, so only here): the run in the
    plane, each target's error against its bound, GOSPA over time."""
    from activetrack.closed_loop.components import scene_sensors
    from activetrack.plots import plot_errors, plot_gospa, plot_run

    sensors = {sid: s for sid, (_, s) in scene_sensors(scenario).items()}
    return [
        plot_run(scenario.name, sensors, summary.records[0], run_dir / "trajectories.png"),
        plot_errors(summary, run_dir / "rmse_vs_bound.png"),
        plot_gospa({"run": summary.evaluations}, run_dir / "gospa.png"),
    ]


def epoch_timeouts(diagnostics: dict) -> dict:
    """The nodes' ``timeout.<k>.<what>`` counters by epoch: what each timeout decided."""
    out: dict = {}
    for node, counts in diagnostics.items():
        for key, n in counts.items():
            parts = key.split(".")
            if len(parts) == 3 and parts[0] == "timeout" and parts[1].isdigit():
                out.setdefault(int(parts[1]), {}).setdefault(node, {})[parts[2]] = n
    return dict(sorted(out.items()))


def _total(counts: dict, prefix: str) -> int:
    return sum(v for k, v in counts.items() if k.startswith(prefix))


def _judge(result: GraphRun, lockstep: bool = True) -> None:
    """A run that completed can still have failed: exceptions in node callbacks, a non-finite
    metric, or, in lockstep, a timeout (what a node decided for lack of a message, e.g. hold
    course: the result is no longer the lockstep one, which the batch loop reproduces; free
    mode promises no such result)."""
    if not result.complete:
        return
    errors = sum(_total(c, "errors.") for c in result.diagnostics.values())
    if errors:
        result.status = "node_errors"
        result.detail = f"{errors} unexpected exceptions in node callbacks (logged, counted)"
    elif result.summary is not None and not _finite_metrics(result.summary):
        result.status = "non_finite"
        result.detail = "a metric is not finite: the track diverged or was corrupted"
    elif lockstep and result.timeouts:
        result.status = "lockstep_timeouts"
        result.detail = describe_timeouts(result.timeouts)


def describe_timeouts(timeouts: dict) -> str:
    """One line: each epoch a timeout decided, with what (``GraphRun.timeouts``)."""
    epochs = [
        f"{k} ({', '.join(f'{node} {what} {n}' for node, d in v.items() for what, n in d.items())})"
        for k, v in timeouts.items()
    ]
    return f"lockstep lost at epoch(s) {'; '.join(epochs)}: the timeouts decided there"


def _finite_metrics(summary: BatchSummary) -> bool:
    """GOSPA must be finite, and so must the RMSE of a target its track always holds (known
    association: a diverged filter shows there); bounds may be NaN only where none is computed
    (nonlinear motion models), never infinite."""
    if not math.isfinite(summary.mean_gospa):
        return False
    if summary.association == "known":
        rmse = (*summary.time_avg_rmse_x, *summary.time_avg_rmse_y)
        if not all(math.isfinite(v) for v in rmse):
            return False
    bounds = (*summary.time_avg_bound_x, *summary.time_avg_bound_y)
    return not any(math.isinf(v) for v in bounds)
