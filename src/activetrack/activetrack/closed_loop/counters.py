"""Counters of what a node received, rejected (by reason), clamped or timed out.

Kept ROS-free: the nodes turn ``as_pairs()`` into a diagnostic_msgs/DiagnosticStatus.
"""

from __future__ import annotations

from collections import Counter

OUTCOME_PREFIXES = ("rejected.", "ignored.", "errors.")  # a message's end other than accepted


class NodeCounters:
    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()
        self.outcomes = 0  # counts added under OUTCOME_PREFIXES (a message's end)

    def received(self, what: str) -> None:
        self.counts[f"received.{what}"] += 1

    def rejected(self, reason: str) -> None:
        self.counts[f"rejected.{reason}"] += 1
        self.outcomes += 1

    def count(self, what: str, n: int = 1) -> None:
        self.counts[what] += n
        if what.startswith(OUTCOME_PREFIXES):
            self.outcomes += n

    def move(self, source: str, target: str, n: int = 1) -> None:
        """``n`` from counter ``source`` to ``target`` (a message taken, later rejected)."""
        self.counts[source] -= n
        self.counts[target] += n

    def total(self, prefix: str) -> int:
        """Sum of the counters whose name starts with ``prefix`` (e.g. ``"foreign."``)."""
        return sum(v for k, v in self.counts.items() if k.startswith(prefix))

    @property
    def total_rejected(self) -> int:
        return self.total("rejected.")

    def as_pairs(self) -> list[tuple[str, str]]:
        return [(k, str(v)) for k, v in sorted(self.counts.items())]
