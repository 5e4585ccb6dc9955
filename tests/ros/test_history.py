"""Per-epoch histories sized to the run: a late joiner gets the whole run, however small the
tools' default depth; a run too long for the cap says so."""

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter

from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from msgs_defs.msg import GroundTruthArray, PlatformState
from sim_node.sim_node import SimNode

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


def _free_run(tmp_path, steps: int) -> str:
    text = open(SCENARIO).read().replace("steps: 8", f"steps: {steps}")
    path = tmp_path / "long.yaml"
    path.write_text(text)
    return str(path)


def _late_joiner(graph, scenario: str):
    params = [
        Parameter("scenario", value=scenario),
        Parameter("mode", value="free"),
        Parameter("rate", value=1e5),
    ]
    sim = graph.add(SimNode(context=graph.context, parameter_overrides=params))
    assert graph.spin_until(lambda: sim.done, timeout=30.0)
    late = graph.add(Node("late_joiner", context=graph.context))
    got = {"truth": [], "states": []}
    late.create_subscription(
        GroundTruthArray, topics.GROUND_TRUTH, got["truth"].append,
        topics.reader_qos(topics.GROUND_TRUTH),
    )  # fmt: skip
    late.create_subscription(
        PlatformState, topics.PLATFORM_STATES, got["states"].append,
        topics.reader_qos(topics.PLATFORM_STATES),
    )  # fmt: skip
    graph.spin_until_quiet(lambda: len(got["truth"]) + len(got["states"]), quiet=0.3, timeout=10)
    return sim, got


def test_a_late_joiner_gets_the_whole_run(graph, tmp_path, monkeypatch):
    monkeypatch.setattr(topics, "LATCHED_DEPTH", 8)  # a tool's default: far too small
    sim, got = _late_joiner(graph, _free_run(tmp_path, 60))
    assert sim.history_depth == 61 * 2  # (steps + 1) x two platforms (one sensor each)
    assert [m.epoch for m in got["truth"]] == list(range(61))
    assert sorted(m.epoch for m in got["states"]) == sorted(list(range(61)) * 2)


def test_a_run_beyond_the_cap_keeps_the_newest_and_says_so(graph, tmp_path, monkeypatch):
    monkeypatch.setattr(topics, "MAX_HISTORY_DEPTH", 20)
    scenario = _free_run(tmp_path, 30)
    assert topics.run_history(load_scenario(scenario)) == 62
    warned = []
    monkeypatch.setattr(SimNode, "get_logger", lambda self: _Spy(warned))
    sim, got = _late_joiner(graph, scenario)
    assert sim.history_depth == 20
    assert any("a late joiner misses the start" in w for w in warned)
    assert [m.epoch for m in got["truth"]] == list(range(11, 31))  # the newest 20


class _Spy:
    def __init__(self, lines):
        self.lines = lines

    def warning(self, text, *a, **k):
        self.lines.append(text)

    def info(self, text, *a, **k):
        pass

    error = warning


def test_every_per_epoch_writer_is_sized_to_the_run(graph, tmp_path):
    """The nodes and the evaluator (its RunMetrics) offer the run's depth, not the tools'."""
    from activetrack_bringup.evaluator import EvaluatorNode
    from planner_node.planner_node import PlannerNode
    from tracker_node.tracker_node import TrackerNode

    scenario = _free_run(tmp_path, 1500)  # more epochs than LATCHED_DEPTH
    sc = load_scenario(scenario)
    want = topics.history_depth(sc)
    assert want > topics.LATCHED_DEPTH
    params = [Parameter("scenario", value=scenario)]
    kw = {"context": graph.context, "start_parameter_services": False}
    evaluator = graph.add(EvaluatorNode(sc, **kw))
    nodes = [
        graph.add(cls(parameter_overrides=params, **kw))
        for cls in (SimNode, TrackerNode, PlannerNode)
    ]
    sim, tracker, planner = nodes
    writers = [evaluator.metrics_pub, sim.platform_pub, tracker.tracks_pub, planner.report_pub]
    assert [w.publisher.qos_profile.depth for w in writers] == [want] * 4
