"""Traffic from outside the graph, for the robustness tests and the foreign-traffic benchmark.

A :class:`ForeignNode` joins a running graph like any other node on the domain would: it
listens to the graph's topics (as a sniffer would, to make plausible messages from genuine
ones), and when the track of a chosen epoch appears it publishes categories of hostile
traffic (:data:`CATEGORIES`): malformed fields, plausible forgeries, replays of genuine
messages, raw garbage bytes and floods. With ``sign=`` it signs its messages with the graph's
key, i.e. plays a buggy member of the graph: then validation, not authentication, must stop
the invalid categories. It counts what it sent per message type, so a test can check that
the graph's counters account for every message.
"""

from __future__ import annotations

import copy
import json
import math
import random
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from message_examples import TOPIC_OF as MESSAGE_TOPIC_OF
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message

from activetrack_ros import graph as topics
from activetrack_ros.convert import MAX_SCAN_DETECTIONS, header
from activetrack_ros.trust import GraphKey, is_signed_type
from msgs_defs.msg import (
    BeamCommand,
    GroundTruthArray,
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    Scan,
    SensorSelection,
    TrackArray,
)

# Every topic the graph reads: the msgs_defs ones and /diagnostics.
TOPIC_OF = {**MESSAGE_TOPIC_OF, DiagnosticArray: topics.DIAGNOSTICS}

# Which of the graph's readers take each type (the runner's evaluator included; the recorder,
# which only stores bytes, not): what a foreign message on that type's topic must be counted by.
READERS = {
    "Scan": ("tracker", "evaluator"),
    "PlatformState": ("tracker", "planner", "evaluator"),
    "TrackArray": ("sim", "planner", "evaluator"),
    "ManoeuvreCommand": ("sim", "evaluator"),  # the evaluator draws the planned legs
    "BeamCommand": ("sim", "evaluator"),
    "SensorSelection": ("sim", "evaluator"),
    "PlanReport": ("evaluator",),
    "GroundTruthArray": ("evaluator",),
    "DiagnosticArray": ("evaluator",),
}


def uncounted(diagnostics: dict, sent: Counter, sent_signed: Counter) -> int:
    """Foreign messages some reader did not count (as foreign, or as lost by DDS): must be 0."""
    missing = 0
    for name, readers in READERS.items():
        unsigned = sent[name] - sent_signed[name]
        for node in readers:
            counts = diagnostics.get(node, {})
            seen = counts.get(f"foreign.{name}", 0) + counts.get(f"dropped.{name}", 0)
            missing += max(0, unsigned - seen)
    return missing


@dataclass
class Context:
    """What a category builds from: the genuine messages seen last, per type, and the epoch."""

    epoch: int
    dt: float
    latest: dict  # message type -> the last genuine message of it
    seen: dict  # message type -> every genuine raw message (replays)
    rng: random.Random

    def like(self, msg_type, **changes):
        """A copy of the latest genuine message of a type with some fields changed; a field's
        path is its names joined by ``__``, a number indexing a sequence
        (``tracks__0__state``)."""
        msg = copy.deepcopy(self.latest[msg_type])
        for path, value in changes.items():
            target = msg
            *parents, name = path.split("__")
            for p in parents:
                target = target[int(p)] if p.isdigit() else getattr(target, p)
            setattr(target, name, value)
        return msg

    def stamp(self, epoch: int):
        t = epoch * self.dt
        return {"header__stamp__sec": int(t), "header__stamp__nanosec": round((t % 1) * 1e9)}


@dataclass(frozen=True)
class Category:
    name: str
    msg_type: type
    build: Callable[[Context, type], list]  # -> messages (or raw bytes, published as such)
    plausible: bool = False  # well-formed: only authentication can tell it from the graph's


