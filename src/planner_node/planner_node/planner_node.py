"""planner_node: PCRLB / modified-Riccati manoeuvre planning and sensor selection.

Publishes manoeuvre commands, sensor selections and plan reports. The planning lives in
``activetrack``.
"""

from collections import Counter

import rclpy
from rclpy.node import Node

from activetrack import topics
from msgs_defs.msg import (
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    SensorSelection,
    TrackEstimate,
)


class PlannerNode(Node):
    def __init__(self, **kwargs):
        super().__init__("planner_node", **kwargs)
        self.declare_parameter("cost", "pcrlb")
        self.declare_parameter("horizon", 1)
        self.declare_parameter("search", "quadrant")
        self.command_pub = self.create_publisher(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, 10)
        self.selection_pub = self.create_publisher(SensorSelection, topics.SENSOR_SELECTION, 10)
        self.report_pub = self.create_publisher(PlanReport, topics.PLAN_REPORT, 10)
        self.create_subscription(TrackEstimate, topics.TRACK, self.on_track, 10)
        self.create_subscription(PlatformState, topics.PLATFORM_STATES, self.on_platform, 10)
        self.received = Counter()

    def on_track(self, msg: TrackEstimate) -> None:
        self.received["TrackEstimate"] += 1

    def on_platform(self, msg: PlatformState) -> None:
        self.received["PlatformState"] += 1


def main(args=None):
    rclpy.init(args=args)
    node = PlannerNode()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
