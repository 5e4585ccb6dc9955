"""Every message accounted for: each reader's counters add up (received = accepted + rejected
+ ignored + foreign + errors), and a message bigger than any of the graph's is dropped on its
length, before the hash and before deserialisation."""

import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.serialization import serialize_message

from activetrack.scenarios import load_scenario
from activetrack_bringup.bag_io import open_bag
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros import node_base
from activetrack_ros.convert import header
from activetrack_ros.node_base import GraphNode, unaccounted
from activetrack_ros.sizes import max_bytes
from activetrack_ros.trust import GraphKey
from msgs_defs.msg import Scan

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


def _decoder_interrupted(data, msg_type):
    """rclpy's C decoder when a Ctrl-C arrives inside it: a SystemError over the interrupt."""
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as exc:
        raise SystemError("returned a result with an exception set") from exc


def test_unaccounted_is_received_minus_every_outcome():
    counts = {
        "received.Scan": 7, "received.DiagnosticArray": 3, "accepted.Scan": 2,
        "rejected.non_finite": 1, "ignored.other_diagnostics": 2, "foreign.Scan": 3,
        "errors.on_scan": 1, "dropped.Scan": 5, "updates": 40,
    }  # fmt: skip
    assert unaccounted(counts) == 10 - 9
    assert unaccounted({**counts, "accepted.DiagnosticArray": 1}) == 0


def test_a_clean_run_accounts_for_every_message_in_every_reader(tmp_path):
    run = run_graph(SCENARIO, run_dir=tmp_path / "run", record=True, plots=False)
    assert set(run.diagnostics) == {"sim", "tracker", "planner", "evaluator", "recorder"}
    for node, counts in run.diagnostics.items():
        assert unaccounted(counts) == 0, (node, counts)
        assert not [k for k in counts if k.startswith(("foreign.", "rejected.", "errors."))], node
        assert sum(v for k, v in counts.items() if k.startswith("accepted.")) > 0, node
    recorder = run.diagnostics["recorder"]
    assert recorder["accepted.Clock"] == recorder["received.Clock"] > 0
    recorded = sum(v for k, v in recorder.items() if k.startswith("accepted."))
    with open_bag(run.bag) as bag:
        assert recorded == sum(t.count for t in bag.topics.values())


@pytest.fixture
def reader(graph):
    """A keyed node reading scans (the short scenario's limits), and a writer outside the
    graph on the same topic."""
    key = GraphKey.generate()
    node = graph.add(GraphNode("scan_reader", graph_key=key, context=graph.context))
    node.byte_limits = max_bytes(load_scenario(SCENARIO))
    node.subscribe(Scan, topics.SCANS, lambda msg: None)
    outsider = graph.add(GraphNode("outsider", context=graph.context))
    pub = outsider.create_publisher(Scan, topics.SCANS, topics.writer_qos(topics.SCANS))
    assert graph.spin_until(lambda: pub.get_subscription_count() == 1, timeout=10.0)
    return node, key, pub


def test_a_huge_foreign_scan_is_dropped_on_its_length_and_counted(graph, reader, monkeypatch):
    node, key, pub = reader
    hashed = []
    verify = key.verify
    monkeypatch.setattr(key, "verify", lambda data: hashed.append(len(data)) or verify(data))
    huge = serialize_message(Scan(dim=1, detections=[0.1] * 100_000))
    assert len(huge) > node.byte_limits["Scan"] > 21_000 * 8
    small = serialize_message(Scan(dim=1, detections=[0.1] * 10))
    for _ in range(20):
        pub.publish(huge)
    pub.publish(small)
    assert graph.spin_until(lambda: node.counters.counts["received.Scan"] == 21, timeout=30.0)
    assert node.counters.counts["foreign.Scan"] == 21
    assert hashed == [len(small)]  # the huge ones cost a length check, not a hash
    assert unaccounted(node.counters.counts) == 0


def test_without_a_key_a_huge_scan_is_rejected_before_deserialisation(graph):
    node = graph.add(GraphNode("open_reader", context=graph.context))
    node.byte_limits = max_bytes(load_scenario(SCENARIO))
    taken = []
    node.subscribe(Scan, topics.SCANS, taken.append)
    outsider = graph.add(GraphNode("driver", context=graph.context))
    pub = outsider.create_publisher(Scan, topics.SCANS, topics.writer_qos(topics.SCANS))
    assert graph.spin_until(lambda: pub.get_subscription_count() == 1, timeout=10.0)
    for n in (100_000, 3):
        pub.publish(serialize_message(Scan(header=header(0.0), dim=1, detections=[0.1] * n)))
    assert graph.spin_until(lambda: node.counters.counts["received.Scan"] == 2, timeout=30.0)
    counts = node.counters.counts
    assert counts["rejected.too_large"] == 1 and counts["accepted.Scan"] == 1
    assert len(taken) == 1 and len(taken[0].detections) == 3
    assert unaccounted(counts) == 0


def test_diagnostics_of_other_drivers_are_ignored_once_per_message(graph):
    """An array of 500 statuses from another driver is one message: one counter."""
    from activetrack_bringup.evaluator import EvaluatorNode

    evaluator = graph.add(
        EvaluatorNode(
            load_scenario(SCENARIO), context=graph.context, start_parameter_services=False
        )
    )
    many = DiagnosticArray(status=[DiagnosticStatus(name=f"motor/{i}") for i in range(500)])
    start = time.monotonic()
    evaluator.guarded(evaluator.on_diagnostics, many)
    assert time.monotonic() - start < 1.0
    assert evaluator.counters.counts == {"ignored.other_diagnostics": 1}


def test_the_recorder_writes_only_the_graphs_diagnostics_and_counts_the_rest(tmp_path):
    """With the key: a driver's /diagnostics array is counted foreign and not written, the
    graph's own (tag inside) is written; each message lands in one counter."""
    from diagnostic_msgs.msg import KeyValue

    from activetrack_bringup.bag import BagRecorder
    from activetrack_bringup.inprocess import InProcessGraph

    key = GraphKey(bytes(range(32)))
    ours = DiagnosticArray(
        header=header(5.0),
        status=[
            DiagnosticStatus(name="activetrack/sim_node", values=[KeyValue(key="a", value="1")])
        ],
    )
    theirs = DiagnosticArray(status=[DiagnosticStatus(name="motor", message="hot")])
    kept = {topics.DIAGNOSTICS: topics.GRAPH_TOPICS[topics.DIAGNOSTICS]}
    with InProcessGraph() as g:
        rec = g.add(BagRecorder(tmp_path / "b", kept, graph_key=key, context=g.context))
        on_raw = rec._verifier(key, topics.DIAGNOSTICS, DiagnosticArray)
        on_raw(serialize_message(key.sign_diagnostics(ours)))
        on_raw(serialize_message(theirs))
        on_raw(b"\x00\x01\x00\x00garbage")
        # a Ctrl-C inside the C decoder (wrapped, as rclpy surfaces it) is raised, not counted
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(node_base, "deserialize_message", _decoder_interrupted)
            with pytest.raises(KeyboardInterrupt):
                on_raw(serialize_message(theirs))
        rec.close()
    assert dict(rec.counters.counts) == {
        "accepted.DiagnosticArray": 1, "foreign.DiagnosticArray": 2
    }  # fmt: skip
    assert rec.foreign == 2 and rec.count == 1
    with open_bag(tmp_path / "b") as bag:
        assert sum(t.count for t in bag.topics.values()) == 1
