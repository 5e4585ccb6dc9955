"""The beta-cautious planner mode through the ROS node graph (scenarios/vanderhook_cautious.yaml).

The planner node sends waypoint commands with measurement gating, the sim measures only when
told to, the tracker predicts through the epochs without measurements (announced by the platform
states), and the run equals the batch loop bit for bit.
"""

from pathlib import Path

import numpy as np
import pytest
from parity import assert_same_run
from recorded import read_topic

from activetrack.closed_loop.batch import run_batch
from activetrack.scenarios import load_scenario
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from msgs_defs.msg import ManoeuvreCommand, Scan

pytestmark = pytest.mark.ros
SCENARIO = Path(__file__).parents[2] / "scenarios" / "vanderhook_cautious.yaml"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cautious")
    graph = run_graph(SCENARIO, run_dir=tmp / "run", plots=False, timeout=180)
    batch = run_batch(load_scenario(SCENARIO), runs=1)
    return graph, batch


def test_graph_equals_the_batch_run(runs):
    graph, batch = runs
    assert_same_run(graph.summary.records[0], batch.records[0])
    assert graph.summary.to_json()["time_avg_bound_x"] == batch.to_json()["time_avg_bound_x"]
    assert graph.summary.time_avg_rmse_x == batch.time_avg_rmse_x


def test_measurements_follow_the_gated_commands(runs):
    graph, batch = runs
    steps = load_scenario(SCENARIO).steps
    commands = sorted(
        read_topic(graph.bag, topics.MANOEUVRE_COMMANDS, ManoeuvreCommand), key=lambda m: m.epoch
    )
    assert [m.epoch for m in commands] == list(range(steps))
    assert all(m.gate_measurement for m in commands)
    asked = [m.epoch + 1 for m in commands if m.take_measurement]
    measured = read_topic(graph.bag, topics.SCANS, Scan)
    assert sorted(m.epoch for m in measured) == asked
    assert asked == list(np.flatnonzero(batch.records[0].looked[:, 0]) + 1)
    assert 1 <= len(asked) <= 4  # Lemma 4 for this scenario
    assert all(m.sensor_kind == "ambiguous_bearing" and len(m.detections) == 1 for m in measured)
    # Waypoints are where the robot stands when it measures.
    path = graph.summary.records[0].platform_paths[:, 0]
    for m in commands:
        if m.take_measurement:
            assert m.has_waypoint
            np.testing.assert_allclose(
                [m.waypoint.x, m.waypoint.y], path[m.epoch + 1, [0, 2]], atol=1e-9
            )


def test_counters_show_the_gating(runs):
    graph, _ = runs
    steps = load_scenario(SCENARIO).steps
    n = graph.diagnostics["sim"]["scans_published"]
    tracker = graph.diagnostics["tracker"]
    assert tracker["updates"] == steps
    assert tracker["epochs_without_scans"] == steps - n
    assert graph.diagnostics["planner"]["decisions"] == steps
    for node in ("sim", "tracker", "planner"):
        assert not any(k.startswith("rejected.") for k in graph.diagnostics[node])
    assert "command_timeouts" not in graph.diagnostics["sim"]
