"""Record and replay graph topics as standard rosbag2 directories (no rosbag2 on PyPI).

Recording writes the raw CDR bytes as received into MCAP storage with the message definitions
and RIHS01 hashes embedded, as rosbag2 does, so ``rosbags``, Foxglove, ``mcap`` and ``ros2 bag
info`` read the bag without this package; it stays readable while it grows and after the
recorder is killed (:mod:`bag_io`, :mod:`mcap_writer`). Replay republishes the stored bytes.
Reading checks every CRC (:mod:`mcap_reader`): what each command does with a damaged bag is in
the README (Command line).
"""

from __future__ import annotations

import hashlib
import importlib
import json
import struct
import sys
import threading
import time
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosgraph_msgs.msg import Clock

from activetrack.closed_loop.counters import NodeCounters
from activetrack.limits import MAX_WALL_SECONDS
from activetrack_bringup import interrupts
from activetrack_bringup.bag_io import BagError, Rosbag2Writer, TopicSpec, check_rate, open_bag
from activetrack_bringup.mcap_reader import INCOMPLETE, LOST
from activetrack_ros import graph as topics
from activetrack_ros.graph import (
    GRAPH_TOPICS,
    MAX_HISTORY_DEPTH,
    graph_topic_of,
    writer_qos,
)
from activetrack_ros.node_base import graph_check, subscribe_batched
from activetrack_ros.params import ParamSpec, declare, fix_use_sim_time, warn_unknown
from activetrack_ros.sizes import DIAGNOSTICS_BYTES
from activetrack_ros.trust import is_signed_type


def _share(package: str) -> Path:
    try:
        return Path(get_package_share_directory(package))
    except (OSError, LookupError, ValueError):  # no AMENT_PREFIX_PATH: installed in this prefix
        return Path(sys.prefix) / "share" / package


def _msgs_defs_files() -> list[Path]:
    return sorted((_share("msgs_defs") / "msg").glob("*.msg"))


