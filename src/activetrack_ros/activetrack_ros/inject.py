"""A test hook: delay or drop one of the graph's own messages, at its writer or at one reader.

Off unless ``ACTIVETRACK_INJECT`` is set (read when a node starts; node processes inherit it).
Its value is a comma-separated list of ``<at>:<topic>#<n>=<action>``:

- ``at``: ``publish`` (the writer: every reader gets it late, or nobody gets it) or a node's
  role (``sim``, ``tracker``, ``planner``, ``activetrack_evaluator``...): that reader only,
  as if its reader had lost the message (the writer's history keeps it);
- ``topic``: a graph topic (``activetrack/scans``); ``n``: the n-th (from 1) message of the
  graph's own on it that this end sees (a writer: publishes; a reader: takes with a valid tag);
- ``action``: ``drop``, or ``delay:<seconds>`` (sent on by a one-shot timer of the node).

``ACTIVETRACK_INJECT="publish:activetrack/scans#5=delay:2.0,tracker:activetrack/tracks#3=drop"``.
Each injection is counted at its end (``injected.drop.<topic>``, ``injected.delay.<topic>``);
a message dropped at a reader also ends in ``ignored.injected``, its outcome.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass

ENV = "ACTIVETRACK_INJECT"
PUBLISH = "publish"
_SPEC = re.compile(r"(?P<at>[\w]+):(?P<topic>[\w/]+)#(?P<n>\d+)=(?P<action>drop|delay:[\d.eE+-]+)")


@dataclass(frozen=True)
class Fault:
    at: str  # PUBLISH or a reader's role
    topic: str
    n: int  # the n-th message (from 1)
    delay: float | None  # seconds; None: dropped


def parse(text: str) -> list[Fault]:
    """The faults of an ``ACTIVETRACK_INJECT`` value; ValueError naming a malformed item."""
    faults = []
    for item in filter(None, (s.strip() for s in text.split(","))):
        m = _SPEC.fullmatch(item)
        if m is None or int(m["n"]) < 1:
            raise ValueError(
                f"{ENV}: {item!r} is not <at>:<topic>#<n>=drop|delay:<seconds> with n >= 1"
            )
        action = m["action"]
        delay = None if action == "drop" else float(action.removeprefix("delay:"))
        if delay is not None and not (math.isfinite(delay) and 0 <= delay <= 3600):
            raise ValueError(f"{ENV}: {item!r}: the delay must be in [0, 3600] s")
        faults.append(Fault(m["at"], m["topic"], int(m["n"]), delay))
    return faults


def from_environment() -> list[Fault]:
    return parse(os.environ.get(ENV, ""))


def matches(at: str, role: str) -> bool:
    """A fault's ``at`` names this end: ``publish``, or the role with or without ``_node``."""
    return at in (role, role.removesuffix("_node"))


class Injector:
    """Counts the messages one end sees on one topic and sends each now, later or never."""

    def __init__(self, node, topic: str, faults: list[Fault], reader: bool = False):
        self.node = node
        self.topic = topic
        self.reader = reader  # a reader's drop is also its message's outcome (ignored.injected)
        self.faults = {f.n: f for f in faults}
        self.seen = 0

    def __call__(self, send: Callable[[], None]) -> None:
        self.seen += 1
        fault = self.faults.get(self.seen)
        if fault is None:
            return send()
        if fault.delay is None:
            self.node.counters.count(f"injected.drop.{self.topic}")
            if self.reader:  # received, so it ends in one outcome counter like any other
                self.node.counters.count("ignored.injected")
            return None
        self.node.counters.count(f"injected.delay.{self.topic}")
        timer = None

        def fire() -> None:
            self.node.destroy_timer(timer)
            send()

        timer = self.node.guarded_timer(fault.delay, fire)
        return None


def injector(node, at: str, topic: str, faults: list[Fault]) -> Injector | None:
    """The hook for one end (``at``: PUBLISH or the reader's role) of ``topic``, or None."""
    mine = [f for f in faults if f.topic == topic and matches(f.at, at)]
    return Injector(node, topic, mine, reader=at != PUBLISH) if mine else None
