"""The graph's frame tree as tf2 transforms: ``platform/<id>`` and its ``sensor/<id>``,
``target/<id>/truth`` and ``target/<id>/estimate`` under the fixed frame (docs/frames.md).
Frames carry no namespace: two graphs in one domain keep separate trees on their own ``tf``.
"""

from __future__ import annotations

import math

from geometry_msgs.msg import TransformStamped
from std_msgs.msg import Header


def platform_frame(platform_id: str) -> str:
    return f"platform/{platform_id}"


def sensor_frame(sensor_id: str) -> str:
    return f"sensor/{sensor_id}"


def truth_frame(target_id: str) -> str:
    return f"target/{target_id}/truth"


def estimate_frame(target_id: str) -> str:
    return f"target/{target_id}/estimate"


def planar_transform(hdr: Header, child: str, x: float, y: float, yaw: float) -> TransformStamped:
    """``hdr.frame_id`` -> ``child``: a translation in the plane and a rotation ``yaw`` (rad,
    counter-clockwise from +x) about z."""
    t = TransformStamped(header=hdr, child_frame_id=child)
    t.transform.translation.x = float(x)
    t.transform.translation.y = float(y)
    t.transform.rotation.z = math.sin(yaw / 2)
    t.transform.rotation.w = math.cos(yaw / 2)
    return t
