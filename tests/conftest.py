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