def _next(**changes):
    """The latest genuine message of the type, moved to the epoch after both its own and the
    firing one (stamp too), changed. Not merely after the firing epoch: the graph may already
    have sent that epoch's message (lockstep runs ahead of the track that fires us), and a copy
    of it would be that genuine message, tag and all: a replay, not a forgery."""

    def build(c: Context, t) -> list:
        k = max(c.epoch, c.latest[t].epoch) + 1
        return [c.like(t, **{"epoch": k, **c.stamp(k), **changes})]

    return build


def _at(epoch: int, **changes):
    """The latest genuine message of the type at another epoch (stamp too), changed."""

    def build(c: Context, t) -> list:
        return [c.like(t, **{"epoch": epoch, **c.stamp(epoch), **changes})]

    return build


def _same(**changes):
    """The latest genuine message of the type with only these fields changed."""
    return lambda c, t: [c.like(t, **changes)]


def _new(make: Callable[[Context], object]):
    return lambda c, t: [make(c)]


def _diag(name: str, message: str = "", values=()) -> DiagnosticArray:
    status = DiagnosticStatus(name=name, message=message, values=list(values))
    return DiagnosticArray(status=[status])


def _beam(c: Context, sensor_id: str, bearing: float) -> BeamCommand:
    """A beam command for the next decision epoch, stamped like the graph's (built, not
    copied: a scene without steerable sensors has no genuine one)."""
    k = c.epoch + 1
    return BeamCommand(
        header=header(k * c.dt), sensor_id=sensor_id, epoch=k, bearing=bearing, track_id=1
    )


def _polar_scan(c: Context) -> Scan:
    """The latest genuine scan as a range-bearing sensor would send it (two components)."""
    scan = c.like(Scan, sensor_kind="range_bearing", dim=2, detections=[900.0, 0.1])
    scan.covariance = [100.0, 0.0, 0.0, 1e-4]
    return scan


def _duplicate_track(c: Context, t) -> list:
    """The latest genuine track array with its first track twice (one id, two tracks)."""
    k = max(c.epoch, c.latest[t].epoch) + 1
    msg = c.like(t, epoch=k, **c.stamp(k))
    msg.tracks = [msg.tracks[0], copy.deepcopy(msg.tracks[0])]
    return [msg]


NAN, INF = math.nan, math.inf
NOT_PD = [1.0, 2.0, 0, 0, 2.0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0]  # eigenvalues -1, 3, 1, 1
SC, P, T = Scan, PlatformState, TrackArray
C, BM, L, R, G, D = (
    ManoeuvreCommand, BeamCommand, SensorSelection, PlanReport, GroundTruthArray, DiagnosticArray,
)  # fmt: skip
TOO_MANY = [0.1] * (MAX_SCAN_DETECTIONS + 1)  # one detection more than any scan may carry

