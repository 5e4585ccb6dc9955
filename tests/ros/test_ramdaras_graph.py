"""Ramdaras MRE positioning and selection through the ROS node graph (docs/ramdaras.md).

Short Pd < 1 cases (15 epochs) in lockstep: the planner node publishes the selection, the sim
node measures with the selected sensor only, the tracker's EKF skips missed detections, and the
run equals the batch loop bit for bit.
"""

import numpy as np
import pytest
import yaml
from parity import assert_same_run
from recorded import read_topic

from activetrack.closed_loop.batch import run_batch
from activetrack.scenarios import load_scenario
from activetrack_bringup.runner import run_graph
from activetrack_experiments.ramdaras import load_case, variant
from activetrack_ros import graph as topics
from msgs_defs.msg import Scan, SensorSelection

pytestmark = pytest.mark.ros
STEPS = 15


def _scenario_file(tmp_path, case):
    scenario = variant(load_case(case), "mre", steps=STEPS)
    path = tmp_path / f"{case}_short.yaml"
    path.write_text(yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False))
    return path


@pytest.fixture(scope="module", params=["case3_pd", "case2_pd"])
def runs(request, tmp_path_factory):
    tmp = tmp_path_factory.mktemp(request.param)
    path = _scenario_file(tmp, request.param)
    graph = run_graph(path, run_dir=tmp / "run", plots=False, timeout=120)
    batch = run_batch(load_scenario(path), runs=1)
    return request.param, graph, batch


def test_graph_equals_the_batch_run(runs):
    _, graph, batch = runs
    assert_same_run(graph.summary.records[0], batch.records[0])
    assert graph.summary.time_avg_rmse_x == batch.time_avg_rmse_x


def test_selections_were_published_and_obeyed(runs):
    case, graph, batch = runs
    decisions = batch.records[0].decisions
    sel = sorted(
        read_topic(graph.bag, topics.SENSOR_SELECTION, SensorSelection), key=lambda m: m.epoch
    )
    assert [m.epoch for m in sel] == list(range(STEPS))
    assert [tuple(m.selected_sensor_ids) for m in sel] == [d.selected_sensor_ids for d in decisions]
    assert all(m.criterion == "mre/det_pos" and len(m.predicted_cost) == 3 for m in sel)
    np.testing.assert_allclose(
        [m.predicted_cost for m in sel], [d.selection_costs for d in decisions], rtol=0, atol=1e-9
    )
    # Only the selected sensor measured at each epoch.
    measured = read_topic(graph.bag, topics.SCANS, Scan)
    by_epoch = {}
    for m in measured:
        by_epoch.setdefault(m.epoch, []).append(m.sensor_id)
    assert by_epoch == {m.epoch + 1: list(m.selected_sensor_ids) for m in sel}
    sim = graph.diagnostics["sim"]
    assert sim["received.SensorSelection"] == STEPS
    assert sim["scans_published"] == STEPS
    assert not any(k.startswith("rejected.") for k in sim)
    assert "command_timeouts" not in sim
    if case == "case3_pd":  # moving platforms: three commands per epoch
        assert sim["commands_applied"] == 3 * STEPS


def test_missed_detections_are_counted_by_sim_and_tracker(runs):
    _, graph, _ = runs
    measured = read_topic(graph.bag, topics.SCANS, Scan)
    missed = sum(len(m.detections) == 0 for m in measured)
    assert missed > 0
    assert graph.diagnostics["sim"]["empty_scans"] == missed
    assert graph.diagnostics["tracker"]["empty_scans"] == missed
    assert graph.diagnostics["tracker"]["updates"] == STEPS
    # The track counts each scan that covered it without a detection (one target: all).
    assert graph.summary.records[0].missed_detections() == missed
