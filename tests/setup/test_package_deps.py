"""Every package declares what it imports, where the tools read it.

- ``package.xml`` (rosdep, colcon, bloom): each import of a package's Python files is an
  ``<exec_depend>`` with its rosdep key, or, when the module has no rosdep key, named in the
  package's ``<!-- pip-only: ... -->`` comment; a declared dependency that nothing imports fails
  too (unless listed in ``UNUSED_OK`` with the reason).
- ``pyproject.toml`` ``[project] dependencies`` / ``setup.cfg`` ``install_requires`` (pip): exactly
  the Python distributions that the runtime modules import (no test tools, no ROS packages,
  which rosdep installs), without versions: every version is pinned in ``constraints.txt`` (the
  one place) and every distribution is named in ``requirements.txt`` (what ``make setup``
  installs).

Imports are read with ``ast`` (top-level module names; the standard library, the package itself
and relative imports left out), including ``importlib.import_module("name...")`` with a literal
start and message type names such as ``"geometry_msgs/msg/PoseArray"`` (loaded by name).
A new third-party import fails here until the tables below say what it is.
"""

from __future__ import annotations

import ast
import re
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from setuptools.config.setupcfg import read_configuration

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
# The workspace's Python packages (msgs_defs is an ament_cmake interface package: no Python).
PACKAGES = (
    "activetrack",
    "activetrack_experiments",
    "activetrack_ros",
    "sim_node",
    "tracker_node",
    "planner_node",
    "activetrack_bringup",
)
# import name -> PyPI distribution, for the workspace's own Python packages.
OWN = {
    "activetrack": "activetrack",
    "activetrack_experiments": "activetrack-experiments",
    "activetrack_ros": "activetrack_ros",
    "sim_node": "sim_node",
    "tracker_node": "tracker_node",
    "planner_node": "planner_node",
    "activetrack_bringup": "activetrack_bringup",
    "msgs_defs": None,  # a ROS interface package, not a pip requirement
}
# ROS packages: the rosdep key is the package name; rosdep installs them, never pip.
ROS = {
    "rclpy",
    "launch",
    "launch_ros",
    "ament_index_python",
    "builtin_interfaces",
    "std_msgs",
    "geometry_msgs",
    "nav_msgs",
    "sensor_msgs",
    "rosgraph_msgs",
    "diagnostic_msgs",
    "visualization_msgs",
    "tf2_msgs",
    "rcl_interfaces",
    "lifecycle_msgs",
}
# import name -> (rosdep key, PyPI distribution) for third-party Python modules with a key.
KEYED = {
    "numpy": ("python3-numpy", "numpy"),
    "scipy": ("python3-scipy", "scipy"),
    "yaml": ("python3-yaml", "pyyaml"),
    "matplotlib": ("python3-matplotlib", "matplotlib"),
    "pydantic": ("python3-pydantic", "pydantic"),
    "pydantic_core": ("python3-pydantic", "pydantic"),  # pydantic's own core, comes with it
    "tqdm": ("python3-tqdm", "tqdm"),
    "numba": ("python3-numba", "numba"),
}
# import name -> PyPI distribution, for modules rosdep has no key for (the pip-only comment).
PIP_ONLY = {
    "rosbags": "rosbags",
    "mcap": "mcap",
    "lz4": "lz4",
    "zstandard": "zstandard",
    "foxglove": "foxglove-sdk",
    "filterpy": "filterpy",
    "distributed": "distributed",  # Dask's cluster client (activetrack.montecarlo.dask)
    "dask": "dask",  # its configuration (activetrack.montecarlo.dask)
    "llvmlite": "llvmlite",  # numba's LLVM binding (activetrack.kernels.pcg64's intrinsic)
}
# Bench-only modules (requirements-bench.txt), imported lazily and only when installed: no
# package declares them. import name -> PyPI distribution.
BENCH_ONLY = {
    "stonesoup": "stonesoup",  # Stone Soup's sensor manager (activetrack_experiments)
}
# Declared but not imported, on purpose: (package, rosdep key or pip name) -> why.
# Each node is an rclpy node (its class derives from rclpy's Node through activetrack_ros):
# ROS tools and reviewers expect rclpy among a node package's dependencies.
UNUSED_OK: dict[tuple[str, str], str] = {
    (node, "rclpy"): "an rclpy node through activetrack_ros.node_base"
    for node in ("sim_node", "tracker_node", "planner_node")
}

MSG_TYPE = re.compile(r"^([a-z][a-z0-9_]*)/msg/[A-Za-z0-9_]+$")
PIP_COMMENT = re.compile(r"^\s*pip-only:\s*([^()]*)")


