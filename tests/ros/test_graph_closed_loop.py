"""The node graph against the batch loop: parity, multi-process mode, bags and replay."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from parity import assert_same_run
from rclpy.node import Node
from recorded import read_topic
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from activetrack.closed_loop.batch import run_batch
from activetrack.scenarios import ScenarioError, load_scenario
from activetrack_bringup.bag import BagPlayer, bag_info
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.retrack import retrack
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.graph import qos_for
from activetrack_ros.node_base import unaccounted
from msgs_defs.msg import ManoeuvreCommand, PlanReport, TrackArray

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def batch():
    return run_batch(load_scenario(SCENARIO), runs=1)


@pytest.fixture(scope="module")
def graph_run(tmp_path_factory):
    return run_graph(SCENARIO, run_dir=tmp_path_factory.mktemp("run"), plots=True)


# The summary's figures that must equal the batch run's exactly (per target, over time, GOSPA).
SUMMARY_FIGURES = (
    "time_avg_rmse_x", "time_avg_rmse_y", "time_avg_bound_x", "time_avg_bound_y",
    "rmse_x_t", "rmse_y_t", "bound_x_t", "bound_y_t", "held_fraction", "mean_gospa", "gospa_t",
)  # fmt: skip


def _assert_parity(result, batch):
    assert_same_run(result.summary.records[0], batch.records[0])
    for name in SUMMARY_FIGURES:
        assert np.array_equal(
            getattr(result.summary, name), getattr(batch, name), equal_nan=True
        ), name


def test_in_process_graph_reproduces_the_batch_run(graph_run, batch):
    _assert_parity(graph_run, batch)
    assert graph_run.summary.time_avg_rmse_x[0] == batch.time_avg_rmse_x[0]
    assert graph_run.summary.time_avg_bound_y[0] == batch.time_avg_bound_y[0]
    assert graph_run.diagnostics["sim"]["commands_applied"] == 2 * 8
    assert "commands_clamped" not in graph_run.diagnostics["sim"]


def test_commands_in_the_bag_equal_the_batch_commands(graph_run, batch):
    cmds = read_topic(graph_run.bag, topics.MANOEUVRE_COMMANDS, ManoeuvreCommand)
    got = sorted((c.epoch, c.platform_id, c.heading_change, c.speed_change) for c in cmds)
    want = sorted(
        (c.epoch, c.platform_id, c.heading_change, c.speed_change)
        for d in batch.records[0].decisions
        for c in d.commands
    )
    assert [g[:2] for g in got] == [w[:2] for w in want]
    np.testing.assert_allclose([g[2:] for g in got], [w[2:] for w in want], rtol=0, atol=1e-9)


def test_run_folder_holds_summary_bag_and_plots(graph_run):
    summary = json.loads((graph_run.run_dir / "summary.json").read_text())
    for key in (
        "time_avg_rmse_x",
        "time_avg_rmse_y",
        "time_avg_bound_x",
        "time_avg_bound_y",
        "mean_gospa",
        "wall_time_s",
        "real_time_factor",
        "bag",
    ):
        assert key in summary
    assert summary["target_ids"] == ["t1"] and len(summary["time_avg_rmse_x"]) == 1
    assert summary["real_time_factor"] > 1.0
    assert {p.name for p in graph_run.files} == {
        "trajectories.png",
        "rmse_vs_bound.png",
        "gospa.png",
    }
    assert all(p.stat().st_size > 10_000 for p in graph_run.files)


def test_bag_info_counts(graph_run):
    info = bag_info(graph_run.bag)
    t = info["topics"]
    assert t["/" + topics.TRACKS]["count"] == 9  # epochs 0..8
    assert t["/" + topics.SCANS]["count"] == 2 * 8
    assert t["/" + topics.GROUND_TRUTH]["count"] == 9
    assert t["/" + topics.MANOEUVRE_COMMANDS]["count"] == 2 * 8
    assert t["/" + topics.PLAN_REPORT]["count"] == 8
    assert t["/" + topics.BEAM_COMMANDS]["count"] == 0  # no steerable sensor
    assert t["/" + topics.TRACKS]["type"] == "msgs_defs/msg/TrackArray"


def test_plain_rosbags_reads_every_custom_type(graph_run):
    # A typestore built here from the repository's .msg files, not the project's helper.
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in sorted(Path("src/msgs_defs/msg").glob("*.msg")):
        store.register(get_types_from_msg(path.read_text(), f"msgs_defs/msg/{path.stem}"))
    rclpy_tracks = read_topic(graph_run.bag, topics.TRACKS, TrackArray)
    seen = set()
    meta = yaml.safe_load((graph_run.bag / "metadata.yaml").read_text())[
        "rosbag2_bagfile_information"
    ]
    assert meta["storage_identifier"] == "mcap" and meta["version"] == 9
    with Reader(graph_run.bag) as reader:
        for conn, _, data in reader.messages():
            msg = store.deserialize_cdr(bytes(data), conn.msgtype)
            seen.add(conn.msgtype)
            if conn.topic == "/" + topics.TRACKS:
                ref = rclpy_tracks[msg.epoch].tracks[0]
                (item,) = msg.tracks
                np.testing.assert_array_equal(item.state, ref.state)
                np.testing.assert_array_equal(item.samples, ref.samples)
                assert item.sample_count == 300  # the PF's planner samples
    custom = {t for t in seen if t.startswith("msgs_defs/")}
    assert custom == {
        "msgs_defs/msg/Scan",
        "msgs_defs/msg/GroundTruthArray",
        "msgs_defs/msg/ManoeuvreCommand",
        "msgs_defs/msg/PlanReport",
        "msgs_defs/msg/PlatformState",
        "msgs_defs/msg/RunMetrics",
        "msgs_defs/msg/TrackArray",
    }


def test_bag_is_self_describing(graph_run):
    # No typestore at all: every type comes from the definitions embedded in the bag.
    rclpy_tracks = read_topic(graph_run.bag, topics.TRACKS, TrackArray)
    counts = {}
    with AnyReader([graph_run.bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        for conn, _, data in reader.messages():
            msg = reader.deserialize(data, conn.msgtype)
            counts[conn.msgtype] = counts.get(conn.msgtype, 0) + 1
            if conn.topic == "/" + topics.TRACKS:
                ref = rclpy_tracks[msg.epoch].tracks[0]
                np.testing.assert_array_equal(msg.tracks[0].covariance, ref.covariance)
                np.testing.assert_array_equal(msg.tracks[0].state_covariance, ref.state_covariance)
    assert counts["msgs_defs/msg/TrackArray"] == len(rclpy_tracks)
    assert len(counts) >= 10


def test_replay_into_fresh_tracker_reproduces_the_track(graph_run):
    same = retrack(graph_run.bag, SCENARIO)
    assert same.epochs == 8 and same.identical and same.target_ids == ("t1",)  # 1..8 replayed
    assert same.max_state_difference == 0.0 and same.max_covariance_difference == 0.0
    assert same.replayed_time_avg_rmse == same.recorded_time_avg_rmse
    assert same.recorded_gospa == same.replayed_gospa
    other = retrack(graph_run.bag, SCENARIO, filter_kind="ekf")
    assert other.replayed_filter == "ekf" and other.recorded_filter == "pf"
    assert other.max_state_difference > 0.0 and not other.identical
    assert all(np.isfinite(other.replayed_time_avg_rmse[0]))


def test_play_republishes_with_recorded_timing(graph_run):
    got = []
    with InProcessGraph() as graph:
        listener = graph.add(Node("listener", context=graph.context))
        listener.create_subscription(
            PlanReport, topics.PLAN_REPORT, got.append, qos_for(topics.PLAN_REPORT)
        )
        player = graph.add(
            BagPlayer(graph_run.bag, [topics.PLAN_REPORT], rate=4.0, context=graph.context)
        )
        graph.spin_until(lambda: (player.play_step(), len(got) == 8)[1], timeout=30, step=0.001)
    assert [m.epoch for m in got] == list(range(8))
    with pytest.raises(ValueError, match="not in the bag"):
        BagPlayer(graph_run.bag, ["/nope"])


@pytest.mark.slow
def test_processes_mode_reproduces_the_batch_run(batch, tmp_path, localhost_discovery):
    result = run_graph(
        SCENARIO, processes=True, run_dir=tmp_path, record=False, plots=False, timeout=120
    )
    _assert_parity(result, batch)
    # Every node process's counters reached the runner (a short run can end before discovery
    # matched its /diagnostics reader: before, one node's in two runs of three), each adding up.
    assert set(result.diagnostics) == {"sim", "tracker", "planner", "evaluator"}
    assert not [k for k in result.diagnostics["evaluator"] if k.startswith("diagnostics_missing")]
    assert result.diagnostics["tracker"]["updates"] == 8
    assert {n: unaccounted(c) for n, c in result.diagnostics.items()} == dict.fromkeys(
        result.diagnostics, 0
    )


def test_processes_mode_refuses_when_discovery_is_off(tmp_path, capsys):
    # tests/conftest.py switches discovery off: node processes could never find each other.
    assert cli_main(["run", SCENARIO, "--processes", "--out", str(tmp_path / "r")]) == 2
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE is OFF" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_malformed_scenario_fails_before_anything_starts(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(open(SCENARIO).read().replace("kind: bearing", "kind: sonar", 1))
    with pytest.raises(ScenarioError, match="sensors.0"):
        run_graph(bad, run_dir=tmp_path / "run")
    assert not (tmp_path / "run").exists()
    assert cli_main(["run", str(bad)]) == 2
    assert "must be one of" in capsys.readouterr().err
