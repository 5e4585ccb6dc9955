"""``activetrack ros tf``: the frame tree from ``tf`` and ``tf_static`` (resolved in the
namespace), each frame under its parent with its latest transform (x, y, z and yaw) and its
age: how far its stamp lies behind the graph's latest time (``clock`` if published, else the
newest stamp seen); static transforms have no age."""

from __future__ import annotations

import math
from dataclasses import dataclass

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from activetrack_bringup.ros_tools.messages import message_type
from activetrack_bringup.ros_tools.session import ToolError, ToolSession

TF_TYPE = "tf2_msgs/msg/TFMessage"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
_KEEP = dict(history=HistoryPolicy.KEEP_ALL, depth=0, reliability=ReliabilityPolicy.RELIABLE)
STATIC_QOS = QoSProfile(durability=DurabilityPolicy.TRANSIENT_LOCAL, **_KEEP)  # as tf2's
DYNAMIC_QOS = QoSProfile(durability=DurabilityPolicy.VOLATILE, **_KEEP)


def stamp_s(stamp) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


@dataclass
class Link:
    """The latest transform parent -> child."""

    parent: str
    child: str
    x: float
    y: float
    z: float
    yaw: float  # rad, about z (from the quaternion)
    stamp: float  # s
    static: bool

    @classmethod
    def of(cls, t, static: bool) -> Link:
        q, p = t.transform.rotation, t.transform.translation
        yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        return cls(t.header.frame_id, t.child_frame_id, p.x, p.y, p.z, yaw,
                   stamp_s(t.header.stamp), static)  # fmt: skip


class TfListener:
    """Collects the latest transform per child frame and the latest clock."""

    def __init__(self, session: ToolSession):
        self.links: dict[str, Link] = {}
        self.clock: float | None = None
        cls = message_type(TF_TYPE)
        node = session.node
        node.create_subscription(cls, session.resolve("tf"), self._take(False), DYNAMIC_QOS)
        node.create_subscription(cls, session.resolve("tf_static"), self._take(True), STATIC_QOS)
        node.create_subscription(
            message_type(CLOCK_TYPE), session.resolve("clock"), self._on_clock, DYNAMIC_QOS
        )

    def _take(self, static: bool):
        def on_tf(msg) -> None:
            for t in msg.transforms:
                old = self.links.get(t.child_frame_id)
                link = Link.of(t, static)
                if old is None or static or link.stamp >= old.stamp:
                    self.links[t.child_frame_id] = link

        return on_tf

    def _on_clock(self, msg) -> None:
        self.clock = max(self.clock or 0.0, stamp_s(msg.clock))

    @property
    def now(self) -> float | None:
        """The graph's latest time: its clock, else the newest stamp of a moving frame."""
        if self.clock is not None:
            return self.clock
        stamps = [link.stamp for link in self.links.values() if not link.static]
        return max(stamps) if stamps else None


def tree_text(links: dict[str, Link], now: float | None) -> str:
    """The tree, roots first, children sorted, drawn with box characters."""
    children: dict[str, list[str]] = {}
    for link in links.values():
        children.setdefault(link.parent, []).append(link.child)
    roots = sorted(set(children) - set(links))
    lines: list[str] = []

    def draw(frame: str, prefix: str, last: bool, depth: int) -> None:
        link = links.get(frame)
        branch = "" if depth == 0 else ("└── " if last else "├── ")
        lines.append(f"{prefix}{branch}{frame}{_link_text(link, now)}")
        below = sorted(children.get(frame, ()))
        inner = prefix if depth == 0 else prefix + ("    " if last else "│   ")
        for i, child in enumerate(below):
            draw(child, inner, i == len(below) - 1, depth + 1)

    for root in roots:
        draw(root, "", True, 0)
    return "\n".join(lines)


def _link_text(link: Link | None, now: float | None) -> str:
    if link is None:
        return ""
    where = f"x {link.x:.3f} y {link.y:.3f} z {link.z:.3f} m, yaw {math.degrees(link.yaw):.2f} deg"
    if link.static:
        return f"  ({where}; static)"
    age = f", age {now - link.stamp:.3f} s" if now is not None else ""
    return f"  ({where}; stamp {link.stamp:.3f} s{age})"


def tf(session: ToolSession, duration: float) -> tuple[dict[str, Link], float | None]:
    """Listen for ``duration`` seconds; the links and the graph's time (ToolError if no
    transform arrived)."""
    listener = TfListener(session)
    session.spin(duration)
    if not listener.links:
        raise ToolError(
            f"no transform on {session.resolve('tf')} or {session.resolve('tf_static')} "
            f"within {duration:g} s (--duration)"
        )
    return listener.links, listener.now
