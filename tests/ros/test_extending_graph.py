"""A sensor kind (and a filter) that only a scenario's plugins know, through the node graph.

The range-only sensor and the UKF are the plugin modules of docs/extending.md (``my_sensors``,
``my_filters``: the code of tests/core/test_extending_{sensor,filter}.py, checked by
test_extending_docs.py), written to a temporary folder on the import path. The scenario names
them under ``plugins:``; every node imports them when it loads the scenario. The range sensor's
scans travel like every other kind's (``Scan``, one component per detection): the simulator
publishes them, the tracker validates and fuses them, the bag records them. In lockstep mode
the graph's run equals ``run_batch``'s bit for bit.
"""

import math
import sys

import pytest
import yaml
from doc_blocks import file_block
from geometry_msgs.msg import Point, Vector3
from parity import assert_same_run
from rclpy.parameter import Parameter
from recorded import read_topic

from activetrack.closed_loop.batch import run_batch
from activetrack.filters import filter_names, unregister_filter
from activetrack.scenarios import load_scenario, registered_kinds, unregister_sensor
from activetrack_bringup.bag import bag_info
from activetrack_bringup.retrack import retrack
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.convert import MAX_SCAN_DETECTIONS, header
from msgs_defs.msg import Scan, TrackArray
from tracker_node.tracker_node import TrackerNode

pytestmark = pytest.mark.ros

# A robot and a buoy with range-only sensors (the plugin's kind) and a bearing sensor: one
# epoch's three scans of two kinds (docs/extending.md, "A sensor").
SCENARIO = """\
name: range_only
seed: 11
plugins: [my_sensors]
dt: 2.0
steps: 10
target:
  motion: {model: ncv, q: 0.05}
  prior: {mean: [300.0, 3.0, 400.0, -2.0], var: [900.0, 1.0, 900.0, 1.0]}
platforms:
  - id: robot
    initial_state: [0.0, 20.0, 0.0, 0.0]
    controllable: true
    limits: {dpsi_max: 0.7853981633974483, dv_max: 5.0, v_min: 10.0, v_max: 40.0}
    sensors:
      - {id: r1, kind: range, sigma_r: 2.0}
  - id: buoy
    initial_state: [600.0, 0.0, 0.0, 0.0]
    sensors:
      - {id: r2, kind: range, sigma_r: 2.0, pd: 0.9}
      - {id: b2, kind: bearing, sigma: 0.02}
tracker: {filter: ekf}
planner: {cost: pcrlb, criterion: b_k, search: quadrant, mc_samples: 200}
"""
STEPS = 10


@pytest.fixture
def plugin_folder(tmp_path, monkeypatch):
    """tmp_path on the import path with docs/extending.md's plugin modules; what they register
    and the imported modules are taken away afterwards."""
    for name in ("my_sensors", "my_filters"):
        (tmp_path / f"{name}.py").write_text(file_block(f"{name}.py"))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for name in ("my_sensors", "my_filters"):
        sys.modules.pop(name, None)
    if "range" in registered_kinds():
        unregister_sensor("range")
    if "ukf" in filter_names():
        unregister_filter("ukf")


def scenario_file(folder, filter_name: str = "ekf"):
    data = yaml.safe_load(SCENARIO)
    if filter_name == "ukf":
        data["plugins"].append("my_filters")
        data["tracker"] = {"filter": "ukf"}
    path = folder / f"range_only_{filter_name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.mark.parametrize("filter_name", ["ekf", "ukf"])
def test_the_graph_runs_a_plugin_sensor_as_the_batch_does(plugin_folder, filter_name):
    path = scenario_file(plugin_folder, filter_name)
    assert "range" not in registered_kinds()
    batch = run_batch(load_scenario(path))  # loading imports the plugins: now registered
    assert "range" in registered_kinds()
    result = run_graph(path, run_dir=plugin_folder / "run", plots=False)
    a, b = result.summary.records[0], batch.records[0]
    assert_same_run(a, b)
    assert result.summary.time_avg_rmse_x == batch.time_avg_rmse_x
    assert math.isfinite(batch.time_avg_rmse_x[0])
    # Three scans each epoch (two of the plugin's kind), fused; nothing refused anywhere.
    d = result.diagnostics
    assert d["tracker"]["received.Scan"] == 3 * STEPS
    assert d["evaluator"]["received.Scan"] == 3 * STEPS
    assert d["tracker"]["updates"] == STEPS and "incomplete_epochs" not in d["tracker"]
    for node, counts in d.items():
        bad = [k for k in counts if k.startswith(("rejected.", "errors.", "foreign."))]
        assert not bad, (node, bad)
    # The bag holds them (schema embedded); detections as in the batch run, z = (range,).
    assert bag_info(result.bag)["topics"]["/" + topics.SCANS]["count"] == 3 * STEPS
    scans = read_topic(result.bag, topics.SCANS, Scan)
    kinds = {(m.sensor_id, m.sensor_kind) for m in scans}
    assert kinds == {("r1", "range"), ("r2", "range"), ("b2", "bearing")}
    ranges = [m for m in scans if m.sensor_kind == "range"]
    assert all(m.dim == 1 and len(m.detections) <= 1 for m in ranges)
    assert all(list(m.covariance) == [4.0] for m in ranges)
    assert sum(len(m.detections) for m in ranges) == int(b.detected[:, :2].sum()) < 2 * STEPS
    arrays = read_topic(result.bag, topics.TRACKS, TrackArray)
    assert {t.filter_kind for t in arrays} == {filter_name}
    # The bag replays into a fresh tracker (the plugin's scans included): the identical track.
    report = retrack(result.bag, str(path))
    assert report.epochs == STEPS and report.replayed_filter == filter_name  # 1..K replayed
    assert report.identical
    assert report.max_state_difference == 0.0 and report.max_covariance_difference == 0.0