def graph_typestore():
    """The Jazzy typestore plus the msgs_defs types, read from their installed .msg files."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in _msgs_defs_files():
        types.update(get_types_from_msg(path.read_text(), f"msgs_defs/msg/{path.stem}"))
    store.register(types)
    return store


# The graph types' schemas cost ~0.4 s to build: set-up (tools/setup.sh) writes them to the
# install, and a process computes them at most once when that file is missing or stale.
SCHEMA_CACHE = Path(sys.prefix) / "share" / "activetrack" / "bag_schemas.json"
_schemas_in_memory: dict[str, dict] = {}


def graph_schemas(msgtypes=None, *, write_cache: bool = False) -> dict[str, tuple[str, str]]:
    """``{msgtype: (msgdef, rihs01)}`` for the graph's types (default: every graph topic's),
    from the install's cache if it matches the rosbags version and the installed msgs_defs
    files; ``write_cache`` (set-up only) refreshes that file."""
    from importlib.metadata import version

    msgtypes = sorted(set(msgtypes or GRAPH_TOPICS.values()))
    digest = hashlib.sha256(version("rosbags").encode())
    for path in _msgs_defs_files():
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    key = digest.hexdigest()
    known = _schemas_in_memory.get(key)
    if known is None and not write_cache:
        try:
            cached = json.loads(SCHEMA_CACHE.read_text())
            if cached.get("key") == key:
                known = cached["schemas"]
        except (OSError, ValueError, KeyError, TypeError):
            pass
    if known is None or not all(t in known for t in msgtypes):
        store = graph_typestore()
        every = sorted(set(GRAPH_TOPICS.values()) | set(msgtypes))
        known = {
            t: (store.generate_msgdef(t, ros_version=2)[0], store.hash_rihs01(t)) for t in every
        }
    if write_cache:
        SCHEMA_CACHE.parent.mkdir(parents=True, exist_ok=True)
        SCHEMA_CACHE.write_text(json.dumps({"key": key, "schemas": known}))
    _schemas_in_memory[key] = known
    return {t: tuple(known[t]) for t in msgtypes}


def message_class(msgtype: str):
    """The rclpy message class of a type name like ``msgs_defs/msg/TrackEstimate``."""
    package, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def installed_type_hash(msgtype: str) -> str | None:
    """The RIHS01 hash of the installed definition of ``msgtype`` (rosidl's type description
    file), or None when it cannot be found."""
    package, _, name = msgtype.partition("/msg/")
    try:
        hashes = json.loads((_share(package) / "msg" / f"{name}.json").read_text())["type_hashes"]
        return next(h["hash_string"] for h in hashes if h["type_name"] == msgtype)
    except (OSError, ValueError, KeyError, TypeError, StopIteration):
        return None


def bag_qos(topic: str, depth: int | None = None) -> list[dict]:
    """Offered QoS written to the bag (rosbag2 v9 dictionaries), so that a real `ros2 bag play`
    matches ours."""
    qos = writer_qos(topic, depth)
    latched = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    return [
        {
            "history": "keep_last",
            "depth": qos.depth,
            "reliability": "reliable",
            "durability": "transient_local" if latched else "volatile",
            "deadline": {"sec": 0, "nsec": 0},
            "lifespan": {"sec": 0, "nsec": 0},
            "liveliness": "automatic",
            "liveliness_lease_duration": {"sec": 0, "nsec": 0},
            "avoid_ros_namespace_conventions": False,
        }
    ]


def first_stamp_ns(data: bytes) -> int:
    """The first field's time (a Header's stamp, a Clock's clock) of a CDR message, in ns:
    int32 sec and uint32 nanosec after the 4-byte encapsulation header. ValueError when the
    bytes are too short to hold one."""
    if len(data) < 12:
        raise ValueError(f"{len(data)} bytes hold no stamp")
    order = "<" if data[1] & 1 else ">"
    sec, nanosec = struct.unpack_from(order + "iI", data, 4)
    return sec * 1_000_000_000 + nanosec


def recorder_params(path, topic_types, depth, clock_lead) -> tuple[ParamSpec, ...]:
    """A recorder's parameters, defaulting to its constructor's arguments."""
    return (
        ParamSpec(
            "bag", "" if path is None else str(path),
            "the rosbag2 directory to write (must not exist yet)", required=True,
        ),
        ParamSpec(
            "topics", " ".join(topic_types or ()),
            "graph topics recorded, relative names separated by spaces (empty: all of them)",
        ),
        ParamSpec(
            "depth", int(depth or 0),
            "history depth written as the per-epoch topics' offered QoS (0: the tools' default)",
            low=0, high=MAX_HISTORY_DEPTH,
        ),
        ParamSpec(
            "clock_lead", float(clock_lead),
            "with a graph key: seconds a /clock may lead the newest stamp of the graph's own "
            "messages to be taken as the log time",
            low=0.0, high=1e9,
        ),
    )  # fmt: skip


def recorded_topics(names, what: str = "parameter 'topics'") -> dict[str, str]:
    """Graph topic -> type of the graph topics ``names`` (none: every graph topic); ValueError
    naming ``what`` for a name that is not one."""
    if not names:
        return dict(GRAPH_TOPICS)
    unknown = [t for t in names if graph_topic_of(t) is None]
    if unknown:
        raise ValueError(f"{what} must name graph topics {sorted(GRAPH_TOPICS)}; got {unknown}")
    return {graph_topic_of(t): GRAPH_TOPICS[graph_topic_of(t)] for t in names}


class BagRecorder(Node):
    """Subscribes to topics (raw CDR, stored under their resolved names) and writes them to a
    rosbag2 directory; ``close()`` finishes it (summary, final metadata.yaml).

    Log time is the latest ``clock`` received (``ros2 bag record --use-sim-time``; 0 before).
    With ``graph_key`` (activetrack_ros.trust), signed-type messages and ``/diagnostics`` that
    do not verify are counted as ``foreign.<Type>``, not recorded; ``clock`` cannot be signed,
    so a clock value is taken as log time only while it never goes back and stays within
    ``clock_lead`` s of the newest verified stamp: another writer's clock can shift log times by
    less than an epoch, never reorder the run (``clock_refused`` counts the values not taken;
    they are recorded, as every clock: in free mode the sim's clock may lead the graph's
    messages). Every message ends in one counter, as in a graph node: ``received.<Type>`` =
    ``accepted.<Type>`` (recorded) + ``foreign.<Type>`` (``counters``). The
    arguments are the defaults of read-only parameters (:func:`recorder_params`) a standalone
    recorder takes from --ros-args.
    """

    TICK_S = 0.25  # timer period: closes chunks older than 0.5 s, rewrites metadata.yaml (1 s)

    def __init__(
        self,
        path: str | Path | None = None,
        topic_types: dict[str, str] | None = None,
        *,
        graph_key=None,
        depth: int | None = None,
        clock_lead: float = 3600.0,
        **kwargs,
    ):
        super().__init__("activetrack_recorder", **kwargs)
        try:  # the arguments are the parameters' defaults: a standalone recorder sets them
            fix_use_sim_time(self)
            p = declare(self, recorder_params(path, topic_types, depth, clock_lead))
            warn_unknown(self)
            self.topic_types = recorded_topics(p["topics"].split())
            self.path = Path(p["bag"])
            depth, clock_lead = p["depth"] or None, p["clock_lead"]
            schemas = graph_schemas(self.topic_types.values())
            names = {t: self.resolve_topic_name(t) for t in self.topic_types}
            specs = [
                TopicSpec(names[topic], msgtype, *schemas[msgtype], qos=bag_qos(topic, depth))
                for topic, msgtype in self.topic_types.items()
            ]
            self.writer = Rosbag2Writer(self.path, specs)  # BagError if the path exists
        except BaseException:
            super().destroy_node()
            raise
        self.count = 0  # messages written
        self.counters = NodeCounters()
        self.failed: str | None = None
        self._lock = threading.Lock()
        self._channel = {t: self.writer.channel_ids[names[t]] for t in self.topic_types}
        self._key = graph_key
        self._now_ns = 0  # log time: the graph's sim time
        self._signed_ns = 0  # newest stamp of a verified graph message (with a key)
        self._lead_ns = int(clock_lead * 1e9)
        for topic, msgtype in self.topic_types.items():
            cls = message_class(msgtype)
            if graph_key is not None and (is_signed_type(cls) or cls is DiagnosticArray):
                callback = self._verifier(graph_key, topic, cls)
            elif topic == topics.CLOCK:
                callback = self._on_clock
            else:
                callback = self._recorder_of(topic, cls.__name__)
            self._subscribe(cls, topic, callback)
        if topics.CLOCK not in self.topic_types:  # the time source, recorded or not
            self._subscribe(Clock, topics.CLOCK, self._on_clock)
        self.create_timer(self.TICK_S, self._tick)

    @property
    def foreign(self) -> int:
        return self.counters.total("foreign.")

    @property
    def clock_refused(self) -> int:
        return self.counters.counts["clock_refused"]

    def _subscribe(self, cls, topic: str, callback) -> None:
        """A raw subscription counting every sample, and the samples DDS reports lost."""
        name = cls.__name__

        def on_raw(data: bytes) -> None:
            self.counters.received(name)
            callback(data)

        lost = lambda info: self.counters.count(f"dropped.{name}", info.total_count_change)  # noqa: E731
        subscribe_batched(self, cls, topic, on_raw, SubscriptionEventCallbacks(message_lost=lost))

    def _on_clock(self, data: bytes) -> None:
        try:
            t = first_stamp_ns(data)
        except ValueError:
            t = None
        if t is not None and self._key is None:
            self._now_ns = max(t, 0)
        elif t is not None and self._now_ns <= t <= self._signed_ns + self._lead_ns:
            self._now_ns = t
        else:  # with the key: not taken as log time (in free mode the sim's clock may lead)
            self.counters.count("clock_refused")
        if topics.CLOCK in self._channel:
            self._write(topics.CLOCK, data)
            self.counters.count("accepted.Clock")
        else:
            self.counters.count("ignored.clock_not_recorded")

    def _verifier(self, key, topic: str, cls):
        """The graph's tagged streams (node_base.graph_check, as the nodes' readers take it):
        recorded when they carry the graph's tag, counted as foreign when not."""
        name = cls.__name__
        signed = is_signed_type(cls)
        check = graph_check(key, cls)
        assert check is not None  # the caller's types: signed ones and /diagnostics

        def on_raw(data: bytes) -> None:
            ok = (signed or len(data) <= DIAGNOSTICS_BYTES) and check(data)[0]
            if not ok:
                self.counters.count(f"foreign.{name}")
                return
            if signed:
                self._signed_ns = max(self._signed_ns, first_stamp_ns(data))
            self._write(topic, data)
            self.counters.count(f"accepted.{name}")

        return on_raw

    def _recorder_of(self, topic: str, name: str):
        """Streams for people and tools (tf, markers, poses): no tag, recorded as they come."""

        def on_raw(data: bytes) -> None:
            self._write(topic, data)
            self.counters.count(f"accepted.{name}")

        return on_raw

    def _write(self, topic: str, data: bytes) -> None:
        self._guarded(self._append, self._channel[topic], data)

    def _append(self, channel: int, data: bytes) -> None:
        self.writer.write(channel, self._now_ns, data)
        self.count += 1

    def _tick(self) -> None:
        self._guarded(lambda: self.writer.tick())

    def _guarded(self, action, *args) -> None:
        """``action(*args)`` unless the bag is closed or failed. Signals wait
        (interrupts.deferred): raised inside a chunk's write(2) they would leave half a chunk."""
        with self._lock, interrupts.deferred():
            if self.writer is None or self.failed:
                return
            try:
                action(*args)
            except OSError as exc:  # a full disk must not stop the graph: stop recording
                self.failed = f"recording to {self.path} stopped: {exc.strerror or exc}"
                self.get_logger().error(self.failed)

    def close(self) -> None:
        """Finish the bag (summary, final metadata.yaml); idempotent."""
        with self._lock:
            writer, self.writer = self.writer, None
        if writer is None:
            return
        with interrupts.deferred():  # the summary and metadata.yaml are written whole
            if self.failed:  # the file is as a killed recorder leaves it: `bag recover` reads it
                writer.abandon()
            else:
                writer.close()

    def destroy_node(self):
        self.close()  # a graph torn down without close() still leaves a finished bag
        return super().destroy_node()


