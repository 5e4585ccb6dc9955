"""The launch file, checked without launch (``launch``/``launch_ros`` are not on PyPI; the PyPI
package named ``launch`` is unrelated):

- it imports launch APIs only (AST);
- run against stand-ins of those APIs that record every call, it starts each node from an
  executable that is a console script of that package (setup.cfg), and every parameter it passes
  is one the node declares (the nodes are built in-process on a scenario and asked), with the
  node's own default as the argument's default;
- every launch configuration it reads is a declared launch argument, and every option of
  ``activetrack run`` is one of its arguments or named here with the reason it is not;
- setup.cfg installs it into share/activetrack_bringup/launch (data_files).
"""

from __future__ import annotations

import ast
import configparser
import importlib
import sys
import types
from pathlib import Path

import pytest
from setuptools.config.setupcfg import read_configuration

ROOT = Path(__file__).resolve().parents[2]
BRINGUP = ROOT / "src" / "activetrack_bringup"
LAUNCH_FILE = BRINGUP / "launch" / "activetrack.launch.py"
SCENARIO = str(ROOT / "scenarios" / "default.yaml")
ALLOWED_ROOTS = {"launch", "launch_ros"}
# The node classes behind the executables (instantiated to read their parameters).
NODE_CLASSES = {
    "sim_node": "sim_node.sim_node:SimNode",
    "tracker_node": "tracker_node.tracker_node:TrackerNode",
    "planner_node": "planner_node.planner_node:PlannerNode",
    "activetrack_evaluator": "activetrack_bringup.standalone:activetrack_evaluator",
    "activetrack_recorder": "activetrack_bringup.standalone:activetrack_recorder",
}
# Each option of `activetrack run` (argparse dest): the launch arguments that carry it, or why
# launch has none. A new option fails test_every_run_option_is_a_launch_argument until added.
RUN_OPTIONS = {
    "scenario": ("scenario",),
    "namespace": ("namespace",),
    "run": ("run",),
    "mode": ("mode",),
    "rate": ("rate",),
    "filter": ("filter",),
    "wait_for": ("wait_for_subscribers", "wait_for_topic"),
    "no_bag": ("recorder",),
    "json": ("summary",),
}
NOT_IN_LAUNCH = {
    "processes": "launch always starts one process per node",
    "nodes": "launch starts every node; on other hosts, launch there",
    "out": "a run folder is the runner's: bag and summary take their own paths",
    "no_plots": "the PNG plots are drawn by the runner from its summary",
    "timeout": "the runner's wall-clock limit; a launch runs until stopped (exit)",
    "wait_timeout": "the runner's limit of --wait-for; under launch the sim waits until told",
    "foxglove": "the live view is the runner's (foxglove_bridge on a full install)",
    "port": "the live view's",
    "host": "the live view's",
    "foxglove_wait": "the live view's",
}


def _tree() -> ast.Module:
    return ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))


def test_imports_only_launch_apis():
    imported = []
    for node in ast.walk(_tree()):
        if isinstance(node, ast.Import):
            imported += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, "relative import in a launch file"
            imported.append(node.module or "")
        elif isinstance(node, ast.Call) and getattr(node.func, "id", "") == "__import__":
            pytest.fail("dynamic import in the launch file")
    others = [m for m in imported if m.split(".")[0] not in ALLOWED_ROOTS]
    assert imported and not others, f"the launch file imports more than launch APIs: {others}"


class Recorded:
    """A stand-in of a launch class or function: keeps its arguments."""

    api = ""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _FakeModule(types.ModuleType):
    """``launch``/``launch_ros`` (sub)modules whose every attribute is a recording class."""

    def __init__(self, name: str, calls: list):
        super().__init__(name)
        self.__path__: list[str] = []  # a package: submodules import
        self._calls = calls

    def __getattr__(self, attr: str):
        if attr.startswith("__"):
            raise AttributeError(attr)
        calls = self._calls

        def init(obj, *args, **kwargs):
            Recorded.__init__(obj, *args, **kwargs)
            calls.append(obj)

        cls = type(attr, (Recorded,), {"api": f"{self.__name__}.{attr}", "__init__": init})
        setattr(self, attr, cls)
        return cls


