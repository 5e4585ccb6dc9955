"""One set of node executables serves every scenario: a multi-target one (``targets:``, clutter,
beams) and a single-target one alike; the former ``multi_*_node`` twins are gone. A node that
cannot load its scenario fails at once with one line (exit 2), never a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from rclpy.parameter import Parameter

from activetrack.planning.across_targets import MultiTargetPlanner
from activetrack.scenarios import load_scenario
from planner_node.planner_node import PlannerNode
from sim_node.sim_node import SimNode
from tracker_node.tracker_node import TrackerNode

ROOT = Path(__file__).resolve().parents[2]
MULTI = ROOT / "scenarios" / "mt_bearings_crossing.yaml"
SINGLE = ROOT / "scenarios" / "default.yaml"
NODES = ("sim_node", "tracker_node", "planner_node")
BIN = Path(sys.executable).parent


def _start(exe: str, *params: str, timeout: float = 120) -> subprocess.CompletedProcess:
    args = [str(BIN / exe), "--ros-args"]
    for p in params:
        args += ["-p", p]
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout)


def test_only_the_three_node_executables_exist():
    for node in NODES:
        assert (BIN / node).exists(), node
        assert not (BIN / f"multi_{node}").exists(), node
        setup = (ROOT / "src" / node / "setup.cfg").read_text()
        assert f"{node} = {node}.{node}:main" in setup and "multi_" not in setup


@pytest.mark.parametrize("scenario", [SINGLE, MULTI], ids=["single", "multi"])
def test_the_sim_executable_runs_either_kind_to_its_end(scenario):
    """Alone (nobody commands), the sim holds course after each timeout and runs every epoch."""
    proc = _start(
        "sim_node",
        f"scenario:={scenario}",
        "command_timeout:=0.001",
        "exit_when_done:=true",
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    assert f"scenario {load_scenario(scenario).name} finished" in proc.stderr + proc.stdout


@pytest.mark.parametrize("node", NODES)
def test_a_node_without_a_loadable_scenario_exits_2_with_one_line(node, tmp_path):
    proc = _start(node, f"scenario:={tmp_path / 'none.yaml'}", timeout=60)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "error:" in lines[0] and "none.yaml" in lines[0], lines
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("scenario", [SINGLE, MULTI], ids=["single", "multi"])
def test_in_process_nodes_build_the_scenarios_components(scenario, graph):
    """The tracker node associates as the scenario says (known association for one target
    without clutter, JPDA otherwise), the planner plans across targets with beams for a
    multi-target scene, and the sim simulates every target."""
    params = [Parameter("scenario", value=str(scenario))]
    kw = {"context": graph.context, "parameter_overrides": params}
    sim = graph.add(SimNode(**kw))
    tracker = graph.add(TrackerNode(**kw))
    planner = graph.add(PlannerNode(**kw))
    multi = scenario == MULTI
    assert len(sim.sim.truth_set().ids) == (3 if multi else 1)
    assert sim.sim.steerable_ids == (("s1", "s2") if multi else ())
    assert tracker.core.known_association is not multi
    assert any(isinstance(s, MultiTargetPlanner) for s in planner.core.strategies) is multi
    assert len(tracker.core.snapshot().tracks) == (3 if multi else 1)
