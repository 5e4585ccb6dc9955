"""Run several nodes in one process without launch: a fresh rclpy context and an executor.

Used by the command line, by tests and by user scripts::

    with InProcessGraph() as graph:
        sim = graph.add(SimNode(context=graph.context))
        graph.spin_until(lambda: sim.done, timeout=10.0)
"""

from __future__ import annotations

import time
from collections.abc import Callable

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node


class InProcessGraph:
    """Owns one rclpy context, its executor and the nodes added to it; tears all down on exit."""

    def __init__(self, args: list[str] | None = None, domain_id: int | None = None):
        self.context = Context()
        init_kwargs = {"args": args, "context": self.context}
        if domain_id is not None:
            init_kwargs["domain_id"] = domain_id
        rclpy.init(**init_kwargs)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes: list[Node] = []
        self.supervisor = None  # the node processes' supervisor, when the runner spawned them
        self.evaluator = None  # the runner's evaluator node, when a run scores the graph

    def add(self, node: Node) -> Node:
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def spin_until(self, condition: Callable[[], bool], timeout: float, step: float = 0.01) -> bool:
        """Spin until ``condition()`` holds or ``timeout`` seconds of wall time pass."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=step)
        return True

    def spin_until_quiet(
        self, progress: Callable, quiet: float = 0.02, timeout: float = 1.0, step: float = 0.0
    ) -> bool:
        """Spin until ``progress()`` (e.g. a message count) has not changed for ``quiet``
        seconds, or ``timeout`` seconds pass; it is read after each executor step (at most
        ``step`` s, default quiet / 4)."""
        deadline = time.monotonic() + timeout
        last, since = progress(), time.monotonic()
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=step or quiet / 4)
            now = progress()
            if now != last:
                last, since = now, time.monotonic()
            elif time.monotonic() - since >= quiet:
                return True
        return False

    def close(self) -> None:
        for node in self.nodes:
            self.executor.remove_node(node)
            node.destroy_node()
        self.nodes.clear()
        self.executor.shutdown()
        if self.context.ok():
            rclpy.shutdown(context=self.context)

    def __enter__(self) -> InProcessGraph:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
