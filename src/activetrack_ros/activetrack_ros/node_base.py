"""The base of every activetrack node: trusted writers only, callbacks that never raise, exact
counters and rate-limited logs.

Every message a subscription takes ends in exactly one counter (docs/robustness.md):
``foreign.<Type>`` (a writer outside the graph, or bigger than any of the graph's messages of
its type: dropped before deserialisation), ``rejected.<reason>`` (the callback raised
:class:`Rejected`, or the header names another frame than the node's ``frame_id``),
``ignored.<reason>`` (valid but not needed), ``errors.<callback>`` (an unexpected exception,
logged with its traceback; the node keeps running) or ``accepted.<Type>`` (taken). So for every
node ``received`` = ``accepted`` + ``rejected`` + ``ignored`` + ``foreign`` + ``errors`` (each
summed over its names; :func:`unaccounted`). A message taken and found invalid later (a scan
not where its platform's state, which came after it, says) moves from ``accepted`` to its
reason (:meth:`GraphNode.reject_taken`). ``dropped.<Type>`` and ``incompatible_writers.<Type>``
count DDS's events: samples that never reached the node.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header

from activetrack.closed_loop.counters import NodeCounters
from activetrack_ros import graph, inject, params, sizes
from activetrack_ros.trust import GraphKey, is_signed_type

# Samples one subscription takes per executor step: draining a flooded reader in batches
# instead of one wait-set round per sample; bounded so the other readers and timers (and a
# Ctrl-C) get their turn.
TAKE_BATCH = 64
REPUBLISH_S = 0.25  # s without a publication after which changed counters are published again


class Rejected(Exception):
    """Raised by a callback for invalid input: counted as ``rejected.<reason>``."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail


class RateLimitedLog:
    """At most one line per key and ``interval`` seconds, saying how many were held back: a
    flood must not become a log flood (the counters stay exact)."""

    def __init__(self, logger, interval: float = 1.0):
        self.logger = logger
        self.interval = interval
        self._last: dict[str, float] = {}
        self._held: dict[str, int] = {}

    def __call__(self, level: str, key: str, text: str) -> None:
        now = time.monotonic()
        if now - self._last.get(key, -float("inf")) < self.interval:
            self._held[key] = self._held.get(key, 0) + 1
            return
        held = self._held.pop(key, 0)
        self._last[key] = now
        suffix = f" (and {held} more like it in the last {self.interval:g} s)" if held else ""
        # One call site per severity: rclpy's logger refuses a severity change at one site.
        if level == "error":
            self.logger.error(text + suffix)
        else:
            self.logger.warning(text + suffix)


class GraphPublisher:
    """A publisher that signs msgs_defs messages with the graph's key (if it has one)."""

    def __init__(self, node: GraphNode, msg_type, topic: str, key: GraphKey | None, depth=None):
        self.publisher = node.create_publisher(msg_type, topic, graph.writer_qos(topic, depth))
        self.key = key if is_signed_type(msg_type) else None
        self.is_diagnostics = msg_type is DiagnosticArray
        self.graph_key = key
        self.inject = inject.injector(node, inject.PUBLISH, topic, node.injections)

    def has_readers(self) -> bool:
        """Some subscription (in this process or another) matches the topic now: a view on a
        volatile topic that nobody reads need not be built (a reader that joins later gets
        the next one, as it would anyway)."""
        return self.publisher.get_subscription_count() > 0

    def publish(self, msg) -> None:
        if self.key is not None:
            data = self.key.sign(serialize_message(msg))
            if self.inject is not None:  # a test's delay or drop (activetrack_ros.inject)
                return self.inject(lambda: self.publisher.publish(data))
            self.publisher.publish(data)
            return
        if self.is_diagnostics and self.graph_key is not None:
            self.graph_key.sign_diagnostics(msg)
        self.publisher.publish(msg)