CATEGORIES: list[Category] = [
    # --- scans (tracker, evaluator) -----------------------------------------------------------
    Category("scan_nan", SC, _next(detections=[NAN])),
    Category("scan_inf_position", SC, _next(sensor_position__x=INF)),
    Category("scan_1e300", SC, _next(detections=[1e300])),
    Category("scan_bearing_4_rad", SC, _next(detections=[4.0])),
    Category("scan_unknown_sensor", SC, _next(sensor_id="s9")),
    Category("scan_wrong_platform", SC, _next(platform_id="p9")),
    Category("scan_negative_stamp", SC, _next(header__stamp__sec=-1)),
    Category("scan_bad_nanosec", SC, _next(header__stamp__nanosec=2_000_000_000)),
    Category("scan_stamp_mismatch", SC, _next(header__stamp__sec=999)),
    Category("scan_far_future", SC, _at(4_000_000_000, header__stamp__sec=0)),
    Category("scan_epoch_zero", SC, _at(0)),
    Category("scan_old_epoch", SC, _at(1)),
    Category("scan_wrong_sigma", SC, _next(covariance=[1.0])),
    Category("scan_nan_covariance", SC, _next(covariance=[NAN])),
    Category("scan_wrong_kind", SC, _next(sensor_kind="range_bearing")),
    Category("scan_polar_for_bearing_sensor", SC, _new(_polar_scan)),
    Category("scan_wrong_dim", SC, _next(dim=2, detections=[0.1, 0.2])),
    Category("scan_too_many_detections", SC, _next(detections=TOO_MANY)),
    Category("scan_fov_not_the_sensors", SC, _next(fov_width=1.0)),
    Category("scan_fov_nan", SC, _next(fov_r_max=NAN)),
    Category("scan_clutter_density", SC, _next(clutter_density=1.0)),
    Category("scan_count_exceeds_sensors", SC, _next(epoch_scan_count=9)),
    Category("scan_huge_string", SC, _next(sensor_id="s" * 1_000_000)),
    Category("scan_plausible_next_epoch", SC, _next(detections=[0.1]), plausible=True),
    Category("scan_stream_ahead", SC, lambda c, t: [  # drives a trusting tracker ahead
        c.like(t, epoch=k, detections=[0.1], **c.stamp(k))
        for k in range(c.epoch + 1, c.epoch + 120)
    ], plausible=True),
    # --- platform states (tracker, planner, evaluator) ---------------------------------------
    Category("state_unknown_platform", P, _same(platform_id="p9")),
    Category("state_nan_position", P, _next(position__x=NAN)),
    Category("state_1e300_velocity", P, _next(velocity__y=1e300)),
    Category("state_negative_stamp", P, _next(header__stamp__sec=-1)),
    Category("state_far_future", P, _at(1_000_000)),
    Category("state_other_sensors", P, _next(sensor_ids=["s9"])),
    Category("state_announces_more_than_sensors", P, _next(epoch_scan_count=3)),
    Category("state_announces_none", P, _next(epoch_scan_count=0), plausible=True),
    # --- track arrays (planner, sim, evaluator) -----------------------------------------------
    Category("track_wrong_dimension", T, _next(
        state_names=["a", "b", "c"], tracks__0__state=[0.0] * 3,
        tracks__0__state_covariance=list(np.eye(3).ravel()),
    )),
    Category("track_not_pd", T, _next(tracks__0__covariance=NOT_PD)),
    Category("track_nan_state", T, _next(tracks__0__state=[NAN] * 4)),
    Category("track_1e300_state", T, _next(tracks__0__state=[1e300] * 4)),
    Category("track_sample_mismatch", T, _next(tracks__0__sample_count=7)),
    Category("track_huge_sample_claim", T, _next(tracks__0__sample_count=4_000_000_000)),
    Category("track_bad_status", T, _next(tracks__0__status=7)),
    Category("track_unknown_origin", T, _next(tracks__0__origin="t9")),
    Category("track_duplicate_id", T, _duplicate_track),
    Category("track_more_unassociated", T, _next(unassociated=1_000, detections=999)),
    Category("track_negative_stamp", T, _next(header__stamp__sec=-1)),
    Category("track_future_epoch", T, _at(10_000)),
    Category("track_bad_filter_kind", T, _next(filter_kind="ukf")),
    Category("track_plausible_next", T, _next(
        tracks__0__state=[1000.0, 1.0, 1000.0, 1.0], tracks__0__mean=[1000.0, 1.0, 1000.0, 1.0]
    ), plausible=True),
    # --- commands, beams and selections (sim, evaluator) -------------------------------------
    Category("command_unknown_platform", C, _same(platform_id="p9")),
    Category("command_nan", C, _next(heading_change=NAN)),
    Category("command_1e300_heading", C, _next(heading_change=1e300)),
    Category("command_1e300_speed", C, _next(speed_change=1e300)),
    Category("command_stale_epoch", C, _at(0)),
    Category("command_future_epoch", C, _at(50)),
    Category("command_negative_stamp", C, _next(header__stamp__sec=-1)),
    Category("command_plausible_next", C, _next(heading_change=0.2), plausible=True),
    Category("beam_unknown_sensor", BM, _new(lambda c: _beam(c, "s9", 0.5))),
    Category("beam_not_steerable", BM, _new(lambda c: _beam(c, "s1", 0.5))),
    Category("beam_nan_bearing", BM, _new(lambda c: _beam(c, "s1", NAN))),
    Category("selection_empty", L, _new(lambda c: L(epoch=c.epoch + 1)), plausible=True),
    Category("selection_unknown_sensor", L, _new(lambda c: L(selected_sensor_ids=["s9"]))),
    # --- evaluator inputs ---------------------------------------------------------------------
    Category("report_nan_costs", R, _next(predicted_costs=[NAN] * 4, cost_names=list("abcd"))),
    Category("report_length_mismatch", R, _next(cost_names=["x"])),
    Category("truth_nan", G, _next(positions__0__x=NAN)),
    Category("truth_unknown_target", G, _next(target_ids=["t9"])),
    Category("truth_missing_state", G, _next(states=[])),
    Category("truth_plausible_next", G, _next(), plausible=True),
    Category("diagnostics_temperature", D, _new(lambda c: _diag(
        "thermal_monitor", "ok", [KeyValue(key="activetrack", value="41.5 C")]
    ))),
    Category("diagnostics_posing_as_sim", D, _new(lambda c: _diag(
        "activetrack/sim_node", "finished",
        [KeyValue(key="updates", value="-1"), KeyValue(key="graph_auth", value="00")],
    )), plausible=True),
    Category("diagnostics_many_statuses", D, _new(lambda c: DiagnosticArray(
        status=[DiagnosticStatus(name=f"activetrack/n{i}") for i in range(5000)]
    ))),
]  # fmt: skip