@pytest.fixture(scope="module")
def launched():
    """The launch description built against recording stand-ins: every API object made."""
    calls: list[Recorded] = []
    names = {n.module for n in ast.walk(_tree()) if isinstance(n, ast.ImportFrom) and n.module} | {
        a.name for n in ast.walk(_tree()) if isinstance(n, ast.Import) for a in n.names
    }
    fakes = {}
    for name in sorted(names | ALLOWED_ROOTS):
        parts = name.split(".")
        for i in range(1, len(parts) + 1):
            sub = ".".join(parts[:i])
            fakes.setdefault(sub, _FakeModule(sub, calls))
    saved = {k: sys.modules.get(k) for k in fakes}
    sys.modules.update(fakes)
    try:
        namespace: dict = {"__name__": "activetrack_launch", "__file__": str(LAUNCH_FILE)}
        exec(compile(LAUNCH_FILE.read_text(), str(LAUNCH_FILE), "exec"), namespace)
        description = namespace["generate_launch_description"]()
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v
    assert type(description).api == "launch.LaunchDescription"
    return calls


def _made(calls, api: str) -> list[Recorded]:
    return [c for c in calls if c.api == api]


def _console_scripts(package: str) -> dict[str, str]:
    """name -> "module:function" of a package's console scripts (its setup.cfg)."""
    options = read_configuration(BRINGUP.parent / package / "setup.cfg")["options"]
    scripts = options.get("entry_points", {}).get("console_scripts", [])
    return {name.strip(): target.strip() for name, _, target in (s.partition("=") for s in scripts)}


def _nodes(calls) -> list[Recorded]:
    nodes = _made(calls, "launch_ros.actions.Node")
    assert nodes, "the launch file starts no node"
    return nodes


def test_starts_the_graph_the_evaluator_and_the_recorder(launched):
    started = sorted((n.kwargs["package"], n.kwargs["executable"]) for n in _nodes(launched))
    bringup = "activetrack_bringup"
    assert started == sorted(
        (bringup if name.startswith("activetrack_") else name, name) for name in NODE_CLASSES
    )
    optional = {
        n.kwargs["executable"]: n.kwargs["condition"].args[0].args
        for n in _nodes(launched)
        if "condition" in n.kwargs
    }
    assert optional == {"activetrack_evaluator": ("evaluator",),
                        "activetrack_recorder": ("recorder",)}  # fmt: skip


def _arguments(calls) -> dict[str, str | None]:
    """Declared launch argument -> its default (None: required)."""
    return {
        a.args[0]: a.kwargs.get("default_value")
        for a in _made(calls, "launch.actions.DeclareLaunchArgument")
    }


def test_every_run_option_is_a_launch_argument(launched):
    from activetrack_bringup.cli import build_parser

    run = next(
        p for a in build_parser()._subparsers._group_actions for n, p in a.choices.items()
        if n == "run"
    )  # fmt: skip
    options = {a.dest for a in run._actions if a.dest != "help"}
    assert options == set(RUN_OPTIONS) | set(NOT_IN_LAUNCH), "map each run option here"
    assert not set(RUN_OPTIONS) & set(NOT_IN_LAUNCH)
    declared = _arguments(launched)
    carried = {a for names in RUN_OPTIONS.values() for a in names}
    assert carried <= set(declared)
    # ... and each launch argument carries a run option, or a setting of the graph's nodes.
    assert set(declared) - carried == {"frame_id", "exit", "evaluator", "bag"}


def test_exit_ends_the_launch_when_the_run_is_done(launched):
    handlers = _made(launched, "launch.actions.RegisterEventHandler")
    targets = {}
    for h in handlers:
        on_exit = h.args[0]
        assert on_exit.api == "launch.event_handlers.OnProcessExit"
        target = on_exit.kwargs["target_action"].kwargs["executable"]
        (emit,) = on_exit.kwargs["on_exit"]
        assert emit.kwargs["event"].api == "launch.events.Shutdown"
        condition = h.kwargs["condition"].args[0]  # IfCondition(AndSubstitution(exit, when))
        assert condition.api == "launch.substitutions.AndSubstitution"
        targets[target] = condition.args
    exit_arg, when = targets["activetrack_evaluator"]
    assert exit_arg.args == ("exit",) and when.args == ("evaluator",)
    exit_arg, when = targets["sim_node"]
    assert exit_arg.args == ("exit",) and when.api == "launch.substitutions.NotSubstitution"


