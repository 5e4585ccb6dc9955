"""The graph's frame tree (docs/frames.md), as tf2 transforms.

::

    <frame_id>                       fixed frame (parameter, default "world"): x east, y north
    ├── platform/<id>                each platform: x along its heading (REP 103), sim_node
    │   └── sensor/<id>              each sensor, on its platform (tf_static), sim_node
    ├── target/<id>/truth            the simulated target, sim_node (evaluation and views only)
    └── target/<id>/estimate         the track's mean, course from its velocity, tracker_node

Names are relative to the node's namespace only through the topic (``<ns>/tf``): frames do not
carry the namespace, so two graphs in one domain keep separate trees.
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
