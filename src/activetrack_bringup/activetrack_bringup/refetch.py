"""The evaluator fetches a message its reader lost again, from its writer's history.

The graph's per-epoch writers keep the whole run, transient-local, for late joiners
(activetrack_ros.graph): a fresh reader of a topic gets every message published on it so far.
A message the evaluator's reader lost (DDS, or the test hook) is known to be lost once a later
epoch's message came on the same topic (each topic has one writer, which publishes in epoch
order, and delivery is reliable and in order), or, for the last epochs, once the run finished
(the sweeps at the end). For each topic with such a gap the evaluator opens one fresh reader
(never two at once on a topic; each gap tried once, then once more in each sweep: a message
late at its writer may have come since), takes from it only the epochs it lacks, and destroys
it once it has them, once its history stopped coming (REFETCH_QUIET_S after its last sample)
or after REFETCH_S. Counted on the evaluator:
``refetches.<Type>`` (readers opened), ``refetch_unfilled.<Type>`` (a reader that ended
without every epoch it was for), and per sample of the fresh reader ``received.refetched.<Type>``
ending in ``accepted.refetched.<Type>`` (a gap filled) or ``ignored.refetch_known`` (held
already). A message never sent is in no history: the evaluator gives it up (evaluator.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from activetrack_ros.node_base import Rejected

REFETCH_S = 2.0  # the longest a fresh reader waits for its history
REFETCH_QUIET_S = 0.2  # its history came: no sample for this long after one
TICK_S = 0.05  # how often the evaluator looks for gaps and ends fresh readers
# Fresh readers per topic before the final pass: each takes the whole history so far, so a
# graph that leaves gaps all the time (a planner that decides no epoch) is not read over and
# over; later gaps wait for the final pass (counted once: refetch_limit.<Type>).
READERS_PER_TOPIC = 4


@dataclass
class Refetch:
    """One fresh reader of a topic for the epochs ``wanted``."""

    wanted: set[int]
    started: float = field(default_factory=time.monotonic)
    last: float | None = None  # its latest sample
    subscription: object = None

    def ended(self, now: float) -> bool:
        quiet = self.last is not None and now - self.last >= REFETCH_QUIET_S
        return quiet or now - self.started >= REFETCH_S


class Refetcher:
    """The gaps of the evaluator's topics and the fresh readers that fill them.

    ``inputs``: topic -> (message type, callback of the evaluator's reader); ``has(topic, k)``:
    epoch k's messages of the topic are all held; ``last``: topic -> its last epoch."""

    def __init__(self, node, inputs: dict, has: Callable[[str, int], bool], last: dict):
        self.node = node
        self.inputs = inputs
        self.has = has
        self.last = last
        self.newest = dict.fromkeys(inputs, -1)  # newest epoch a message of it came for
        self.checked = dict.fromkeys(inputs, 0)  # epochs below it looked at once
        self.gaps: dict[str, set[int]] = {t: set() for t in inputs}
        self.tried: dict[str, set[int]] = {t: set() for t in inputs}
        self.active: dict[str, Refetch] = {}
        self.filled: set[tuple[str, int]] = set()  # (topic, epoch) a fresh reader filled
        self.opened = dict.fromkeys(inputs, 0)
        self.limited: set[str] = set()  # topics that reached READERS_PER_TOPIC
        self.passes = 0  # sweeps of every epoch still lacking (tick's ``sweeps``) made

    def saw(self, topic: str, epoch: int) -> None:
        """A message of ``topic`` came for ``epoch`` (on the evaluator's own reader)."""
        if epoch > self.newest[topic]:
            self.newest[topic] = epoch

    def filled_before(self, topic: str, epoch: int) -> bool:
        """A fresh reader filled this epoch of the topic: a copy now is no fault."""
        return (topic, epoch) in self.filled

    def busy(self) -> bool:
        return bool(self.active)

    def tick(self, sweeps: int = 0) -> None:
        """End the fresh readers that are done, note new gaps, open readers for untried
        ones; once ``sweeps`` exceeds the sweeps made (the run finished: the evaluator asks
        for one when the sim finished, one when the tracker did), a sweep: every epoch still
        lacking, tried or not."""
        now = time.monotonic()
        for topic, r in list(self.active.items()):
            if all(self.has(topic, k) for k in r.wanted) or r.ended(now):
                self._end(topic, r)
        for topic in self.inputs:
            upto = min(self.newest[topic], self.last[topic] + 1)  # below: the writer moved on
            start, self.checked[topic] = self.checked[topic], max(self.checked[topic], upto)
            self.gaps[topic].update(k for k in range(start, upto) if not self.has(topic, k))
            self.gaps[topic] = {k for k in self.gaps[topic] if not self.has(topic, k)}
        if sweeps > self.passes and not self.active:
            self.passes += 1
            for topic in self.inputs:
                lacking = [k for k in range(self.last[topic] + 1) if not self.has(topic, k)]
                self.gaps[topic].update(lacking)
                self.tried[topic].clear()  # a last try each (a message late at its writer)
        for topic, gaps in self.gaps.items():
            untried = gaps - self.tried[topic]
            if not untried or topic in self.active:
                continue
            if self.opened[topic] >= READERS_PER_TOPIC and not self.passes:
                if topic not in self.limited:
                    self.limited.add(topic)
                    self.node.counters.count(f"refetch_limit.{self.inputs[topic][0].__name__}")
                continue
            self._open(topic, set(gaps))

    def _open(self, topic: str, wanted: set[int]) -> None:
        msg_type, callback = self.inputs[topic]
        name = msg_type.__name__
        r = Refetch(wanted)
        self.tried[topic] |= wanted
        self.opened[topic] += 1
        self.node.counters.count(f"refetches.{name}")

        def take(msg) -> None:
            r.last = time.monotonic()
            if msg.epoch not in r.wanted or self.has(topic, msg.epoch):
                return self.node.ignore("refetch_known")
            try:
                callback(msg)
            except Rejected as exc:
                if exc.reason != "duplicate":  # e.g. another platform's state of the epoch
                    raise
                return self.node.ignore("refetch_known")
            self.filled.add((topic, msg.epoch))

        r.subscription = self.node.subscribe(msg_type, topic, take, label=f"refetched.{name}")
        self.active[topic] = r

    def _end(self, topic: str, r: Refetch) -> None:
        del self.active[topic]
        self.node.destroy_subscription(r.subscription)
        if not all(self.has(topic, k) for k in r.wanted):
            name = self.inputs[topic][0].__name__
            self.node.counters.count(f"refetch_unfilled.{name}")