def test_every_executable_is_a_console_script_of_its_package(launched):
    for node in _nodes(launched):
        package, executable = node.kwargs["package"], node.kwargs["executable"]
        scripts = _console_scripts(package)
        assert executable in scripts, f"{package} has no console script {executable}"
        module, _, function = scripts[executable].partition(":")
        assert callable(getattr(importlib.import_module(module), function))
        # ros2 run/launch look for it in lib/<package> (setup.cfg's script_dir)
        cfg = configparser.ConfigParser()
        cfg.read(BRINGUP.parent / package / "setup.cfg")
        assert cfg.get("install", "install_scripts") == f"$base/lib/{package}"


def test_namespace_and_launch_arguments(launched):
    declared = {a.args[0] for a in _made(launched, "launch.actions.DeclareLaunchArgument")}
    assert {"scenario", "namespace", "run", "mode"} <= declared
    read = {c.args[0] for c in _made(launched, "launch.substitutions.LaunchConfiguration")}
    assert read <= declared, f"launch configurations never declared: {read - declared}"
    for node in _nodes(launched):
        ns = node.kwargs.get("namespace")
        assert ns is not None and ns.args == ("namespace",)


@pytest.fixture(scope="module")
def declared_parameters(tmp_path_factory):
    """The parameters each node declares, asked from the nodes themselves on a scenario."""
    pytest.importorskip("rclpy", reason="needs the workspace venv (make setup)")
    from rclpy.parameter import Parameter

    from activetrack_bringup.inprocess import InProcessGraph

    out = {}
    bag = tmp_path_factory.mktemp("launch") / "bag"
    with InProcessGraph() as graph:
        for package, target in NODE_CLASSES.items():
            module, _, cls = target.partition(":")
            node_class = getattr(importlib.import_module(module), cls)
            given = (
                ("bag", str(bag)) if package == "activetrack_recorder" else ("scenario", SCENARIO)
            )
            node = graph.add(
                node_class(
                    context=graph.context,
                    parameter_overrides=[Parameter(given[0], value=given[1])],
                    start_parameter_services=False,
                )
            )
            out[package] = {n: p.value for n, p in node._parameters.items()}
    return out


def test_every_parameter_is_declared_by_its_node(launched, declared_parameters):
    defaults = _arguments(launched)
    for node in _nodes(launched):
        name = node.kwargs["executable"]
        passed = {}
        for entry in node.kwargs.get("parameters", []):
            assert isinstance(entry, dict), f"{name}: parameters given other than by name"
            passed |= entry
        assert name == "activetrack_recorder" or {"scenario", "run"} <= set(passed)
        unknown = set(passed) - set(declared_parameters[name])
        assert not unknown, f"{name} declares no parameter {unknown}"
        # A launch argument's default is the node's (scenario and bag: required).
        for param, value in passed.items():
            if not hasattr(value, "args"):
                continue  # a literal the launch file sets, not a launch argument
            typed = _perform(value, defaults)
            if typed is None or param == "bag" or value.args[0].api.endswith("Expression"):
                continue  # a required argument, or one computed from several
            assert typed == declared_parameters[name][param], (name, param)


def _perform(value, arguments: dict):
    """A recorded ParameterValue evaluated as launch would, given the arguments' values (None
    if a required one has none): LaunchConfiguration, AndSubstitution, NotSubstitution,
    PythonExpression; a literal (no ParameterValue) as it is."""
    if not hasattr(value, "args"):
        return value

    def text(sub) -> str | None:
        kind = sub.api.rsplit(".", 1)[1]
        if kind == "LaunchConfiguration":
            return arguments[sub.args[0]]
        if kind == "PythonExpression":  # launch evaluates the concatenated text
            return str(eval("".join(p if isinstance(p, str) else text(p) for p in sub.args[0])))
        parts = [text(a) for a in sub.args]
        if None in parts:
            return None
        truth = [{"true": True, "false": False}[p] for p in parts]
        return str(all(truth) if kind == "AndSubstitution" else not truth[0]).lower()

    (sub,) = value.args
    raw, value_type = text(sub), value.kwargs["value_type"]
    if raw is None:
        return None
    return {"true": True, "false": False}[raw] if value_type is bool else value_type(raw)


