"""Hold a sim's first epoch until viewers have joined (``activetrack run --wait-for``; the
sim's ``wait_for_*`` parameters), so a viewer started before a fast run (RViz, Foxglove's
bridge) does not miss its start on the volatile streams (``clock``, ``tf``).

The sim publishes nothing of the run (its latched static frames excepted) until, as its own
participant sees the graph, the subscribers asked for (:class:`WaitFor`) are there; outside
means any node but the graph's own (:data:`GRAPH_NODE_NAMES`) in the sim's namespace. Seeing
a viewer's subscription does not mean the viewer knows the graph's writers yet: discovery is
per endpoint and participant, and a volatile reader drops what a writer sent before it matched
(measured: a viewer seen by the sim missed the first clocks, or the tracker's first
estimates). So the sim then lets discovery settle for ``SETTLE_S`` and waits until each of
its publishers has matched every subscription it has discovered (at most ``MATCH_WAIT_S``
more). Clearing the parameters while it holds starts the run at once; once started they
cannot change.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from rclpy.expand_topic_name import expand_topic_name

from activetrack_ros.graph import GRAPH_TOPICS
from activetrack_ros.params import ParamSpec

WAIT_FOR_SUBSCRIBERS = ParamSpec(
    "wait_for_subscribers", 0,
    "hold the first epoch until this many nodes outside the graph subscribe to its topics "
    "(0: do not wait; changeable until the run starts)",
    read_only=False, low=0, high=10_000,
)  # fmt: skip
WAIT_FOR_TOPIC = ParamSpec(
    "wait_for_topic", "",
    "hold the first epoch until a node outside the graph subscribes to this topic (relative: "
    "in the node's namespace; empty: do not wait; changeable until the run starts)",
    read_only=False, pattern=r"[A-Za-z_~/][A-Za-z0-9_/~]*",
)  # fmt: skip
WAIT_FOR_NODES = ParamSpec(
    "wait_for_nodes", "",
    "hold the first epoch until these nodes of the namespace (names separated by spaces) "
    "subscribe to the graph's topics: the launch file names the evaluator and recorder it "
    "starts, which must see the run from its start (changeable until the run starts)",
    read_only=False, pattern=r"[A-Za-z_][A-Za-z0-9_]*( +[A-Za-z_][A-Za-z0-9_]*)*",
)  # fmt: skip
WAIT_FOR = (WAIT_FOR_SUBSCRIBERS, WAIT_FOR_TOPIC, WAIT_FOR_NODES)
SETTLE_S = 3.5  # once satisfied: Fast DDS announces and heartbeats discovery every 3 s
MATCH_WAIT_S = 2.0  # after settling: the longest wait for discovered readers to match
STARTED = "the wait_for parameters hold the first epoch only: the run has started"
_NOT_THE_RUNS = ("/rosout", "/parameter_events")  # every node's own, not the run's streams

# The graph's own node names: its nodes, and the runner's evaluator, recorder and live view.
_NODES = ("sim_node", "tracker_node", "planner_node")
_RUNNERS = ("activetrack_evaluator", "activetrack_recorder", "activetrack_live_view")
GRAPH_NODE_NAMES = frozenset((*_NODES, *_RUNNERS))


@dataclass(frozen=True)
class WaitFor:
    """``count`` outside subscriber nodes of any graph topic, one of ``topic``, and the
    subscriber nodes ``nodes`` (names, in or outside the graph): all that are given."""

    count: int = 0
    topic: str = ""
    nodes: tuple[str, ...] = ()

    @classmethod
    def of_params(cls, p: dict) -> WaitFor:
        names = tuple(p[WAIT_FOR_NODES.name].split())
        return cls(p[WAIT_FOR_SUBSCRIBERS.name], p[WAIT_FOR_TOPIC.name], names)

    @property
    def any(self) -> bool:
        return bool(self.count or self.topic or self.nodes)

    @classmethod
    def parse(cls, text: str) -> WaitFor | None:
        """``--wait-for N|TOPIC``: N >= 1 or a topic name ('': None); ValueError naming it."""
        text = text.strip()
        if not text:
            return None
        if text.isdigit():
            if int(text) < 1:
                raise ValueError(f"--wait-for: a number of subscribers must be >= 1, got {text}")
            return cls(count=int(text))
        if WAIT_FOR_TOPIC.check(text) is not None:
            raise ValueError(f"--wait-for: a subscriber count or a topic name, got {text!r}")
        return cls(topic=text)

    def params(self) -> dict:
        """The sim's parameters for this, those off their defaults (``-p name:=`` cannot be '')."""
        given = {WAIT_FOR_SUBSCRIBERS.name: self.count, WAIT_FOR_TOPIC.name: self.topic}
        return {k: v for k, v in given.items() if v}

    def describe(self, namespace: str) -> str:
        what = []
        if self.count:
            what.append(f"{self.count} subscriber node(s) of the graph's topics outside the graph")
        if self.topic:
            what.append(f"a subscriber of {resolve(self.topic, namespace)} outside the graph")
        if self.nodes:
            what.append(f"the nodes {list(self.nodes)} as subscribers of the graph's topics")
        return " and ".join(what)

    def satisfied(self, node, namespace: str) -> bool:
        """Whether ``node``'s participant sees the subscribers asked for."""
        if self.topic and not subscribers(node, namespace, [resolve(self.topic, namespace)]):
            return False
        every = set().union(*subscribers(node, namespace, outside=False).values())
        ns = namespace or "/"
        if any((ns, name) not in every for name in self.nodes):
            return False
        outside = {(n_ns, n) for n_ns, n in every if not (n_ns == ns and n in GRAPH_NODE_NAMES)}
        return len(outside) >= self.count


