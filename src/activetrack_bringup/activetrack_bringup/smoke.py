"""Smoke run of the node graph: bring up sim, tracker and planner in one process and pass one
message of every msgs_defs type over the graph's topics.

Every message is published by a probe node on its graph topic; the nodes that consume that
topic must receive it, and the probe's own subscription must get back every field unchanged.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from rclpy.node import Node

from activetrack_bringup.examples import MESSAGE_TYPES, TOPIC_OF, example_messages
from activetrack_bringup.inprocess import InProcessGraph
from planner_node.planner_node import PlannerNode
from sim_node.sim_node import SimNode
from tracker_node.tracker_node import TrackerNode

# Which node consumes which type (the probe consumes all of them).
CONSUMERS = {
    "BearingMeasurement": "tracker_node",
    "PolarMeasurement": "tracker_node",
    "PlatformState": "planner_node",
    "TrackEstimate": "planner_node",
    "ManoeuvreCommand": "sim_node",
    "SensorSelection": "sim_node",
}


class ProbeNode(Node):
    """Publishes the examples and records what comes back on every graph topic."""

    def __init__(self, **kwargs):
        super().__init__("smoke_probe", **kwargs)
        self.got: dict[str, object] = {}
        self.pubs = {}
        for msg_type in MESSAGE_TYPES:
            name = msg_type.__name__
            self.pubs[name] = self.create_publisher(msg_type, TOPIC_OF[msg_type], 10)
            self.create_subscription(
                msg_type, TOPIC_OF[msg_type], lambda m, n=name: self.got.setdefault(n, m), 10
            )


@dataclass
class SmokeResult:
    rows: list[tuple[str, str, bool, bool]] = field(default_factory=list)
    wall_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        return bool(self.rows) and all(intact and consumed for _, _, intact, consumed in self.rows)


def run_smoke(timeout: float = 10.0) -> SmokeResult:
    start = time.monotonic()
    with InProcessGraph() as graph:
        nodes = {
            "sim_node": graph.add(SimNode(context=graph.context)),
            "tracker_node": graph.add(TrackerNode(context=graph.context)),
            "planner_node": graph.add(PlannerNode(context=graph.context)),
        }
        probe = graph.add(ProbeNode(context=graph.context))
        sent = {type(m).__name__: m for m in example_messages()}

        def delivered(name: str) -> bool:
            consumer = CONSUMERS.get(name)
            got_back = name in probe.got
            return got_back and (consumer is None or nodes[consumer].received[name] > 0)

        deadline = time.monotonic() + timeout
        # Republish until delivered: a new subscription may miss the very first message.
        while not all(delivered(n) for n in sent) and time.monotonic() < deadline:
            for name, msg in sent.items():
                if not delivered(name):
                    probe.pubs[name].publish(msg)
            graph.spin_until(lambda: False, timeout=0.05)

        result = SmokeResult()
        for name, msg in sent.items():
            consumer = CONSUMERS.get(name, "(evaluators)")
            intact = probe.got.get(name) == msg
            consumed = consumer not in nodes or nodes[consumer].received[name] > 0
            result.rows.append((name, consumer, intact, consumed))
    result.wall_time_s = time.monotonic() - start
    return result