def bag_info(path: str | Path) -> dict:
    """Topics, types, message counts and duration of a bag (what `ros2 bag info` shows), and
    its damage (CRC-checked). Raises BagError when nothing of the bag is readable."""
    with open_bag(path) as bag:
        notes = list(bag.notes)
        for t in bag.topics.values():
            problem = None if t.problem else _type_problem(t)
            if problem:
                notes.append(f"{path}: topic {t.topic} ({t.count} messages): {problem}")
        return {
            "duration_s": bag.duration_ns * 1e-9,
            "messages": bag.message_count,
            "topics": {
                t.topic: {"type": t.msgtype, "count": t.count}
                | ({"skipped": t.problem} if t.problem else {})
                for t in bag.topics.values()
            },
            "intact": bag.intact,
            "damage": [{"kind": d.kind, "what": d.text} for d in bag.damage],
            "notes": notes,
        }


class BagPlayer(Node):
    """Republishes a bag's raw messages with their recorded timing (scaled by ``rate``).

    ``warnings`` lists what was skipped (one line each). A bag with lost data (corrupt chunks)
    is refused unless ``skip_damaged``; the messages of verified chunks are played then.
    """

    def __init__(
        self,
        path: str | Path,
        topics_filter=None,
        rate: float = 1.0,
        *,
        skip_damaged: bool = False,
        **kwargs,
    ):
        rate = check_rate(rate)
        bag = open_bag(path)
        try:
            self.warnings = [str(d) for d in bag.damage] + list(bag.notes)
            check_damage(bag, path, skip_damaged, "`--skip-damaged` plays the rest")
            check_playback_time(bag, rate)
            wanted = [bag_topic(bag, t) or t for t in topics_filter] if topics_filter else None
            missing = sorted(set(wanted or ()) - set(bag.topics))
            if missing:
                raise BagError(f"topics not in the bag: {missing}")
            classes = {}
            for name in wanted or bag.usable_topics:  # unusable ones are in bag.notes already
                topic = bag.topics[name]
                problem = topic.problem or _type_problem(topic)
                if problem is None:
                    classes[name] = message_class(topic.msgtype)
                elif wanted:
                    raise BagError(f"{path}: topic {name} cannot be played: {problem}")
                else:
                    text = f"{path}: topic {name} ({topic.count} messages): {problem}"
                    self.warnings.append(text)
            if not classes:
                raise BagError(f"{path}: no playable topic")
        except BaseException:
            bag.close()
            raise
        super().__init__("activetrack_player", **kwargs)
        self.rate = rate
        self.bag = bag
        self.pubs = {name: self._publisher(name, cls) for name, cls in classes.items()}
        self.messages = bag.messages(list(classes))
        self.published = 0
        self.done = False
        self._next = self._t0_bag = self._t0_wall = None

    def _publisher(self, name: str, cls):
        """Publish on the recorded (resolved) name with the graph's QoS for that topic; a
        per-epoch topic keeps every message of the bag for late joiners."""
        topic = topics.graph_topic_of(name)
        if topic is None:
            return self.create_publisher(cls, name, topics.STREAM_DEPTH)
        return self.create_publisher(cls, name, writer_qos(topic, self.bag.topics[name].count))

    def play_step(self, max_burst: int = 64) -> None:
        """Publish the messages whose (scaled) time has come, at most ``max_burst`` per call so
        that subscribers in the same executor keep up; call repeatedly."""
        if self.done:
            return
        now = time.monotonic()
        for _ in range(max_burst):
            if self._next is None:
                try:
                    self._next = next(self.messages)
                except StopIteration:
                    self.done = True
                    self.bag.close()
                    return
            topic, stamp, data = self._next
            if self._t0_bag is None:
                self._t0_bag, self._t0_wall = stamp, now
            due = self._t0_wall + (stamp - self._t0_bag) * 1e-9 / self.rate
            if due > now:
                return
            self.pubs[topic].publish(data)
            self.published += 1
            self._next = None

    def destroy_node(self):
        self.messages.close()
        self.bag.close()
        return super().destroy_node()


