"""The graph (sim_node, tracker_node, planner_node and the runner's evaluator) on the
multi-target scenarios against the batch loop: `activetrack run` equals `run_once` bit for bit
on each of them, in one process and as node processes; the bag holds the run and replays into a
fresh tracker to the same tracks; bad scans are rejected, counted and logged while the tracker
keeps running."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from parity import assert_same_run, same_tracks
from rclpy.node import Node
from rclpy.parameter import Parameter
from recorded import read_topic

from activetrack.closed_loop.batch import run_batch, summarize
from activetrack.closed_loop.components import build_simulator, component_rngs
from activetrack.closed_loop.evaluation import evaluate_run
from activetrack.closed_loop.loop import run_once
from activetrack.scenarios import load_scenario
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.retrack import retrack
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.convert import platform_state_msg, scan_msg, track_array_from_msg
from activetrack_ros.graph import reader_qos, writer_qos
from msgs_defs.msg import PlatformState, TrackArray
from msgs_defs.msg import Scan as ScanMsg
from tracker_node.tracker_node import TrackerNode

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[2]


def _short(tmp: Path, name: str, steps: int, scale_epochs: float = 1.0) -> Path:
    """The scenario with ``steps`` epochs (births and deaths scaled by ``scale_epochs``)."""
    data = yaml.safe_load((ROOT / "scenarios" / f"{name}.yaml").read_text())
    data["steps"] = steps
    for t in data["targets"]:
        for key in ("birth", "death"):
            if key in t:
                t[key] = int(t[key] * scale_epochs)
    path = tmp / f"{name}_short.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


SHORT = {  # name: (steps, scale of births and deaths); (c) keeps a birth and a death
    "mt_bearings_crossing": (10, 1.0),
    "mt_radars_beams": (12, 1.0),
    "mt_appear_disappear": (16, 0.25),
}


# The summary's figures a graph run shares with the batch run, exactly.
SUMMARY_FIGURES = (
    "time_avg_rmse_x", "time_avg_rmse_y", "time_avg_bound_x", "time_avg_bound_y",
    "rmse_x_t", "rmse_y_t", "bound_x_t", "bound_y_t", "held_fraction", "mean_gospa", "gospa_t",
    "breaks", "swaps", "run_gospa",
)  # fmt: skip


def _assert_same_summary(a, b) -> None:
    for name in SUMMARY_FIGURES:
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name


@pytest.mark.parametrize("name", sorted(SHORT))
def test_the_graph_equals_the_batch_loop_bit_for_bit(name, tmp_path):
    path = _short(tmp_path, name, *SHORT[name])
    scenario = load_scenario(path)
    result = run_graph(path, run_dir=tmp_path / "run", plots=True, timeout=300)
    assert result.status == "complete", result.detail
    batch = run_batch(scenario, runs=1)
    assert_same_run(result.summary.records[0], batch.records[0])
    _assert_same_summary(result.summary, batch)  # the same evaluator draws
    assert all(k.split(".")[0] not in ("rejected", "errors") for c in
               result.diagnostics.values() for k in c)  # fmt: skip
    assert [f.name for f in result.files] == ["trajectories.png", "rmse_vs_bound.png", "gospa.png"]
    assert all(f.stat().st_size > 10_000 for f in result.files)
    # The bag holds the run: a track array per epoch, equal to the batch run's tracks.
    recorded = read_topic(result.bag, topics.TRACKS, TrackArray)
    assert [m.epoch for m in recorded] == list(range(scenario.steps + 1))
    for msg, tracks in zip(recorded, batch.records[0].tracks, strict=True):
        assert same_tracks(track_array_from_msg(msg, scenario), tracks)
    scans = read_topic(result.bag, topics.SCANS, ScanMsg)
    assert len(scans) == sum(len(s) for s in result.summary.records[0].scans) > 0
    # ... and replays: its scans into a fresh tracker give the same tracks and GOSPA.
    replay = retrack(result.bag, str(path))
    assert replay.epochs == scenario.steps and replay.identical
    assert replay.max_state_difference == 0.0 and replay.max_covariance_difference == 0.0
    assert replay.recorded_gospa == replay.replayed_gospa
    assert replay.recorded_gospa == pytest.approx(batch.mean_gospa, rel=1e-12)


def test_retrack_refuses_a_bag_of_another_scenario(tmp_path, capsys):
    a = _short(tmp_path, "mt_bearings_crossing", 4)
    result = run_graph(a, run_dir=tmp_path / "run", plots=False)
    b = _short(tmp_path, "mt_radars_beams", 4)
    assert cli_main(["bag", "retrack", str(result.bag), "--scenario", str(b)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "wrong --scenario?" in err[0], err


def test_node_processes_equal_the_batch_loop_and_the_cli_prints_gospa(
    tmp_path, capsys, localhost_discovery
):
    path = _short(tmp_path, "mt_bearings_crossing", 8)
    code = cli_main(["run", str(path), "--processes", "--out", str(tmp_path / "run")])
    out = capsys.readouterr().out
    assert code == 0, out
    batch = run_batch(load_scenario(path), runs=1)
    line = next(x for x in out.splitlines() if x.strip().startswith("GOSPA"))
    assert float(line.split()[1]) == pytest.approx(batch.mean_gospa, abs=0.006)
    assert "decisions  8" in out and "(processes)" in out


def test_a_multitarget_run_also_runs_in_free_mode(tmp_path):
    """Free mode (sim time at 20x wall time): beams, commands and scans apply as they arrive;
    the run completes with a track array per epoch, finite GOSPA and nothing refused."""
    path = _short(tmp_path, "mt_bearings_crossing", 4)
    result = run_graph(
        path, run_dir=tmp_path / "run", plots=False, mode="free", sim_params={"rate": 20.0}
    )
    assert result.status == "complete", result.detail
    record = result.summary.records[0]
    assert [t.epoch for t in record.tracks] == list(range(5))
    assert math.isfinite(result.summary.mean_gospa)
    assert all(len(d.beams) == 2 for d in record.decisions)  # both beams steered each epoch
    for node, counts in result.diagnostics.items():
        assert not [k for k in counts if k.startswith(("rejected.", "errors."))], node


# --- bad scans at the tracker node ------------------------------------------------------------


def _state_msgs(sim, scan_count: int) -> list[PlatformState]:
    """The platform states the sim node publishes at its current epoch."""
    return [platform_state_msg(s, scan_count, "world") for s in sim.platform_snapshots()]


def test_bad_scans_are_rejected_counted_and_the_tracker_keeps_running(graph, tmp_path):
    path = _short(tmp_path, "mt_radars_beams", 6)
    scenario = load_scenario(path)
    params = [Parameter("scenario", value=str(path)), Parameter("mode", value="lockstep")]
    tracker = graph.add(TrackerNode(context=graph.context, parameter_overrides=params))
    received: list[TrackArray] = []
    probe = graph.add(Node("probe", context=graph.context))  # a writer without the graph's key
    probe.create_subscription(TrackArray, topics.TRACKS, received.append, reader_qos(topics.TRACKS))
    pubs = {
        t: probe.create_publisher(cls, t, writer_qos(t))
        for t, cls in ((topics.SCANS, ScanMsg), (topics.PLATFORM_STATES, PlatformState))
    }
    sim = build_simulator(scenario, component_rngs(scenario.seed, None)[0])
    scans = sim.advance()  # epoch 1, as the sim node publishes it
    states = _state_msgs(sim, len(scans))

    def scan(**change) -> ScanMsg:
        msg = scan_msg(scans[0], scenario, len(scans))
        for k, v in change.items():
            setattr(msg, k, v)
        return msg

    bad = [
        scan(detections=[math.nan] * scan().dim),  # NaN
        scan(sensor_id="sonar9"),  # unknown sensor
        scan(epoch=scenario.steps + 1),  # beyond the run (a nearer one waits in the buffer)
        scan(dim=3, detections=[1.0, 2.0, 3.0]),  # wrong shape
        scan(fov_width=1.0),  # not the sensor's field of view
    ]
    bad[2].header.stamp.sec = int((scenario.steps + 1) * scenario.dt)
    for msg in bad:
        pubs[topics.SCANS].publish(msg)
    graph.spin_until(lambda: tracker.counters.total("rejected.") >= len(bad), timeout=10)
    counts = tracker.counters.counts
    assert tracker.counters.total("rejected.") == len(bad), counts
    for reason in ("unknown_sensor", "future_epoch", "sensor_mismatch"):
        assert counts.get(f"rejected.{reason}") == 1, counts
    assert "updates" not in counts  # nothing bad reached the filter
    # ... and the node still runs: epochs 1-3 (beams held where they start) update it.
    detections = 0
    for k in (1, 2, 3):
        if k > 1:
            scans = sim.advance()
            states = _state_msgs(sim, len(scans))
        for one in scans:
            pubs[topics.SCANS].publish(scan_msg(one, scenario, len(scans)))
            detections += len(one.Z)
        for m in states:
            pubs[topics.PLATFORM_STATES].publish(m)
        assert graph.spin_until(lambda k=k: any(m.epoch == k for m in received), timeout=10)
    assert counts.get("updates") == 3
    assert counts.get("detections") == detections > 0
    assert not any(k.startswith("errors.") for k in counts)


def test_a_monte_carlo_run_index_is_that_run_of_the_batch(tmp_path):
    """``--run r``: the graph draws every generator of run r, the evaluator's (the sampled
    per-target bound) included."""
    path = _short(tmp_path, "mt_bearings_crossing", 5)
    scenario = load_scenario(path)
    result = run_graph(path, run_dir=tmp_path / "run", plots=False, run=2)
    batch = run_once(scenario, 2)
    assert_same_run(result.summary.records[0], batch)
    want = evaluate_run(scenario, batch, component_rngs(scenario.seed, 2)[3])
    assert result.summary.run_gospa == [want.mean_gospa]
    _assert_same_summary(result.summary, summarize(scenario, [batch], [want]))
