"""The multi-target graph (multi_sim_node, multi_tracker_node, multi_planner_node and the
multi-target evaluator) against the batch loop: `activetrack run` equals `run_multi_once` bit
for bit on each of the issue's scenarios, in one process and as node processes; the bag holds
the run and replays into a fresh tracker to the same tracks; bad scans are rejected, counted
and logged while the tracker keeps running."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from rclpy.node import Node
from rclpy.parameter import Parameter

from activetrack.closed_loop.batch import component_rngs
from activetrack.multitarget.evaluation import evaluate_run
from activetrack.multitarget.loop import run_multi_batch, run_multi_once
from activetrack.multitarget.simulator import MultiTargetSimulator
from activetrack.scenarios import load_scenario
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.retrack import read_topic
from activetrack_bringup.retrack_multi import retrack_multi
from activetrack_bringup.runner import GraphSetupError, run_graph
from activetrack_ros import graph as topics
from activetrack_ros.convert_multi import scan_msg, track_array_from_msg
from activetrack_ros.graph import reader_qos, writer_qos
from msgs_defs.msg import PlatformState, TrackArray
from msgs_defs.msg import Scan as ScanMsg
from sim_node.sim_node import platform_state_msgs
from tracker_node.multi_tracker_node import MultiTrackerNode

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


def _same_tracks(a, b) -> bool:
    return len(a.tracks) == len(b.tracks) and all(
        x.track_id == y.track_id
        and x.status == y.status
        and np.array_equal(x.mean, y.mean)
        and np.array_equal(x.cov, y.cov)
        for x, y in zip(a.tracks, b.tracks, strict=True)
    )


def _assert_bit_for_bit(graph_record, batch_record) -> None:
    a, b = graph_record, batch_record
    assert np.array_equal(a.truth, b.truth, equal_nan=True)
    assert np.array_equal(a.platform_paths, b.platform_paths)
    assert np.array_equal(a.observed, b.observed)
    assert len(a.tracks) == len(b.tracks)
    assert all(_same_tracks(x, y) for x, y in zip(a.tracks, b.tracks, strict=True))
    for x, y in zip(a.scans, b.scans, strict=True):
        assert [s.sensor_id for s in x] == [s.sensor_id for s in y]
        assert all(np.array_equal(s.Z, t.Z) for s, t in zip(x, y, strict=True))
    assert [d.beams for d in a.decisions] == [d.beams for d in b.decisions]
    assert [[c.heading_change for c in d.commands] for d in a.decisions] == [
        [c.heading_change for c in d.commands] for d in b.decisions
    ]
    costs = [d.report.predicted_costs for d in a.decisions]
    assert costs == [d.report.predicted_costs for d in b.decisions]


@pytest.mark.parametrize("name", sorted(SHORT))
def test_the_graph_equals_the_batch_loop_bit_for_bit(name, tmp_path):
    path = _short(tmp_path, name, *SHORT[name])
    scenario = load_scenario(path)
    result = run_graph(path, run_dir=tmp_path / "run", plots=True, timeout=300)
    assert result.status == "complete", result.detail
    _assert_bit_for_bit(result.summary.records[0], run_multi_once(scenario, None))
    batch = run_multi_batch(scenario, runs=1)
    assert result.summary.mean_gospa == batch.mean_gospa  # the same evaluator draws
    assert result.summary.gospa_t == batch.gospa_t
    assert result.summary.target_bound == batch.target_bound
    assert all(k.split(".")[0] not in ("rejected", "errors") for c in
               result.diagnostics.values() for k in c)  # fmt: skip
    assert [f.name for f in result.files] == ["tracks.png", "gospa.png"]
    assert all(f.stat().st_size > 10_000 for f in result.files)
    # The bag holds the run: a track array per epoch, equal to the batch run's tracks.
    recorded = read_topic(result.bag, topics.TRACKS, TrackArray)
    assert [m.epoch for m in recorded] == list(range(scenario.steps + 1))
    batch_tracks = run_multi_once(scenario, None).tracks
    for msg, tracks in zip(recorded, batch_tracks, strict=True):
        assert _same_tracks(track_array_from_msg(msg, scenario), tracks)
    scans = read_topic(result.bag, topics.SCANS, ScanMsg)
    assert len(scans) == sum(len(s) for s in result.summary.records[0].scans) > 0
    # ... and replays: its scans into a fresh tracker give the same tracks and GOSPA.
    replay = retrack_multi(result.bag, str(path))
    assert replay.epochs == scenario.steps and replay.identical
    assert replay.max_mean_difference == 0.0
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
    batch = run_multi_batch(load_scenario(path), runs=1)
    line = next(x for x in out.splitlines() if x.strip().startswith("GOSPA"))
    assert float(line.split()[1]) == pytest.approx(batch.mean_gospa, abs=0.006)
    assert "decisions  8" in out and "(processes)" in out


def test_a_multitarget_run_is_lockstep_only(tmp_path):
    path = _short(tmp_path, "mt_bearings_crossing", 4)
    with pytest.raises(GraphSetupError, match="lockstep"):
        run_graph(path, run_dir=tmp_path / "run", mode="free")


# --- bad scans at the tracker node ------------------------------------------------------------


def test_bad_scans_are_rejected_counted_and_the_tracker_keeps_running(graph, tmp_path):
    path = _short(tmp_path, "mt_radars_beams", 6)
    scenario = load_scenario(path)
    params = [Parameter("scenario", value=str(path)), Parameter("mode", value="lockstep")]
    tracker = graph.add(MultiTrackerNode(context=graph.context, parameter_overrides=params))
    received: list[TrackArray] = []
    probe = graph.add(Node("probe", context=graph.context))  # a writer without the graph's key
    probe.create_subscription(TrackArray, topics.TRACKS, received.append, reader_qos(topics.TRACKS))
    pubs = {
        t: probe.create_publisher(cls, t, writer_qos(t))
        for t, cls in ((topics.SCANS, ScanMsg), (topics.PLATFORM_STATES, PlatformState))
    }
    sim = MultiTargetSimulator(scenario, component_rngs(scenario.seed, None)[0])
    scans = sim.advance()  # epoch 1, as the sim node publishes it
    states = platform_state_msgs(sim, len(scans), "world")

    def scan(**change) -> ScanMsg:
        msg = scan_msg(scans[0], scenario, len(scans))
        for k, v in change.items():
            setattr(msg, k, v)
        return msg

    bad = [
        scan(detections=[math.nan] * scan().dim),  # NaN
        scan(sensor_id="sonar9"),  # unknown sensor
        scan(epoch=3),  # wrong (future) epoch, stamp consistent below
        scan(dim=3, detections=[1.0, 2.0, 3.0]),  # wrong shape
        scan(fov_width=1.0),  # not the sensor's field of view
    ]
    bad[2].header.stamp.sec = int(3 * scenario.dt)
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
            states = platform_state_msgs(sim, len(scans), "world")
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
    batch = run_multi_once(scenario, 2)
    _assert_bit_for_bit(result.summary.records[0], batch)
    want = evaluate_run(scenario, batch, component_rngs(scenario.seed, 2)[3])
    assert result.summary.run_gospa == [want.mean_gospa]
    assert result.summary.target_bound == [float(b) for b in want.target_bound]
