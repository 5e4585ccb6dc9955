"""sim_node: simulated target(s) and sensor platforms.

Publishes platform states, bearing and polar measurements and ground truth; listens to
manoeuvre commands and sensor selections. The simulation itself lives in ``activetrack``.
"""

from collections import Counter

import rclpy
from rclpy.node import Node

from activetrack import topics
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    ManoeuvreCommand,
    PlatformState,
    PolarMeasurement,
    SensorSelection,
)


class SimNode(Node):
    def __init__(self, **kwargs):
        super().__init__("sim_node", **kwargs)
        self.declare_parameter("scenario", "")
        self.platform_pub = self.create_publisher(PlatformState, topics.PLATFORM_STATES, 10)
        self.bearing_pub = self.create_publisher(
            BearingMeasurement, topics.BEARING_MEASUREMENTS, 10
        )
        self.polar_pub = self.create_publisher(PolarMeasurement, topics.POLAR_MEASUREMENTS, 10)
        self.truth_pub = self.create_publisher(GroundTruth, topics.GROUND_TRUTH, 10)
        self.create_subscription(ManoeuvreCommand, topics.MANOEUVRE_COMMANDS, self.on_command, 10)
        self.create_subscription(SensorSelection, topics.SENSOR_SELECTION, self.on_selection, 10)
        self.received = Counter()

    def on_command(self, msg: ManoeuvreCommand) -> None:
        self.received["ManoeuvreCommand"] += 1

    def on_selection(self, msg: SensorSelection) -> None:
        self.received["SensorSelection"] += 1


def main(args=None):
    rclpy.init(args=args)
    node = SimNode()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