def test_run_rate_range_is_the_sims(declared_parameters):
    from activetrack_bringup.cli_types import SIM_RATE_RANGE
    from sim_node.sim_node import PARAMS

    rate = next(p for p in PARAMS if p.name == "rate")
    assert SIM_RATE_RANGE == (rate.low, rate.high)


def test_setup_installs_the_launch_file():
    data_files = read_configuration(BRINGUP / "setup.cfg")["options"]["data_files"]
    installed = {(target, source) for target, sources in data_files for source in sources}
    for path in sorted((BRINGUP / "launch").glob("*.launch.py")):
        rel = str(path.relative_to(BRINGUP))
        assert ("share/activetrack_bringup/launch", rel) in installed, f"{rel} is not installed"
        assert path.is_file()


@pytest.mark.ros
@pytest.mark.slow
def test_the_launch_description_runs_the_graph_evaluator_and_recorder(launched, tmp_path):
    """What ros2 launch would start, started here from the recorded description (each node's
    parameters as a params file, as launch_ros passes them), in a namespace with exit:=true: the
    evaluator writes the summary of the whole run, equal to activetrack batch, and exits; the
    recorder's bag holds the run from sim time 0."""
    import json
    import os
    import signal
    import subprocess

    import yaml

    from activetrack.closed_loop.batch import run_batch
    from activetrack.scenarios import load_scenario
    from activetrack_bringup.bag import bag_info
    from activetrack_ros.trust import GraphKey

    scenario = str(ROOT / "tests" / "ros" / "data" / "short_two_sensors.yaml")
    given = {"scenario": scenario, "namespace": "l27", "exit": "true",
             "summary": str(tmp_path / "summary.json"), "bag": str(tmp_path / "bag")}  # fmt: skip
    values = {**_arguments(launched), **given}
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ACTIVETRACK_GRAPH_KEY"] = GraphKey.generate().hex()
    procs = {}
    logs = {}
    try:
        for node in _nodes(launched):
            name = node.kwargs["executable"]
            logs[name] = open(tmp_path / f"{name}.log", "w")
            params = {}
            for entry in node.kwargs["parameters"]:
                params |= {param: _perform(value, values) for param, value in entry.items()}
            path = tmp_path / f"{name}.yaml"
            path.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}))
            exe = Path(sys.executable).parent / name
            procs[name] = subprocess.Popen(
                [str(exe), "--ros-args", "-r", f"__ns:=/{values['namespace']}",
                 "--params-file", str(path)],
                env=env, stdout=subprocess.DEVNULL, stderr=logs[name], text=True,
            )  # fmt: skip
        evaluator = procs["activetrack_evaluator"]
        assert evaluator.wait(timeout=120) == 0, (
            tmp_path / "activetrack_evaluator.log"
        ).read_text()
        assert procs["sim_node"].poll() is None  # with an evaluator, the sim waits for Shutdown
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)  # what launch's Shutdown sends
        for proc in procs.values():
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
    summary = json.loads((tmp_path / "summary.json").read_text())
    batch = run_batch(load_scenario(scenario)).to_json()
    for key in (
        "time_avg_rmse_x",
        "time_avg_rmse_y",
        "time_avg_bound_x",
        "time_avg_bound_y",
        "rmse_x_t",
        "rmse_y_t",
        "mean_gospa",
    ):
        assert summary[key] == batch[key], key
    info = bag_info(tmp_path / "bag")
    assert info["intact"] and info["duration_s"] == 40.0
    assert info["topics"]["/l27/activetrack/platform_states"]["count"] == 2 * 9
