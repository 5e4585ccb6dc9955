"""A remappable, namespaced graph: two graphs at once in one DDS domain under two namespaces,
with different seeds, each equal to its own batch run; names remap with ``--ros-args -r``."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from parity import same_tracks
from rclpy.node import Node
from rclpy.parameter import Parameter
from recorded import read_topic

from activetrack.closed_loop.loop import run_once
from activetrack.scenarios import load_scenario
from activetrack_bringup.bag import bag_info
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.runner import GraphSetupError, run_graph
from activetrack_ros import graph as topics
from activetrack_ros.convert import track_array_from_msg
from msgs_defs.msg import TrackArray
from tracker_node.tracker_node import TrackerNode

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


def test_two_graphs_share_a_domain_under_two_namespaces(tmp_path, localhost_discovery):
    """Both runs overlap in time on one domain (node processes, DDS discovery on this host);
    each reproduces run_once of its own run index, and no node of either saw a message of
    the other (zero foreign messages: the names never met)."""
    exe = Path(sys.executable).parent / "activetrack"
    env = dict(os.environ, ROS_DOMAIN_ID=str(20 + os.getpid() % 80))
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    procs = {}
    for run, ns in ((0, "g1"), (1, "fleet/g2")):
        argv = [
            str(exe), "run", SCENARIO, "--processes", "--namespace", ns, "--run", str(run),
            "--out", str(tmp_path / f"run{run}"), "--no-plots", "--json",
            str(tmp_path / f"run{run}.json"), "--timeout", "120",
        ]  # fmt: skip
        procs[run] = (ns, subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, text=True))
    scenario = load_scenario(SCENARIO)
    for run, (ns, proc) in procs.items():
        out, _ = proc.communicate(timeout=180)
        assert proc.returncode == 0, out
        summary = json.loads((tmp_path / f"run{run}.json").read_text())
        assert summary["complete"] and summary["status"] == "complete"
        assert sum(summary["foreign_messages_dropped"].values()) == 0
        bag = tmp_path / f"run{run}" / "bag"
        names = set(bag_info(bag)["topics"])
        assert f"/{ns}/{topics.TRACKS}" in names and f"/{ns}/{topics.TF}" in names
        assert all(n.startswith(f"/{ns}/") for n in names)
        ref = run_once(scenario, run)
        arrays = sorted(read_topic(bag, topics.TRACKS, TrackArray), key=lambda m: m.epoch)
        assert [t.epoch for t in arrays] == list(range(scenario.steps + 1))
        tracks = [track_array_from_msg(m, scenario) for m in arrays]
        assert all(same_tracks(a, b) for a, b in zip(tracks, ref.tracks, strict=True))
    # Different seeds: the two runs differ (so each matched its own reference, not the other's).
    a, b = (read_topic(tmp_path / f"run{r}" / "bag", topics.TRACKS, TrackArray) for r in (0, 1))
    assert not np.allclose(a[-1].tracks[0].state, b[-1].tracks[0].state)


def test_a_bad_namespace_fails_before_anything_starts(tmp_path):
    with pytest.raises(GraphSetupError, match="is not a ROS namespace"):
        run_graph(SCENARIO, run_dir=tmp_path / "r", namespace="9lives")
    assert not (tmp_path / "r").exists()


def test_topic_names_remap_with_ros_args():
    """`--ros-args -r activetrack/tracks:=/fleet/tracks -r __ns:=/g7`: the tracker publishes
    its track arrays on the remapped name and everything else under the namespace."""
    args = ["--ros-args", "-r", "activetrack/tracks:=/fleet/tracks", "-r", "__ns:=/g7"]
    with InProcessGraph(args=args) as g:
        tracker = g.add(
            TrackerNode(
                context=g.context, parameter_overrides=[Parameter("scenario", value=SCENARIO)]
            )
        )
        probe = g.add(Node("probe", context=g.context, use_global_arguments=False))

        def published() -> set:
            return {n for n, _ in probe.get_topic_names_and_types()}

        assert g.spin_until(lambda: "/fleet/tracks" in published(), timeout=5.0)
        names = published()
        assert "/g7/activetrack/track_pose" in names and "/g7/tf" in names
        assert "/g7/activetrack/tracks" not in names and "/activetrack/tracks" not in names
        assert tracker.get_namespace() == "/g7"
