"""``activetrack ros echo TOPIC``: each message as YAML, ``---`` after each (as ``ros2 topic
echo``); the type comes from the graph, the QoS adapts to the publishers: reliable if all of
them are, transient-local (their history first, oldest first) if all of them are."""

from __future__ import annotations

from collections.abc import Callable

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from activetrack_bringup.ros_tools.messages import field, message_type, to_plain, to_yaml
from activetrack_bringup.ros_tools.session import ToolError, ToolSession


def topic_type(session: ToolSession, topic: str, wait: float) -> str:
    """The one type of ``topic`` (resolved) once it has a publisher, within ``wait`` s."""

    def published() -> bool:
        return bool(session.node.get_publishers_info_by_topic(topic))

    if not session.spin_until(published, wait):
        raise ToolError(f"no publisher of {topic} appeared within {wait:g} s (--wait)")
    types = sorted({i.topic_type for i in session.node.get_publishers_info_by_topic(topic)})
    if len(types) > 1:
        raise ToolError(f"{topic} has publishers of several types: {types}", 2)
    return types[0]


def adapted_qos(session: ToolSession, topic: str) -> QoSProfile:
    """A reader that matches every publisher of ``topic`` and gets what they keep."""
    offered = [i.qos_profile for i in session.node.get_publishers_info_by_topic(topic)]
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        depth=0,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def echo(
    session: ToolSession,
    topic: str,
    *,
    count: int | None,
    field_path: str | None,
    wait: float,
    duration: float | None,
    out: Callable[[str], None] = print,
) -> int:
    """Print messages of ``topic`` until ``count`` were printed, ``duration`` seconds passed
    or Ctrl-C; returns how many were printed."""
    name = session.resolve(topic)
    type_name = topic_type(session, name, wait)
    cls = message_type(type_name)
    printed = 0

    def on_message(msg) -> None:
        nonlocal printed
        if count is not None and printed >= count:
            return
        data = to_plain(msg)
        if field_path:
            data = field(data, field_path, type_name)
        out(to_yaml(data) + "\n---")
        printed += 1

    session.node.create_subscription(cls, name, on_message, adapted_qos(session, name))
    forever = float("inf")
    session.spin_until(
        lambda: count is not None and printed >= count,
        timeout=forever if duration is None else duration,
    )
    return printed
