"""A tool's connection to a graph: a node of its own on a chosen domain, and the namespace that
relative names resolve in."""

from __future__ import annotations

import os

from rclpy.expand_topic_name import expand_topic_name
from rclpy.node import Node

from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.ros_tools import DISCOVERY_S, SETTLE_S


class ToolError(Exception):
    """A tool that cannot do what it was asked: one ``error:`` line; ``code`` the exit code
    (1: nothing answered in time, 2: bad input)."""

    def __init__(self, message: str, code: int = 1):
        super().__init__(message)
        self.code = code


class ToolSession:
    """``with ToolSession(domain, namespace) as s:`` a node on the domain, spun by ``s.spin``."""

    def __init__(self, domain: int | None = None, namespace: str = "", name: str = "tool"):
        self.namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
        self.graph = InProcessGraph(domain_id=domain)
        # A unique name: two tools at once are two nodes, not one name twice.
        self.node = self.graph.add(
            Node(
                f"activetrack_ros_{name}_{os.getpid()}",
                context=self.graph.context,
                start_parameter_services=False,
            )
        )

    def resolve(self, name: str) -> str:
        """A topic name as a node in the namespace resolves it (absolute names stay)."""
        return expand_topic_name(name, self.node.get_name(), self.namespace or "/")

    def resolve_node(self, name: str) -> str:
        """A node name: absolute as given, else in the namespace (``sim_node`` ->
        ``/g1/sim_node``)."""
        if name.startswith("/"):
            return name
        return f"{self.namespace}/{name}"

    def spin(self, seconds: float) -> None:
        self.graph.spin_until(lambda: False, timeout=seconds, step=0.01)

    def spin_until(self, condition, timeout: float) -> bool:
        """Spin until ``condition()`` holds (e.g. a node or topic was discovered)."""
        return self.graph.spin_until(condition, timeout=timeout, step=0.01)

    wait_for_graph = spin_until

    def discover(self, wait: float = DISCOVERY_S) -> None:
        """Spin until the graph this participant sees has not changed for SETTLE_S seconds,
        or ``wait`` seconds pass."""
        self.graph.spin_until_quiet(self._census, quiet=SETTLE_S, timeout=wait, step=0.1)

    def _census(self) -> tuple:
        """Nodes and, per topic, its endpoint counts: what discovery may still fill in."""
        node = self.node
        topics = tuple(
            (name, node.count_publishers(name), node.count_subscribers(name))
            for name, _ in node.get_topic_names_and_types()
        )
        return tuple(self.nodes()), topics

    def nodes(self) -> list[str]:
        """Every node of the graph (absolute names, sorted), this tool's own excepted."""
        own = self.node.get_name()
        return sorted(
            (ns.rstrip("/") + "/" + name)
            for name, ns in self.node.get_node_names_and_namespaces()
            if name != own
        )

    def in_namespace(self, name: str) -> bool:
        """Whether an absolute node or topic name lies in the session's namespace."""
        return not self.namespace or name.startswith(self.namespace + "/")

    def close(self) -> None:
        self.graph.close()

    def __enter__(self) -> ToolSession:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
