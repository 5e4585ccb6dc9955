"""The core library never imports rclpy (it must work where ROS is not installed), nor the
experiments package, which is a client of the core (and may be absent)."""

import ast
import subprocess
import sys
from pathlib import Path

CORE = Path(__file__).resolve().parents[1] / "src" / "activetrack" / "activetrack"
ROS_MODULES = {"rclpy", "rosidl_runtime_py", "msgs_defs", "std_msgs", "geometry_msgs"}
# The layers above the core: the experiments, the ROS side and the nodes.
FORBIDDEN = ROS_MODULES | {
    "activetrack_experiments",
    "activetrack_ros",
    "activetrack_bringup",
    "sim_node",
    "tracker_node",
    "planner_node",
}


def test_no_ros_or_experiment_import_in_core_sources():
    offenders = []
    for path in CORE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            offenders += [f"{path.name}: {n}" for n in names if n.split(".")[0] in FORBIDDEN]
    assert not offenders


def test_core_imports_with_rclpy_unimportable():
    # rclpy is made unimportable (a None entry in sys.modules raises ImportError on import),
    # then every module of the core is imported.
    code = (
        "import sys, pkgutil, importlib\n"
        "for m in ('rclpy', 'msgs_defs', 'activetrack_experiments'): sys.modules[m] = None\n"
        "import activetrack\n"
        "mods = [m.name for m in pkgutil.walk_packages(activetrack.__path__, 'activetrack.')]\n"
        "for m in mods: importlib.import_module(m)\n"
        "print(len(mods))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout.strip()) >= 1