def _dynamic_module(node: ast.Call) -> str | None:
    """The module of ``importlib.import_module("a.b")`` / ``import_module(f"a.{x}")``."""
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if name != "import_module" or not node.args:
        return None
    arg = node.args[0]
    if isinstance(arg, ast.JoinedStr) and arg.values:
        arg = arg.values[0]
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        head = arg.value.split(".")[0]
        return head if head and head.isidentifier() and not head.startswith("_") else None
    return None


def _modules(tree: ast.AST) -> set[str]:
    """Top-level names of the modules a source imports or loads by name."""
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module.split(".")[0])
        elif isinstance(node, ast.Call) and (mod := _dynamic_module(node)):
            found.add(mod)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            if m := MSG_TYPE.match(node.value):
                found.add(m.group(1))
    return found


def package_imports(package: str) -> dict[str, list[str]]:
    """Third-party and workspace modules of a package's installed Python files (not setup.py):
    module -> the files that use it."""
    base = SRC / package
    uses: dict[str, list[str]] = {}
    for path in sorted(base.rglob("*.py")):
        rel = path.relative_to(base)
        if rel == Path("setup.py") or rel.parts[0] in ("build", "test", "tests"):
            continue
        for mod in _modules(ast.parse(path.read_text(), filename=str(path))):
            if mod in sys.stdlib_module_names or mod == package or mod == "__future__":
                continue
            uses.setdefault(mod, []).append(str(rel))
    return uses


def runtime_imports(package: str) -> dict[str, list[str]]:
    """The imports of the Python package itself (what pip installs), not of launch files."""
    return {
        mod: files
        for mod, files in package_imports(package).items()
        if any(Path(f).parts[0] == package for f in files)
    }


def package_xml(package: str) -> tuple[set[str], set[str]]:
    """(exec_depend and depend keys, pip-only names of the comment) of a package.xml."""
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    root = ET.parse(SRC / package / "package.xml", parser).getroot()
    keys = {e.text.strip() for e in root if e.tag in ("exec_depend", "depend") and e.text}
    pip: set[str] = set()
    for e in root.iter():
        if e.tag is ET.Comment and (m := PIP_COMMENT.match(e.text or "")):
            pip |= {n.strip() for n in m.group(1).replace(";", ",").split(",") if n.strip()}
    return keys, pip


def _requirement_name(req: str) -> str:
    return re.split(r"[\s<>=!~;\[(]", req.strip(), maxsplit=1)[0]


