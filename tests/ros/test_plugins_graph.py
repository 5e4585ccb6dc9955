"""The graph half of issue 24's plugin test: a sensor kind and a filter defined only in a test
module (tests/plugins_for_tests.py: the ``position_fix`` sensor with its own clutter model, the
``pda_kf`` filter with ``update_pda`` and a factory that takes ``t0``) run a scene of three
targets, one born late and one dying, with clutter and steerable beams, through `activetrack
run` (the in-process graph: sim, tracker and planner nodes, the runner's evaluator) and
`activetrack bag retrack`, each equal to the batch loop bit for bit.

The scenario names ``plugin_registration`` under ``plugins:``; every node imports it when it
loads the file. As in tests/core/test_plugins.py, the three scenario rules that still name the
built-in multi-target kinds and filters are waived (there, a strict xfail asserts they fail).
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import plugins_for_tests as plugins
import pytest
from parity import same_tracks
from recorded import read_topic

from activetrack.closed_loop.batch import run_batch
from activetrack.scenarios import load_scenario
from activetrack_bringup.cli import main as cli_main
from activetrack_ros import graph as topics
from activetrack_ros.convert import track_array_from_msg
from msgs_defs.msg import Scan, TrackArray

pytestmark = pytest.mark.ros

SCENARIO = plugins.scene_yaml("plugin_graph", steps=10, death=8, birth=3, mc_samples=60)
# The summary's figures `activetrack run` shares with `activetrack batch` exactly.
FIGURES = ("time_avg_rmse_x", "time_avg_bound_y", "rmse_x_t", "held_fraction", "gospa_t")


@pytest.fixture
def scene(tmp_path):
    """The scene's file (it loads as written: the rules ask the registries what a kind can
    do); the plugins its ``plugins:`` registered are taken away afterwards."""
    path = tmp_path / "plugin_graph.yaml"
    path.write_text(SCENARIO)
    yield path
    plugins.unregister()
    sys.modules.pop("plugin_registration", None)


def _cli(*argv) -> int:
    return cli_main([str(a) for a in argv])


def test_plugin_sensor_and_filter_run_the_graph_and_retrack(scene, tmp_path, capsys):
    scenario = load_scenario(scene)  # imports plugin_registration: both registered
    assert scenario.tracker.filter == plugins.FILTER_NAME
    batch = run_batch(scenario, runs=1)
    record = batch.records[0]
    assert batch.association == "jpda" and np.isfinite(batch.gospa_t).all()

    # `activetrack run`: the graph in this process, the summary the batch run's, bit for bit.
    plugins.FACTORY_T0.clear()
    out = tmp_path / "run"
    assert _cli("run", scene, "--out", out, "--json", tmp_path / "run.json", "--no-plots") == 0
    summary = json.loads((tmp_path / "run.json").read_text())
    assert summary["status"] == "complete" and summary["target_ids"] == ["t1", "t2", "t3"]
    assert summary["mean_gospa"] == batch.mean_gospa and math.isfinite(batch.mean_gospa)
    for name in FIGURES:  # summary.json writes NaN (no target yet) as null
        got = np.array(summary[name], dtype=float)
        assert np.array_equal(got, getattr(batch, name), equal_nan=True), name
    for node, counts in summary["diagnostics"].items():
        bad = [k for k in counts if k.startswith(("rejected.", "errors.", "foreign."))]
        assert not bad, (node, bad)
    # The tracker node built filters from the plugin sensor's detections after epoch 0.
    assert any(t0 > 0.0 for t0 in plugins.FACTORY_T0)

    # The bag: the plugin kind's scans (two components, its clutter density) and every epoch's
    # tracks, equal to the batch run's; tracks started from detections and beams on tracks.
    bag = out / "bag"
    scans = read_topic(bag, topics.SCANS, Scan)
    assert {m.sensor_kind for m in scans} == {plugins.SENSOR_KIND}
    assert all(m.dim == 2 for m in scans) and {m.clutter_density for m in scans} == {1e-8, 1e-7}
    detections = sum(len(s.Z) for epoch in record.scans for s in epoch)
    assert sum(len(m.detections) // 2 for m in scans) == detections
    arrays = read_topic(bag, topics.TRACKS, TrackArray)
    assert [m.epoch for m in arrays] == list(range(scenario.steps + 1))
    for msg, tracks in zip(arrays, record.tracks, strict=True):
        assert same_tracks(track_array_from_msg(msg, scenario), tracks), msg.epoch
    assert any(t.origin == "" for ts in record.tracks for t in ts.confirmed)
    assert any(b.track_id > 0 for d in record.decisions for b in d.beams)

    # `activetrack bag retrack`: the scans into a fresh pda_kf tracker, the identical tracks.
    capsys.readouterr()
    assert _cli("bag", "retrack", bag, "--scenario", scene, "--json", tmp_path / "rt.json") == 0
    report = json.loads((tmp_path / "rt.json").read_text())
    assert report["identical"] and report["epochs"] == scenario.steps
    assert report["replayed_filter"] == report["recorded_filter"] == plugins.FILTER_NAME
    assert report["max_state_difference"] == 0.0 == report["max_covariance_difference"]
    assert report["recorded_gospa"] == report["replayed_gospa"] == batch.mean_gospa
