"""The one ``main()`` of every node: init, build (bad parameters exit 2), spin, shut down."""

from __future__ import annotations

import sys
from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from activetrack.allocator import tune_allocator
from activetrack.scenarios import ScenarioError


def spin_node(node_class, args=None, done: Callable[[object], bool] | None = None) -> None:
    """Run one node until shutdown or ``done(node)``; exit 2 on bad parameters, unpublished."""
    tune_allocator()  # a node process: numpy temporaries stay on the heap (faster)
    rclpy.init(args=args)
    node = None
    try:
        try:
            node = node_class()
        except (ValueError, ScenarioError) as exc:
            print(f"{node_class.__name__}: error: {exc}", file=sys.stderr)
            rclpy.try_shutdown()
            raise SystemExit(2) from None
        while rclpy.ok() and not (done is not None and done(node)):
            rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass  # stopped while being built or while spinning
    except _rclpy.RCLError:
        if rclpy.ok():  # else SIGTERM shut the context down under the constructor or the wait
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