def normalize(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def requirements(package: str) -> tuple[list[str], dict[str, list[str]]]:
    """(runtime requirements, extras) as written in the package's pyproject.toml or setup.cfg."""
    pyproject = SRC / package / "pyproject.toml"
    if pyproject.exists():
        project = tomllib.loads(pyproject.read_text()).get("project", {})
        if "dependencies" in project:
            return project["dependencies"], project.get("optional-dependencies", {})
    options = read_configuration(SRC / package / "setup.cfg")["options"]
    return options.get("install_requires", []), options.get("extras_require", {})


def _pins() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            pins[normalize(name)] = version.strip()
    return pins


def _required_by_workspace() -> set[str]:
    lines = (ROOT / "requirements.txt").read_text().splitlines()
    return {normalize(_requirement_name(x)) for x in lines if x.split("#")[0].strip()}


def rosdep_key(module: str) -> str | None:
    if module in ROS or module in OWN:
        return module
    return KEYED[module][0] if module in KEYED else None


def distribution(module: str) -> str | None:
    """The pip requirement a runtime import of ``module`` needs (None: a ROS package)."""
    if module in OWN:
        return OWN[module]
    if module in KEYED:
        return KEYED[module][1]
    return PIP_ONLY.get(module)


@pytest.mark.parametrize("package", PACKAGES)
def test_every_import_is_known(package):
    known = ROS | set(OWN) | set(KEYED) | set(PIP_ONLY) | set(BENCH_ONLY)
    unknown = {m: f for m, f in package_imports(package).items() if m not in known}
    assert not unknown, f"{package}: add these modules to the tables of this test: {unknown}"


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_declares_every_import(package):
    keys, pip = package_xml(package)
    missing, missing_pip = {}, {}
    for mod, files in package_imports(package).items():
        key = rosdep_key(mod)
        if key is not None and key not in keys:
            missing[key] = files
        elif key is None and mod in PIP_ONLY and PIP_ONLY[mod] not in pip:
            missing_pip[PIP_ONLY[mod]] = files
    assert not missing, f"{package}/package.xml lacks <exec_depend> for {missing}"
    assert not missing_pip, f"{package}/package.xml: name in its pip-only comment {missing_pip}"


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_declares_nothing_unused(package):
    keys, pip = package_xml(package)
    uses = package_imports(package)
    used_keys = {rosdep_key(m) for m in uses} - {None}
    used_pip = {PIP_ONLY[m] for m in uses if m in PIP_ONLY}
    unused = {k for k in keys - used_keys if (package, k) not in UNUSED_OK}
    unused_pip = {n for n in pip - used_pip if (package, n) not in UNUSED_OK}
    assert not unused, f"{package}/package.xml: <exec_depend> nothing imports: {sorted(unused)}"
    assert not unused_pip, f"{package}/package.xml: pip-only names not imported: {unused_pip}"


@pytest.mark.parametrize("package", PACKAGES)
def test_runtime_requirements_are_what_the_modules_import(package):
    declared, _ = requirements(package)
    names = {normalize(_requirement_name(r)) for r in declared}
    needed: dict[str, list[str]] = {}
    for mod, files in runtime_imports(package).items():
        if (dist := distribution(mod)) is not None:
            needed.setdefault(normalize(dist), []).extend(files)
    missing = {d: f for d, f in needed.items() if d not in names}
    assert not missing, f"{package}: runtime requirements lack {missing}"
    extra = names - set(needed)
    assert not extra, f"{package}: runtime requirements that no runtime module imports: {extra}"


@pytest.mark.parametrize("package", PACKAGES)
def test_versions_are_pinned_in_constraints_only(package):
    runtime, extras = requirements(package)
    reqs = [*runtime, *(r for group in extras.values() for r in group)]
    versioned = [r for r in reqs if normalize(_requirement_name(r)) != normalize(r.strip())]
    assert not versioned, f"{package}: versions belong in constraints.txt, not here: {versioned}"
    _, pip = package_xml(package)
    own = {normalize(d) for d in OWN.values() if d}
    third_party = {normalize(_requirement_name(r)) for r in reqs} | {normalize(n) for n in pip}
    third_party -= own
    pins, wanted = _pins(), _required_by_workspace()
    unpinned, unlisted = third_party - pins.keys(), third_party - wanted
    assert not unpinned, f"{package}: not pinned in constraints.txt: {unpinned}"
    assert not unlisted, f"{package}: not in requirements.txt: {unlisted}"


@pytest.mark.parametrize("package", PACKAGES)
def test_test_tools_are_test_extras(package):
    runtime, extras = requirements(package)
    names = {normalize(_requirement_name(r)) for r in runtime}
    assert not names & {"pytest", "hypothesis", "mypy", "mcap-ros2-support", "websockets"}
    assert "pytest" in {normalize(_requirement_name(r)) for r in extras.get("test", [])}


def test_bench_only_modules_are_bench_requirements():
    bench = (ROOT / "requirements-bench.txt").read_text().splitlines()
    names = {normalize(_requirement_name(x)) for x in bench if x.split("#")[0].strip()}
    assert {normalize(d) for d in BENCH_ONLY.values()} <= names
    assert not {normalize(d) for d in BENCH_ONLY.values()} & _required_by_workspace()


def test_the_tables_know_rosdep_keys_not_pip_names():
    # A key here must be a rosdep key, a pip-only name must not have one.
    assert all(key.startswith("python3-") for key, _ in KEYED.values())
    assert not set(PIP_ONLY) & (set(KEYED) | ROS)


def test_imports_are_found(tmp_path):
    # The reader itself: static, lazy and dynamic imports and message type names.
    tree = ast.parse(
        "import numpy.linalg\n"
        "from yaml import safe_load\n"
        "from . import sibling\n"
        "def f():\n"
        "    import tqdm\n"
        "    importlib.import_module(f'activetrack_experiments.{name}')\n"
        "    importlib.import_module(f'{package}.msg')\n"
        "TYPES = {'t': 'geometry_msgs/msg/PoseArray', 'doc': 'not geometry_msgs/msg/X here'}\n"
    )
    assert _modules(tree) == {
        "numpy",
        "yaml",
        "tqdm",
        "activetrack_experiments",
        "geometry_msgs",
    }


def test_test_tooling_stays_out_of_the_shipped_packages():
    """Foreign traffic and message examples are test tooling users do not run: they live in
    tests/tools (tests and benchmarks import them from there), not in an installed package."""
    tools = {"adversary", "message_examples", "examples"}
    shipped = sorted(str(p.relative_to(SRC)) for p in SRC.rglob("*.py") if p.stem in tools)
    assert not shipped, f"test tooling in the shipped packages: {shipped}"
    assert {p.stem for p in (SRC.parent / "tests" / "tools").glob("*.py")} >= tools - {"examples"}
