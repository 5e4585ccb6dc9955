"""Bounded memory: what a long run keeps per epoch is results, not messages, and path markers
do not grow with the path."""

import tracemalloc
from pathlib import Path

import pytest
import yaml
from rclpy.parameter import Parameter
from visualization_msgs.msg import MarkerArray

from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from sim_node.sim_node import PATH_CHUNK, SimNode

pytestmark = pytest.mark.ros
SHORT = "tests/ros/data/short_two_sensors.yaml"


def test_a_long_run_keeps_results_not_messages(tmp_path):
    """Python allocations between epochs 30 and 100 of a run whose tracks carry 1,000 particle
    samples (32 kB a message): the evaluator used to keep every message (> 32 kB an epoch),
    and kept each track's samples (42 kB an epoch) until it kept the tracks without them.
    What is left per epoch is the run's record (a track set, two scans and a decision: about
    3 kB here, as the batch loop keeps) and the small objects decoding left in it, a fraction
    of one track message."""
    data = yaml.safe_load(Path(SHORT).read_text())
    data.update(name="long", steps=110)
    data["tracker"] = {"filter": "pf", "particles": 1000, "planner_samples": 1000}
    data["planner"] = {"enabled": False}
    scenario = tmp_path / "long.yaml"
    scenario.write_text(yaml.safe_dump(data))
    sizes = {}

    def sample(graph):
        evaluator = next(n for n in graph.nodes if n.get_name() == "activetrack_evaluator")
        k = len(evaluator.tracks) - 1
        if k in (30, 100) and k not in sizes:
            sizes[k] = tracemalloc.get_traced_memory()[0]

    tracemalloc.start()
    try:
        run_graph(scenario, run_dir=tmp_path / "run", plots=False, during_spin=sample, record=False)
    finally:
        tracemalloc.stop()
    per_epoch = (sizes[100] - sizes[30]) / 70
    assert per_epoch < 10_000, f"{per_epoch:.0f} bytes kept per epoch"


def test_path_markers_republish_only_their_newest_chunk(graph):
    params = [Parameter("scenario", value=SHORT)]
    sim = graph.add(SimNode(context=graph.context, parameter_overrides=params))
    got = []
    sim.create_subscription(
        MarkerArray, topics.MARKERS, got.append, topics.reader_qos(topics.MARKERS)
    )
    for i in range(3 * PATH_CHUNK):
        sim.publish_markers(float(i))
    assert graph.spin_until(lambda: len(got) >= 3 * PATH_CHUNK, timeout=10)
    sizes = [max(len(m.points) for m in array.markers) for array in got]
    assert max(sizes) == PATH_CHUNK  # bounded, whatever the path's length
    last = {m.ns: m for m in got[-1].markers}
    assert all(m.id == 3 for m in last.values())  # chunks 0..3 so far, one id each
    assert [len(m.points) for m in got[PATH_CHUNK - 2].markers] == [PATH_CHUNK] * 2
    # Consecutive chunks share their end points: the path shows unbroken.
    chunk_end = {m.ns: m.points[-1] for m in got[PATH_CHUNK - 2].markers}
    chunk_start = {m.ns: m.points[0] for m in got[PATH_CHUNK - 1].markers}
    assert chunk_end == chunk_start
