"""Counters of what a node received, rejected (by reason), clamped or timed out.

Kept ROS-free: the nodes turn ``as_pairs()`` into a diagnostic_msgs/DiagnosticStatus.
"""

from __future__ import annotations

from collections import Counter


class NodeCounters:
    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def received(self, what: str) -> None:
        self.counts[f"received.{what}"] += 1

    def rejected(self, reason: str) -> None:
        self.counts[f"rejected.{reason}"] += 1

    def count(self, what: str, n: int = 1) -> None:
        self.counts[what] += n

    def total(self, prefix: str) -> int:
        """Sum of the counters whose name starts with ``prefix`` (e.g. ``"foreign."``)."""
        return sum(v for k, v in self.counts.items() if k.startswith(prefix))

    @property
    def total_rejected(self) -> int:
        return self.total("rejected.")

    def as_pairs(self) -> list[tuple[str, str]]:
        return [(k, str(v)) for k, v in sorted(self.counts.items())]
