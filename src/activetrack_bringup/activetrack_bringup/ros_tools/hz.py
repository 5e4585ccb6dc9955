"""``activetrack ros hz TOPIC``: the rate messages arrive at, by wall clock, over a sliding
window (the figures ``ros2 topic hz`` prints: average rate, min, max and standard deviation of
the gaps, window size)."""

from __future__ import annotations

import itertools
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from activetrack_bringup.ros_tools.echo import topic_type
from activetrack_bringup.ros_tools.messages import message_type
from activetrack_bringup.ros_tools.session import ToolSession

# Live arrivals only (no latched history), from any publisher (best effort matches all).
HZ_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)


@dataclass(frozen=True)
class Rate:
    """Figures of the gaps between arrivals in a window (seconds)."""

    rate: float
    min_s: float
    max_s: float
    std_s: float
    window: int

    def text(self) -> str:
        return (
            f"average rate: {self.rate:.3f}\n"
            f"\tmin: {self.min_s:.3f}s max: {self.max_s:.3f}s std dev: {self.std_s:.5f}s "
            f"window: {self.window}"
        )


class RateWindow:
    """Arrival times (s) in a window of at most ``size`` gaps."""

    def __init__(self, size: int = 10_000):
        self.times: deque[float] = deque(maxlen=size + 1)
        self.count = 0  # arrivals so far

    def add(self, t: float) -> None:
        self.times.append(t)
        self.count += 1

    def figures(self) -> Rate | None:
        """None until two arrivals; the rate is 1 / mean gap (ros2's)."""
        if len(self.times) < 2:
            return None
        t = list(self.times)
        gaps = [b - a for a, b in itertools.pairwise(t)]
        mean = sum(gaps) / len(gaps)
        std = math.sqrt(sum((g - mean) ** 2 for g in gaps) / len(gaps))
        rate = 1.0 / mean if mean > 0 else math.inf
        return Rate(rate, min(gaps), max(gaps), std, len(gaps))


def hz(
    session: ToolSession,
    topic: str,
    *,
    window: int,
    wait: float,
    duration: float | None,
    out: Callable[[str], None] = print,
) -> Rate | None:
    """Print the figures once a second until ``duration`` seconds passed (or Ctrl-C); return
    the last."""
    name = session.resolve(topic)
    cls = message_type(topic_type(session, name, wait))
    arrivals = RateWindow(window)
    session.node.create_subscription(
        cls, name, lambda _msg: arrivals.add(time.monotonic()), HZ_QOS, raw=True
    )
    end = math.inf if duration is None else time.monotonic() + duration
    last, seen = None, 0
    while time.monotonic() < end:
        session.spin(min(1.0, max(0.0, end - time.monotonic())))
        figures = arrivals.figures()
        if figures is None or arrivals.count == seen:
            out("no new messages")
        else:
            last, seen = figures, arrivals.count
            out(figures.text())
    return last