class GraphNode(Node):
    """rclpy Node with the graph's trust filter, guarded callbacks and exact counters.

    ``graph_key``: the run's key; None takes ``ACTIVETRACK_GRAPH_KEY`` from the environment, and
    with neither the node trusts every writer (a node started on its own, for a user's tools).
    """

    def __init__(self, node_name: str, *, graph_key: GraphKey | None = None, **kwargs):
        super().__init__(node_name, **kwargs)
        self.role = node_name  # its diagnostics' name, whatever the node is remapped to
        params.fix_use_sim_time(self)
        self.graph_key = graph_key if graph_key is not None else GraphKey.from_environment()
        self.counters = NodeCounters()
        self.log_limited = RateLimitedLog(self.get_logger())
        self.inputs: dict[str, str] = {}  # message type name -> topic subscribed
        self.frame_id = graph.FIXED_FRAME
        self.mode: str | None = None  # lockstep | free (None: a node without a mode parameter)
        self.history_depth: int | None = None  # per-epoch writers' depth (size_history)
        # (not "faults": the evaluator's are the invalid messages of the graph it saw)
        self.injections = inject.from_environment()  # a test's delays and drops; normally none
        self.byte_limits: dict[str, int] = {}  # type name -> most bytes (sizes, size_history)
        self._republish = None  # the timer of publish_diagnostics, from its first call
        self._last_diagnostics: tuple | None = None
        self._diagnostics_readers = 0  # matched readers of /diagnostics at the last publication
        self._published: dict = {}
        self._newest_input = (0, 0)  # stamp (sec, nanosec) of the newest message accepted

    def declare_params(
        self, specs: tuple[params.ParamSpec, ...], apply=None, *, last: bool = True
    ) -> dict:
        """Declare the node's parameters (activetrack_ros.params) and take its frame_id and
        mode; ``apply``: name -> callable for those a running node can change. Returns the
        values (ValueError on a bad one). ``last``: report unknown overrides now."""
        values = params.declare(self, specs)
        params.on_change(self, specs, {} if apply is None else apply)
        if last:
            params.warn_unknown(self)
        self.frame_id = values.get("frame_id", self.frame_id)
        self.mode = values.get("mode", self.mode)
        return values

    def use_scenario(self, scenario) -> None:
        """Take the node's scenario: size the per-epoch histories for it, publish diagnostics."""
        self.scenario = scenario
        self.size_history(scenario)
        self.diag_pub = self.publisher(DiagnosticArray, graph.DIAGNOSTICS)

    def setter(self, attribute: str) -> Callable:
        """The ``apply`` entry (declare_params) of a parameter the node keeps in ``attribute``."""
        return lambda value: setattr(self, attribute, value)

    def size_history(self, scenario) -> None:
        """Per-epoch writers keep the whole run for late joiners; a run too long says so."""
        self.history_depth = graph.history_depth(scenario)
        self.byte_limits = sizes.max_bytes(scenario)
        most = graph.run_history(scenario)
        if most > self.history_depth:
            self.get_logger().warning(
                f"the run has {most} per-epoch messages per topic at most; writers keep the "
                f"last {self.history_depth}: a late joiner misses the start"
            )

    def subscribe(self, msg_type, topic: str, callback: Callable, *, label: str | None = None):
        """Subscribe with the graph's reader QoS; ``callback(msg)`` may raise Rejected. Returns
        the subscription. ``label``: a second reader of the topic (the evaluator's refetch)
        counts under its own name (``received.<label>``...) and no test hook drops its
        messages (a fresh reader has not lost what the first one did)."""
        name = msg_type.__name__

        def on_trusted(data: bytes, msg) -> None:
            if msg is None:
                try:
                    msg = deserialize_message(data, msg_type)
                except Exception as exc:  # a raw writer can send any bytes
                    raise_interrupt_inside(exc)  # a Ctrl-C inside the C decoder: not the bytes'
                    return self.reject("undecodable", f"{name} on {topic}")
            frame = getattr(getattr(msg, "header", None), "frame_id", self.frame_id)
            if frame != self.frame_id:  # e.g. a driver in "map" feeding a graph in "world"
                return self.reject(
                    "wrong_frame", f"{name} on {topic} in frame {frame!r}, not {self.frame_id!r}"
                )
            outcomes = self.counters.outcomes
            self.guarded(callback, msg)
            stamp = getattr(getattr(msg, "header", None), "stamp", None)
            if (
                self.counters.outcomes == outcomes and stamp is not None
            ):  # accepted: the graph's time
                self._newest_input = max(self._newest_input, (stamp.sec, stamp.nanosec))

        return self._subscribe_trusted(msg_type, topic, on_trusted, label)

    def subscribe_raw(self, msg_type, topic: str, callback: Callable[[bytes], None]) -> None:
        """Like :meth:`subscribe` for a node that passes the bytes on (the live view):
        ``callback(data)`` gets the graph's own messages, undecoded, counted and guarded."""
        self._subscribe_trusted(msg_type, topic, lambda data, _: self.guarded(callback, data))

    def _subscribe_trusted(self, msg_type, topic: str, on_trusted: Callable, label=None):
        """A raw subscription counting every sample and DDS event, dropping a foreign writer's;
        ``on_trusted(data, msg)`` gets the rest (``msg``: decoded if the check had to, or None).
        ``label``: see :meth:`subscribe`."""
        kind = msg_type.__name__  # its byte limit
        name = label or kind  # its counters
        if label is None:
            self.inputs[name] = topic
        key = self.graph_key
        check = None if key is None else graph_check(key, msg_type)
        hook = None
        if self.injections and label is None:
            hook = inject.injector(self, self.role, topic, self.injections)

        def take(data: bytes, msg) -> None:
            outcomes = self.counters.outcomes
            on_trusted(data, msg)
            if self.counters.outcomes == outcomes:
                self.counters.count(f"accepted.{name}")

        def on_raw(data: bytes) -> None:
            self.counters.received(name)
            if len(data) > self.byte_limits.get(kind, len(data)):  # not worth a hash
                if key is not None:
                    return self._foreign(name, topic)
                return self.reject("too_large", f"{name} on {topic}: {len(data)} bytes")
            msg, ok = None, True
            if check is not None:
                ok, msg = check(data)
            if not ok:
                return self._foreign(name, topic)
            if hook is not None:  # a test's delay or drop (activetrack_ros.inject)
                return hook(lambda: take(data, msg))
            take(data, msg)

        events = SubscriptionEventCallbacks(
            message_lost=lambda info: self._lost(name, info),
            incompatible_qos=lambda info: self._incompatible(name, topic, info),
        )
        return subscribe_batched(self, msg_type, topic, on_raw, events)

    def _foreign(self, name: str, topic: str) -> None:
        self.counters.count(f"foreign.{name}")
        self.log_limited(
            "warning",
            f"foreign.{name}",
            f"dropped {name} on {topic} from a writer outside the graph",
        )

    def _lost(self, name: str, info) -> None:
        self.counters.count(f"dropped.{name}", info.total_count_change)
        self.log_limited("warning", f"dropped.{name}", f"DDS lost {name} samples")

    def _incompatible(self, name: str, topic: str, info) -> None:
        self.counters.count(f"incompatible_writers.{name}", info.total_count_change)
        self.log_limited(
            "warning",
            f"incompatible.{name}",
            f"a writer on {topic} offers QoS this graph cannot accept (policy id "
            f"{info.last_policy_kind}); its messages never reach this node",
        )

    def guarded(self, callback: Callable, *args) -> None:
        """Run a callback at the boundary: Rejected is counted, anything else too, never raised."""
        try:
            callback(*args)
        except Rejected as r:
            self.reject(r.reason, r.detail)
        except Exception as exc:
            raise_interrupt_inside(exc)  # before anything is counted: a Ctrl-C is no error
            if not self.context.ok():  # shutting down (SIGTERM): publishing fails, as it may
                return
            where = getattr(callback, "__name__", "callback")
            self.counters.count(f"errors.{where}")
            self.log_limited(
                "error",
                f"errors.{where}",
                f"unexpected {type(exc).__name__} in {where} (counted, node keeps running):\n"
                + traceback.format_exc(),
            )

    def reject(self, reason: str, detail: str) -> None:
        """Count the message at hand as rejected (a callback may raise Rejected instead)."""
        self.counters.rejected(reason)
        self.log_limited("warning", f"rejected.{reason}", f"rejected {reason}: {detail}")

    def ignore(self, reason: str) -> None:
        """Count the message at hand as valid but not needed."""
        self.counters.count(f"ignored.{reason}")

    def reject_taken(self, type_name: str, reason: str, detail: str) -> None:
        """A message of type ``type_name`` accepted earlier turns out invalid (e.g. a scan not
        where its platform's state, which came after it, says): it moves from ``accepted`` to
        ``rejected.<reason>``, whichever message's callback finds it out."""
        self.counters.move(f"accepted.{type_name}", f"rejected.{reason}")
        self.log_limited("warning", f"rejected.{reason}", f"rejected {reason}: {detail}")

    def ignore_taken(self, type_name: str, reason: str, n: int = 1) -> None:
        """``n`` messages of type ``type_name`` accepted earlier are let go unused (e.g.
        evicted from a bounded buffer): they move from ``accepted`` to ``ignored.<reason>``."""
        self.counters.move(f"accepted.{type_name}", f"ignored.{reason}", n)

    def guarded_timer(self, period: float, callback: Callable):
        return self.create_timer(period, lambda: self.guarded(callback))

    def publisher(self, msg_type, topic: str) -> GraphPublisher:
        return GraphPublisher(self, msg_type, topic, self.graph_key, self.history_depth)

    def publish_diagnostics(self, header: Header, message: str) -> None:
        """Publish the node's counters as status ``activetrack/<node>`` (WARN once rejecting).
        Counters that change afterwards (messages after the last epoch, a flood) are published
        again with the same message once the node has published nothing for REPUBLISH_S (a node
        in its own process reports its final counts to the runner), and so are unchanged ones
        once a reader matched since the last publication; stamped with the newest input the
        node accepted if that is later (a recorder logs it near that time)."""
        if self._republish is None:
            self._republish = self.create_timer(REPUBLISH_S, self._republish_changed)
        self._last_diagnostics = (header, message, time.monotonic())
        self._published = dict(self.counters.counts)
        self._diagnostics_readers = self.diag_pub.publisher.get_subscription_count()
        warn = self.counters.total_rejected or self.counters.total("errors.")
        status = DiagnosticStatus(
            level=DiagnosticStatus.WARN if warn else DiagnosticStatus.OK,
            name=f"activetrack/{self.role}",
            hardware_id=self.scenario.name,
            message=message,
            values=[KeyValue(key=k, value=v) for k, v in self.counters.as_pairs()],
        )
        self.diag_pub.publish(DiagnosticArray(header=header, status=[status]))

    def _republish_changed(self) -> None:
        header, message, when = self._last_diagnostics
        idle = time.monotonic() - when >= REPUBLISH_S
        # A reader that matched since (the runner's, between processes, after a short run's
        # last epoch: /diagnostics is a stream) has not seen the counts: they go again.
        joined = self.diag_pub.publisher.get_subscription_count() > self._diagnostics_readers
        if idle and (joined or self.counters.counts != self._published):
            sec, nanosec = max(self._newest_input, (header.stamp.sec, header.stamp.nanosec))
            stamp = Time(sec=sec, nanosec=nanosec)
            self.guarded(
                self.publish_diagnostics, Header(stamp=stamp, frame_id=header.frame_id), message
            )


