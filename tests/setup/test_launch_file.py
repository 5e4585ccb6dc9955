"""The launch file, checked without launch (``launch``/``launch_ros`` are not on PyPI; the PyPI
package named ``launch`` is unrelated):

- it imports launch APIs only (AST);
- run against stand-ins of those APIs that record every call, it starts each node from an
  executable that is a console script of that package (setup.py), and every parameter it passes
  is one the node declares (the nodes are built in-process on a scenario and asked);
- every launch configuration it reads is a declared launch argument;
- setup.py installs it into share/activetrack_bringup/launch (data_files).
"""

from __future__ import annotations

import ast
import configparser
import importlib
import sys
import types
from pathlib import Path

import pytest

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
    """name -> "module:function" of a package's console scripts (setup.py and setup.cfg)."""
    scripts: dict[str, str] = {}
    setup = BRINGUP.parent / package / "setup.py"
    for node in ast.walk(ast.parse(setup.read_text())):
        if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "setup":
            for kw in node.keywords:
                if kw.arg == "entry_points":
                    for line in ast.literal_eval(kw.value).get("console_scripts", []):
                        name, _, target = line.partition("=")
                        scripts[name.strip()] = target.strip()
    cfg = configparser.ConfigParser()
    cfg.read(BRINGUP.parent / package / "setup.cfg")
    if cfg.has_option("options.entry_points", "console_scripts"):
        for line in cfg.get("options.entry_points", "console_scripts").splitlines():
            if "=" in line:
                name, _, target = line.partition("=")
                scripts[name.strip()] = target.strip()
    return scripts


def _nodes(calls) -> list[Recorded]:
    nodes = _made(calls, "launch_ros.actions.Node")
    assert nodes, "the launch file starts no node"
    return nodes


def test_starts_the_three_nodes(launched):
    started = sorted((n.kwargs["package"], n.kwargs["executable"]) for n in _nodes(launched))
    assert started == sorted((p, p) for p in NODE_CLASSES)


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
def declared_parameters():
    """The parameters each node declares, asked from the nodes themselves on a scenario."""
    pytest.importorskip("rclpy", reason="needs the workspace venv (make setup)")
    from rclpy.parameter import Parameter

    from activetrack_bringup.inprocess import InProcessGraph

    out = {}
    with InProcessGraph() as graph:
        for package, target in NODE_CLASSES.items():
            module, _, cls = target.partition(":")
            node_class = getattr(importlib.import_module(module), cls)
            node = graph.add(
                node_class(
                    context=graph.context,
                    parameter_overrides=[Parameter("scenario", value=SCENARIO)],
                    start_parameter_services=False,
                )
            )
            out[package] = set(node._parameters)
    return out


def test_every_parameter_is_declared_by_its_node(launched, declared_parameters):
    for node in _nodes(launched):
        package = node.kwargs["package"]
        passed = set()
        for entry in node.kwargs.get("parameters", []):
            assert isinstance(entry, dict), f"{package}: parameters given other than by name"
            passed |= set(entry)
        assert {"scenario", "run"} <= passed
        unknown = passed - declared_parameters[package]
        assert not unknown, f"{package} declares no parameter {unknown}"


def test_setup_installs_the_launch_file():
    tree = ast.parse((BRINGUP / "setup.py").read_text())
    constants = {  # module-level NAME = "literal" (package_name)
        n.targets[0].id: ast.literal_eval(n.value)
        for n in tree.body
        if isinstance(n, ast.Assign)
        and isinstance(n.targets[0], ast.Name)
        and isinstance(n.value, ast.Constant)
    }
    data_files = None
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "setup":
            for kw in node.keywords:
                if kw.arg == "data_files":
                    data_files = kw.value
    assert data_files is not None, "setup.py has no data_files"

    def text(expr: ast.expr) -> str:  # "share/" + package_name + "/launch"
        if isinstance(expr, ast.BinOp) and isinstance(expr.op, ast.Add):
            return text(expr.left) + text(expr.right)
        return constants[expr.id] if isinstance(expr, ast.Name) else ast.literal_eval(expr)

    installed = {
        (text(entry.elts[0]), text(source))
        for entry in data_files.elts
        for source in entry.elts[1].elts
    }
    for path in sorted((BRINGUP / "launch").glob("*.launch.py")):
        rel = str(path.relative_to(BRINGUP))
        assert ("share/activetrack_bringup/launch", rel) in installed, f"{rel} is not installed"
        assert path.is_file()