def random_message(msg_type, rng: random.Random, depth: int = 0):
    """A message of ``msg_type`` with every field random, extremes included (NaN, inf, huge,
    negative stamps, long strings and sequences). ``rng``: a seeded ``random.Random``."""
    msg = msg_type()
    for name, kind in msg_type.get_fields_and_field_types().items():
        setattr(msg, name, _random_value(kind, getattr(msg, name), rng, depth))
    return msg


_FLOATS = (0.0, -0.0, 1.0, -1.0, 1e300, -1e300, math.inf, -math.inf, math.nan, 5e-324)
_UINTS = (0, 1, 2, 3, 2**32 - 1)
_INTS = (-1, 0, 5, 2**31 - 1, -(2**31))
_INT64S = (-2, -1, 0, 1, 2**63 - 1, -(2**63))
_STRINGS = ("", "s1", "p1", "t1", "pf", "ekf", "activetrack/sim_node")


def _random_value(kind: str, current, rng: random.Random, depth: int):
    if kind == "double":
        return rng.choice(_FLOATS) if rng.random() < 0.3 else rng.gauss(0.0, 1e4)
    if kind == "uint32":
        return rng.choice(_UINTS) if rng.random() < 0.5 else rng.getrandbits(32)
    if kind == "int32":
        return rng.choice(_INTS)
    if kind == "int64":
        return rng.choice(_INT64S)
    if kind == "uint8":
        return rng.getrandbits(8)
    if kind == "boolean":
        return rng.random() < 0.5
    if kind == "octet":
        return bytes([rng.getrandbits(8)])
    if kind == "string":
        return rng.choice(_STRINGS) if rng.random() < 0.8 else "x" * rng.randrange(300)
    if kind == "uint8[16]":
        return list(rng.randbytes(16))
    if kind.startswith("double[") and kind.endswith("]"):  # fixed size
        return [_random_value("double", None, rng, depth) for _ in range(int(kind[7:-1]))]
    if kind.startswith("sequence<"):
        inner = kind[len("sequence<") : -1]
        if "/" in inner:  # messages: a few, and fewer inside nested messages
            n = rng.choice((0, 1, 4, 16, 64)) if depth == 0 else rng.randrange(3)
            cls = type(current[0]) if len(current) else _message_class(inner)
            return [random_message(cls, rng, depth + 1) for _ in range(n)]
        n = rng.choice((0, 1, 4, 16, 1000)) if depth == 0 else rng.randrange(3)
        return [_random_value(inner, None, rng, depth + 1) for _ in range(n)]
    if "/" in kind:
        return random_message(type(current), rng, depth + 1)
    raise ValueError(f"no random value for field type {kind!r}")