def check_damage(bag, path, skip_damaged: bool, skip_note: str) -> None:
    """BagError unless every message of ``bag`` is there or ``skip_damaged``: corrupt chunks
    (lost data) and a cut-off end (a killed recorder: the last messages are missing) refuse;
    damage proven harmless (a damaged index, summary or magic) does not."""
    missing = [d for d in bag.damage if d.kind in (LOST, INCOMPLETE)]
    if missing and not skip_damaged:
        raise BagError(
            f"{missing[0]} ({len(missing)} problem(s) that lose messages: {skip_note}, "
            f"`activetrack bag recover {path}` rewrites the bag)"
        )


def check_playback_time(bag, rate: float) -> None:
    """BagError when playing ``bag`` at ``rate`` would take longer than MAX_WALL_SECONDS."""
    wall = bag.duration_ns * 1e-9 / rate
    if wall > MAX_WALL_SECONDS:
        raise BagError(
            f"playing {bag.duration_ns * 1e-9:g} s of bag at --rate {rate:g} would take "
            f"{wall:.3g} s, more than {MAX_WALL_SECONDS:g} s: raise --rate"
        )


def bag_topic(bag, name: str) -> str | None:
    """A topic as the opened ``bag`` names it: ``name`` itself, or the graph topic ``name``
    stands for (``activetrack/track``) under the namespace it was recorded in; None when the
    bag has neither. BagError when several namespaces hold it (name it with its namespace)."""
    if name in bag.topics:
        return name
    topic = topics.graph_topic_of(name)
    if topic is None:
        return None
    try:
        return topics.find_topic(bag.topics, topic)
    except ValueError as exc:
        raise BagError(f"{bag.path}: {exc}: name the topic with its namespace") from None


def _type_problem(topic) -> str | None:
    """Why the bag's messages of ``topic`` cannot be published here: a type that is not
    installed, or whose installed definition is not the recorded one (play skips the topic)."""
    try:
        message_class(topic.msgtype)
    except (ImportError, AttributeError, ValueError):
        return f"type {topic.msgtype} is not installed here (play skips it)"
    if not topic.rihs01:
        return None
    installed = installed_type_hash(topic.msgtype)
    if installed is not None and installed != topic.rihs01:
        return (
            f"the bag's {topic.msgtype} ({topic.rihs01[:15]}...) is not the installed "
            f"definition ({installed[:15]}...): recorded with another version of the type "
            "(play skips it)"
        )
    return None