def _valid(**changes) -> Scan:
    """What the simulator publishes for the buoy's range sensor at epoch 1, changed."""
    msg = Scan(
        header=header(2.0),
        platform_id="buoy",
        sensor_id="r2",
        sensor_kind="range",
        epoch=1,
        epoch_scan_count=3,
        sensor_position=Point(x=600.0, y=0.0),
        sensor_velocity=Vector3(),
        fov_centre=0.0,
        fov_width=2 * math.pi,
        fov_r_min=0.0,
        fov_r_max=math.inf,
        dim=1,
        detections=[500.0],
        covariance=[4.0],
        clutter_density=0.0,
    )
    for name, value in changes.items():
        setattr(msg, name, value)
    return msg


INVALID = [
    ("unknown_sensor", dict(sensor_id="r9")),
    ("wrong_sensor_kind", dict(sensor_id="b2")),  # the buoy's bearing sensor
    ("wrong_sensor_kind", dict(sensor_kind="sonar")),
    ("wrong_sensor_kind", dict(  # a range sensor's scan as a range-bearing one
        sensor_kind="range_bearing", dim=2, detections=[500.0, 0.1],
        covariance=[4.0, 0.0, 0.0, 1e-4],
    )),
    ("inconsistent", dict(platform_id="robot")),
    ("out_of_order", dict(epoch=0, header=header(0.0))),
    ("future_epoch", dict(epoch=11, header=header(22.0))),  # beyond the run's 10 steps
    ("bad_stamp", dict(header=header(3.0))),
    ("non_finite", dict(sensor_position=Point(x=math.nan))),
    ("bad_covariance", dict(covariance=[4.0, 0.0])),
    ("bad_covariance", dict(covariance=[-4.0])),
    ("sensor_mismatch", dict(covariance=[9.0])),
    ("sensor_mismatch", dict(clutter_density=0.5)),
    ("sensor_mismatch", dict(fov_width=1.0)),
    ("out_of_range", dict(epoch_scan_count=4)),
    ("wrong_dimension", dict(dim=2, detections=[500.0, 1.0])),
    ("wrong_dimension", dict(dim=0, detections=[])),
    ("wrong_dimension", dict(detections=[500.0] * (MAX_SCAN_DETECTIONS + 1))),
    ("non_finite", dict(detections=[math.nan])),
    ("non_finite", dict(detections=[math.inf])),
    ("out_of_range", dict(detections=[1e300])),
]  # fmt: skip


def test_plugin_scans_are_validated_like_every_other_kind(plugin_folder, graph):
    path = scenario_file(plugin_folder)
    params = [Parameter("scenario", value=str(path))]
    kw = {"context": graph.context, "start_parameter_services": False}
    tracker = graph.add(TrackerNode(parameter_overrides=params, **kw))

    def counted(msg) -> dict:
        before = dict(tracker.counters.counts)
        tracker.guarded(tracker.on_scan, msg)
        after = tracker.counters.counts
        return {k: v - before.get(k, 0) for k, v in after.items() if v != before.get(k, 0)}

    for reason, changes in INVALID:
        assert counted(_valid(**changes)) == {f"rejected.{reason}": 1}, (reason, changes)
    # The valid one is taken (epoch 1 now waits for the rest), a second copy is a duplicate.
    assert counted(_valid()) == {}
    assert counted(_valid(detections=[])) == {"rejected.duplicate": 1}
    scan = tracker.epochs[1].scans["r2"]
    assert scan.Z.tolist() == [[500.0]] and scan.time == 2.0
    assert tracker.sensors["r2"][1].kind == "range"
    assert not [k for k in tracker.counters.counts if k.startswith("errors.")]


def test_the_tracker_refuses_a_filter_parameter_nobody_registered(plugin_folder, graph):
    path = scenario_file(plugin_folder, "ukf")
    params = [Parameter("scenario", value=str(path)), Parameter("filter", value="srukf")]
    with pytest.raises(ValueError, match=r"parameter 'filter' must be one of \['ekf', 'pf', 'ukf'"):
        TrackerNode(parameter_overrides=params, context=graph.context)