def subscribe_batched(node: Node, msg_type, topic: str, on_raw: Callable, events=None):
    """A raw subscription with the graph's reader QoS whose callback ``on_raw(data)`` runs for
    the sample the executor took and up to TAKE_BATCH - 1 more already queued: an executor
    step (a wait-set round) per sample costs ten times more than dropping a foreign one
    (measured in docs/robustness.md), and a reader served one sample a round falls behind
    the readers served in batches."""

    def on_ready(data: bytes) -> None:
        on_raw(data)
        for _ in range(TAKE_BATCH - 1):
            with sub.handle:
                taken = sub.handle.take_message(msg_type, True)
            if taken is None:
                return
            on_raw(taken[0])

    qos = graph.reader_qos(topic)
    sub = node.create_subscription(msg_type, topic, on_ready, qos, raw=True, event_callbacks=events)
    return sub


OUTCOMES = ("accepted.", "rejected.", "ignored.", "foreign.", "errors.")


def unaccounted(counts: dict) -> int:
    """Messages a node received that no outcome counter holds: ``received`` minus the sum of
    ``accepted``, ``rejected``, ``ignored``, ``foreign`` and ``errors`` (each over its names);
    0 for every node (a test checks it under floods)."""
    total = lambda prefix: sum(int(v) for k, v in counts.items() if k.startswith(prefix))  # noqa: E731
    return total("received.") - sum(total(p) for p in OUTCOMES)