def _message_class(name: str):
    import importlib

    package, msg = name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), msg)


class ForeignNode(Node):
    """Publishes categories of traffic when the graph's track of ``at_epoch`` appears.

    ``categories``: names from CATEGORIES; ``floods``: {message type: count} of random messages
    (:func:`random_message`); ``garbage``: raw random bytes per graph topic; ``replay``: every
    genuine per-epoch message seen so far, published again unchanged (valid tags);
    ``messages``: (type, message) pairs given by the caller (e.g. drawn by hypothesis); ``sign``:
    the graph's key (a buggy insider) or None (an outsider). ``rate``: 0 publishes it all at
    once; else a stream of ``rate`` messages per second going round all of it until ``stop()``
    holds (e.g. the run's evaluator is complete).
    """

    def __init__(
        self,
        *,
        dt: float,
        at_epoch: int = 2,
        categories=(),
        floods: dict | None = None,
        garbage: int = 0,
        replay: bool = False,
        messages=(),
        sign: GraphKey | None = None,
        seed: int = 0,
        rate: float = 0.0,
        stop: Callable[[], bool] | None = None,
        **kwargs,
    ):
        super().__init__("foreign_node", **kwargs)
        self.dt = dt
        self.rate = rate
        self.stop = stop
        self.stream: list[Callable[[], None]] = []
        self.streamed = 0
        self.timer = None
        self.at_epoch = at_epoch
        self.categories = [c for c in CATEGORIES if c.name in set(categories)]
        unknown = set(categories) - {c.name for c in self.categories}
        if unknown:
            raise ValueError(f"unknown categories {sorted(unknown)}")
        self.floods = dict(floods or {})
        self.garbage = garbage
        self.replay = replay
        self.messages = list(messages)  # (message type, message) pairs published as they are
        self.key = sign
        self.rng = random.Random(seed)
        # Random messages and garbage made now, serialised: firing must not hold the
        # executor (in one process it is the graph's too) for longer than publishing takes.
        self.pools: dict = {}
        for msg_type, n in self.floods.items():
            self.pools[msg_type] = [
                serialize_message(random_message(msg_type, self.rng)) for _ in range(n)
            ]
        # Not empty: Fast DDS 2.14 does not deliver a 0-byte payload to a reader in another
        # process, and the reliable reader then holds every later sample of that writer
        # (measured): the writer stalls itself, the graph sees none of it to count.
        for msg_type in TOPIC_OF if garbage else ():
            pool = self.pools.setdefault(msg_type, [])
            pool.extend(self.rng.randbytes(self.rng.randrange(1, 512)) for _ in range(garbage))
        self.sent: Counter[str] = Counter()  # message type name -> messages published
        self.sent_signed: Counter[str] = Counter()  # of which carry a valid tag
        self.fired = False
        self.latest: dict = {}
        self.seen: dict = {}
        self.pubs = {
            t: self.create_publisher(t, topic, topics.writer_qos(topic))
            for t, topic in TOPIC_OF.items()
        }
        for msg_type, topic in TOPIC_OF.items():
            self.create_subscription(
                msg_type,
                topic,
                lambda data, t=msg_type: self._sniff(t, data),
                topics.reader_qos(topic),
                raw=True,
            )

    def _sniff(self, msg_type, data: bytes) -> None:
        if self.fired:
            return  # everything after firing may be our own traffic
        self.seen.setdefault(msg_type, []).append(bytes(data))
        msg = deserialize_message(data, msg_type)
        self.latest[msg_type] = msg
        if msg_type is TrackArray and msg.epoch >= self.at_epoch:
            self.fire(msg.epoch)

    def _matched(self, msg_type) -> bool:
        """Whether the publisher of ``msg_type`` reaches every reader the graph has of it (and
        this node's own sniffer of the topic)."""
        readers = READERS.get(msg_type.__name__, ())
        return self.pubs[msg_type].get_subscription_count() >= len(readers) + 1

    def publish(self, msg_type, msg) -> None:
        pub = self.pubs[msg_type]
        if isinstance(msg, bytes):
            pub.publish(msg)
            self.sent[msg_type.__name__] += 1
            return
        if self.key is not None and is_signed_type(msg_type):
            pub.publish(self.key.sign(serialize_message(msg)))
            self.sent_signed[msg_type.__name__] += 1
        elif self.key is not None and msg_type is DiagnosticArray and msg.status:
            pub.publish(self.key.sign_diagnostics(msg))
            self.sent_signed[msg_type.__name__] += 1
        else:
            pub.publish(msg)
        self.sent[msg_type.__name__] += 1

    def fire(self, epoch: int) -> None:
        """Publish every category (at the next track instead, if a genuine message a
        category copies has not been seen yet: the executor may hand the track over first; or
        if a topic it will publish on has not yet matched all of the graph's readers of it:
        a message sent before discovery reaches nobody, so no reader could count it)."""
        ctx = Context(epoch, self.dt, self.latest, self.seen, self.rng)
        try:
            built = [(c.msg_type, m) for c in self.categories for m in c.build(ctx, c.msg_type)]
        except (KeyError, IndexError):  # a genuine message (or a track in it) not seen yet
            return
        types = {t for t, _ in built} | set(self.pools) | {t for t, _ in self.messages}
        if self.replay:
            types |= set(self.seen)
        if not all(self._matched(t) for t in types):
            return
        self.fired = True
        sends = [lambda t=t, m=m: self.publish(t, m) for t, m in built]
        sends += [
            lambda t=t, d=d: self.publish(t, d) for t, pool in self.pools.items() for d in pool
        ]
        sends += [lambda t=t, m=m: self.publish(t, m) for t, m in self.messages]
        if self.replay:
            sends += [
                lambda t=t, raw=raw: self._replay(t, raw)
                for t, raws in self.seen.items()
                for raw in raws
            ]
        if not self.rate:
            for send in sends:
                send()
            return
        self.stream = sends
        self.timer = self.create_timer(1.0 / self.rate, self._stream_next)

    def _replay(self, msg_type, raw: bytes) -> None:
        self.pubs[msg_type].publish(raw)
        self.sent[msg_type.__name__] += 1
        self.sent_signed[msg_type.__name__] += 1  # genuine tags (diagnostics too)

    def _stream_next(self) -> None:
        if self.stop is not None and self.stop():
            self.timer.cancel()
            return
        self.stream[self.streamed % len(self.stream)]()
        self.streamed += 1


