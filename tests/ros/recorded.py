"""What a recorded bag holds, read back with rclpy for the tests' checks."""

from __future__ import annotations

from rclpy.serialization import deserialize_message

from activetrack_bringup.bag import bag_topic
from activetrack_bringup.bag_io import open_bag


def read_topic(bag, topic: str, msg_type) -> list:
    """Every message of one topic of a bag, deserialized (rclpy, exact); ``topic`` as the bag
    names it or a graph topic under any namespace (BagError when several namespaces hold it)."""
    with open_bag(bag) as b:
        name = bag_topic(b, topic)
        if name is None:
            return []
        return [deserialize_message(d, msg_type) for _, _, d in b.messages([name])]