def graph_check(key: GraphKey, msg_type) -> Callable[[bytes], tuple[bool, object]] | None:
    """The check of a reader of ``msg_type`` on a topic the graph's key covers, chosen once per
    reader: ``check(data) -> (from the graph, the message if decoding was needed)``; a signed
    type by its trailing tag, a DiagnosticArray by the tag inside it (decoded for that; bytes
    that do not decode carry no tag); None for any other type (trusted). A Ctrl-C inside the
    C decoder is raised, not counted as foreign. The nodes' readers and the recorder
    (``activetrack_bringup.bag``) both take their check here."""
    if is_signed_type(msg_type):
        return lambda data: (key.verify(data), None)
    if msg_type is not DiagnosticArray:
        return None

    def diagnostics(data: bytes) -> tuple[bool, object]:
        try:
            msg = deserialize_message(data, msg_type)
        except Exception as exc:  # no tag can be read from it: not the graph's
            raise_interrupt_inside(exc)
            return False, None
        return key.verify_diagnostics(msg), msg

    return diagnostics


def raise_interrupt_inside(exc: BaseException) -> None:
    """Raise the Ctrl-C (KeyboardInterrupt, SystemExit or the runner's SIGTERM) that ``exc``
    wraps, if any; callers of code that may wrap it (a numba kernel, the C message decoder)
    call this first in their ``except Exception``."""
    interrupt = _interrupt_inside(exc)
    if interrupt is not None:
        raise interrupt from None


def _interrupt_inside(exc: BaseException) -> BaseException | None:
    """The KeyboardInterrupt or SystemExit that ``exc`` wraps, if any: a signal handler that
    raises while a compiled function (a numba kernel) runs surfaces as a SystemError ("returned
    a result with an exception set") chained to the handler's exception."""
    seen: set[int] = set()
    cause: BaseException | None = exc
    while cause is not None and id(cause) not in seen:
        if not isinstance(cause, Exception):
            return cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None
