"""Test-wide settings: ROS isolation for every test in this run.

ROS tests run in one process each with their own rclpy.Context. Discovery is switched off
(ROS_AUTOMATIC_DISCOVERY_RANGE=OFF: same-process traffic only), so nothing from other
processes on the machine reaches them, and a domain id derived from the pid separates
concurrent test runs (and the workers of one) should a test switch discovery back on for
child processes.
"""

import os
import sys
from pathlib import Path

import pytest

from activetrack.allocator import tune_allocator

# Test tooling that users do not run (foreign traffic, message examples): importable by every
# test (``import adversary``) and run as scripts by the ones that need another process.
TOOLS = Path(__file__).parent / "tools"
sys.path.insert(0, str(TOOLS))

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "OFF"
tune_allocator()  # as the command line does: the suite runs 4x less system time
# One domain per test process: under pytest-xdist (make test: two workers) the controller's
# pid plus the worker's index, so that the workers of one run never share a domain.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
if _WORKER.startswith("gw"):
    _RUN_PID, _INDEX = os.getppid(), int(_WORKER[2:])
else:
    _RUN_PID, _INDEX = os.getpid(), 0
os.environ["ROS_DOMAIN_ID"] = str(100 + (_RUN_PID + _INDEX) % 100)

# The heaviest files first (CPU seconds of each alone, measured 2026-11-27, in brackets):
# under `--dist loadfile` a worker takes the next file when it frees, so a long file taken
# last leaves the other worker idle until it ends. The rest keep their order.
HEAVY_FIRST = (
    "core/test_multitarget_reproduction_e.py",  # 123
    "core/test_ramdaras_closed_loop.py",  # 95
    "core/test_multitarget_reproduction_a.py",  # 88
    "core/test_multitarget_reproduction_b.py",  # 67
    "ros/test_supervision.py",  # 63
    "ros/test_graph_flood.py",  # 38
    "ros/test_ros_tools.py",  # 34
    "test_type_check.py",  # 34
    "test_api_doc.py",  # 29
    "core/test_multitarget_reproduction_d.py",  # 28
    "core/test_multitarget_reproduction_c.py",  # 27
)


def pytest_collection_modifyitems(config, items):
    here = Path(__file__).parent
    gone = [name for name in HEAVY_FIRST if not (here / name).is_file()]
    if gone:  # renamed or removed: the order would silently stop working
        raise pytest.UsageError(f"tests/conftest.py HEAVY_FIRST names no file: {gone}")
    rank = {name: i for i, name in enumerate(HEAVY_FIRST)}

    def first(item) -> int:
        return rank.get(Path(str(item.path)).relative_to(here).as_posix(), len(rank))

    items.sort(key=first)