def flood(
    rate: float,
    duration: float,
    readers: dict[str, int],
    seed: int = 0,
    wait: float = 30.0,
    settle: float = 2.0,
    stop: threading.Event | None = None,
) -> Counter:
    """Publish random messages (no key) round-robin on ``readers``' topics at ``rate`` per
    second for ``duration`` seconds (or until ``stop`` is set), once each topic has its
    expected number of matched readers (``{topic: n}``) and ``settle`` seconds more (a writer
    matches a reader before the reader matches the writer: what it sends in between is lost at
    that reader, uncounted); returns what was sent per message type."""
    import rclpy

    rclpy.init()
    node = rclpy.create_node("foreign_flooder")
    types = {topic: t for t, topic in TOPIC_OF.items() if topic in readers}
    pubs = {
        topic: node.create_publisher(t, topic, topics.writer_qos(topic))
        for topic, t in types.items()
    }
    deadline = time.monotonic() + wait
    while any(pubs[tp].get_subscription_count() < n for tp, n in readers.items()):
        if stop is not None and stop.is_set():
            break
        if time.monotonic() > deadline:
            raise TimeoutError(f"readers not matched within {wait} s: {readers}")
        time.sleep(0.01)
    print(f"flooder: readers matched after {wait - (deadline - time.monotonic()):.1f} s",
          file=sys.stderr, flush=True)  # fmt: skip
    time.sleep(settle)
    rng = random.Random(seed)
    # A pool of random messages per topic, serialised once: the flood is then as fast as DDS.
    pool = {
        tp: [serialize_message(random_message(t, rng)) for _ in range(64)]
        for tp, t in types.items()
    }
    print("flooding", flush=True)  # for a caller that starts its run under the flood
    sent: Counter[str] = Counter()
    order = list(pubs)
    start = time.monotonic()
    i = 0
    while (now := time.monotonic()) - start < duration and not (stop and stop.is_set()):
        due = int((now - start) * rate)
        while i < due:
            topic = order[i % len(order)]
            pubs[topic].publish(pool[topic][(i // len(order)) % 64])
            sent[types[topic].__name__] += 1
            i += 1
        time.sleep(0.001)
    time.sleep(0.5)  # reliable delivery of the tail
    node.destroy_node()
    rclpy.shutdown()
    return sent


class FloodProcess:
    """:func:`flood` in a process of its own, on every topic the graph reads, for a run
    (``run_graph``'s hooks): :meth:`start_under` (``before_spin``) waits until the flood has
    begun, :meth:`stop_when_complete` (``during_spin``) stops it once the run's evaluator is
    complete (the flooder waits for delivery of its tail; the readers count the rest while the
    run drains), :meth:`finish` stops it if it still runs and returns what it sent per type.
    ``started`` and ``stopped``: when (``time.monotonic``)."""

    def __init__(self, rate: float, duration: float, env: dict):
        readers = [f"{topic}={len(READERS[t.__name__])}" for t, topic in TOPIC_OF.items()]
        command = [sys.executable, __file__, "--rate", str(rate), "--stop-on-input"]
        self.proc = subprocess.Popen(
            [*command, "--duration", str(duration), *readers],
            env={k: v for k, v in env.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"},
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        self.started: float | None = None
        self.stopped: float | None = None
        self.report: str | None = None

    def start_under(self, graph) -> None:
        """The graph's readers exist: once the flooder has matched them and begun."""
        while (line := self.proc.stdout.readline()) and line.strip() != "flooding":
            pass
        self.started = time.monotonic()

    def stop_when_complete(self, graph) -> None:
        if self.report is None and graph.evaluator.complete:
            self._stop()

    def _stop(self) -> None:
        self.stopped = time.monotonic()
        self.report = self.proc.communicate(input="stop\n", timeout=120)[0]

    def finish(self) -> Counter:
        """Stop (if the run did not) and end the process; what it sent per message type."""
        try:
            if self.report is None:
                self._stop()
        finally:
            self.proc.kill()
        return Counter(json.loads(self.report.strip().splitlines()[-1]))


def main(argv=None) -> int:
    """python tests/tools/adversary.py --rate R --duration S TOPIC=READERS ..."""
    import argparse

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--rate", type=float, default=2000.0, help="messages per second")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--stop-on-input", action="store_true", help="stop early when a line (or EOF) comes in"
    )
    parser.add_argument("readers", nargs="+", help="TOPIC=N: flood TOPIC once N readers match")
    args = parser.parse_args(argv)
    readers = {k: int(v) for k, v in (item.split("=") for item in args.readers)}
    stop = threading.Event()
    if args.stop_on_input:
        threading.Thread(target=lambda: (sys.stdin.readline(), stop.set()), daemon=True).start()
    sent = flood(args.rate, args.duration, readers, args.seed, stop=stop)
    print(json.dumps(dict(sent)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
