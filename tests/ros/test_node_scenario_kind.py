"""Each node executable runs one kind of scenario: a multi-target one (``targets:``) on the
``multi_*_node`` executables, a single-target one on the others. Given the other kind, a node
fails at once with one line naming the executable to use (exit 2), never a wrong run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MULTI = ROOT / "scenarios" / "mt_bearings_crossing.yaml"
SINGLE = ROOT / "scenarios" / "default.yaml"


def _start(exe: str, scenario: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(Path(sys.executable).parent / exe), "--ros-args", "-p", f"scenario:={scenario}"],
        capture_output=True,
        text=True,
        timeout=60,
    )


@pytest.mark.parametrize("node", ["sim_node", "tracker_node", "planner_node"])
def test_a_single_target_node_names_the_multitarget_one(node):
    proc = _start(node, MULTI)
    assert proc.returncode == 2, proc.stderr
    assert "is multi-target (targets:): run it with multi_" + node in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("node", ["multi_sim_node", "multi_tracker_node", "multi_planner_node"])
def test_a_multitarget_node_names_the_single_target_one(node):
    proc = _start(node, SINGLE)
    assert proc.returncode == 2, proc.stderr
    assert "is single-target: run it with " + node.removeprefix("multi_") in proc.stderr
    assert "Traceback" not in proc.stderr
