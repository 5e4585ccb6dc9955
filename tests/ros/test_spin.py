"""``spin_node``, the one ``main()`` of every node process: a node stopped while it is still being
built (a SIGTERM from the runner early in a run shuts the context down under its constructor)
exits quietly, as one stopped while it spins does."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.ros

SCRIPT = textwrap.dedent(
    """
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import Header

    from activetrack_ros.spin import spin_node


    class StoppedWhileBuilt(Node):
        def __init__(self):
            super().__init__("stopped_while_built")
            rclpy.shutdown()  # what rclpy's SIGTERM handler does, here mid-constructor
            self.create_publisher(Header, "stopped_while_built", 1)


    spin_node(StoppedWhileBuilt)
    print("returned")
    """
)


def test_a_node_stopped_while_it_is_built_exits_quietly():
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "returned"
    assert "Traceback" not in proc.stderr, proc.stderr