def resolve(topic: str, namespace: str) -> str:
    """``topic`` as the graph's nodes in ``namespace`` resolve it."""
    return expand_topic_name(topic, "activetrack_wait_for", namespace or "/")


def subscribers(
    node, namespace: str, topics=None, outside: bool = True
) -> dict[str, set[tuple[str, str]]]:
    """Resolved topic (default: every graph topic) -> (namespace, name) of its subscriber nodes
    (``outside``: those outside the graph), as ``node``'s participant sees the graph now."""
    ns = namespace or "/"
    names = topics if topics is not None else [resolve(t, namespace) for t in GRAPH_TOPICS]
    found: dict[str, set[tuple[str, str]]] = {}
    for name in names:
        readers = {
            (info.node_namespace, info.node_name)
            for info in node.get_subscriptions_info_by_topic(name)
            if not (outside and info.node_namespace == ns and info.node_name in GRAPH_NODE_NAMES)
        }
        if readers:
            found[name] = readers
    return found


class FirstEpochHold:
    """The hold of one sim node (call :attr:`waiting` from its timer): ``start()`` publishes its
    first epoch; the wait_for parameters' entries go into ``changes`` (params.on_change)."""

    def __init__(self, node, params: dict, start: Callable[[], None], changes: dict):
        self.node = node
        self._start = start
        self._changes = changes
        self.wait = WaitFor.of_params(params)
        self.state = "started"  # held | settling | started
        self._settled = self._deadline = 0.0
        if not self.wait.any:
            self._fix()
            start()
        else:
            self.state = "held"
            for spec in WAIT_FOR:
                changes[spec.name] = self._changed
            node.get_logger().info(
                f"holding the first epoch until {self.wait.describe(node.get_namespace())}"
            )

    def _fix(self) -> None:
        for spec in WAIT_FOR:
            self._changes[spec.name] = STARTED

    def _changed(self, _value) -> None:
        """A wait_for parameter changed (post-set: the node holds the new values)."""
        node = self.node
        self.wait = WaitFor.of_params({s.name: node.get_parameter(s.name).value for s in WAIT_FOR})
        self.state = "held"

    @property
    def waiting(self) -> bool:
        """True while the first epoch is held; starts it once the subscribers are there, matched."""
        if self.state == "started":
            return False
        now = time.monotonic()
        if self.state == "held" and not self.wait.any:  # released by hand: no viewer to wait for
            self.state, self._settled, self._deadline = "settling", now, now
        elif self.state == "held" and self.wait.satisfied(self.node, self.node.get_namespace()):
            self.state, self._settled = "settling", now + SETTLE_S
            self._deadline = self._settled + MATCH_WAIT_S
        if self.state != "settling" or now < self._settled:
            return True
        if not self._matched() and now <= self._deadline:
            return True
        self.state = "started"
        self._fix()
        self.node.get_logger().info("first epoch released")
        self._start()
        return False

    def _matched(self) -> bool:
        """Each publisher of the node matched every subscription the participant knows of."""
        node = self.node
        return all(
            pub.get_subscription_count() >= node.count_subscribers(pub.topic_name)
            for pub in node.publishers
            if pub.topic_name not in _NOT_THE_RUNS
        )
