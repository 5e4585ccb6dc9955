"""Record and replay graph topics as standard rosbag2 directories (rosbags; no rosbag2 on PyPI).

Recording writes raw CDR bytes as received (``raw=True`` subscriptions) into MCAP storage with
the message definitions embedded, so plain ``rosbags``, Foxglove and ``ros2 bag info`` read the
bag without this package. Replay republishes the stored bytes unchanged.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import sys
import time
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from rclpy.node import Node
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from activetrack_ros import graph as topics
from activetrack_ros.graph import GRAPH_TOPICS, LATCHED_TOPICS, reader_qos, writer_qos


def _msgs_defs_files() -> list[Path]:
    try:
        share = Path(get_package_share_directory("msgs_defs"))
    except (OSError, LookupError):  # no AMENT_PREFIX_PATH: msgs_defs is installed in this prefix
        share = Path(sys.prefix) / "share" / "msgs_defs"
    return sorted((share / "msg").glob("*.msg"))


def graph_typestore():
    """The Jazzy typestore plus the msgs_defs types, read from their installed .msg files."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in _msgs_defs_files():
        types.update(get_types_from_msg(path.read_text(), f"msgs_defs/msg/{path.stem}"))
    store.register(types)
    return store


# Schemas (message definition text and RIHS01 hash) of the graph's types, computed once per
# install: building the typestore and hashing 13 types costs ~0.4 s per recorder otherwise.
SCHEMA_CACHE = Path(sys.prefix) / "share" / "activetrack" / "bag_schemas.json"


def graph_schemas(msgtypes=None) -> dict[str, tuple[str, str]]:
    """``{msgtype: (msgdef, rihs01)}`` for the graph's types (default: every graph topic's),
    from a cache keyed by the rosbags version and the installed msgs_defs files."""
    from importlib.metadata import version

    msgtypes = sorted(set(msgtypes or GRAPH_TOPICS.values()))
    digest = hashlib.sha256(version("rosbags").encode())
    for path in _msgs_defs_files():
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    key = digest.hexdigest()
    try:
        cached = json.loads(SCHEMA_CACHE.read_text())
        if cached.get("key") == key and all(t in cached["schemas"] for t in msgtypes):
            return {t: tuple(cached["schemas"][t]) for t in msgtypes}
    except (OSError, ValueError, KeyError, TypeError):
        pass
    store = graph_typestore()
    schemas = {
        t: (store.generate_msgdef(t, ros_version=2)[0], store.hash_rihs01(t)) for t in msgtypes
    }
    try:
        SCHEMA_CACHE.parent.mkdir(parents=True, exist_ok=True)
        SCHEMA_CACHE.write_text(json.dumps({"key": key, "schemas": schemas}))
    except OSError:  # a read-only install: compute each time
        pass
    return schemas


def message_class(msgtype: str):
    """The rclpy message class of a type name like ``msgs_defs/msg/TrackEstimate``."""
    package, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def _bag_qos(topic: str) -> list[Qos]:
    """Offered QoS written to metadata.yaml, so that a real `ros2 bag play` matches ours."""
    latched = topic in LATCHED_TOPICS
    return [
        Qos(
            history=QosHistory.KEEP_LAST,
            depth=topics.LATCHED_DEPTH if latched else topics.STREAM_DEPTH,
            reliability=QosReliability.RELIABLE,
            durability=QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
            deadline=QosTime(0, 0),
            lifespan=QosTime(0, 0),
            liveliness=QosLiveliness.AUTOMATIC,
            liveliness_lease_duration=QosTime(0, 0),
            avoid_ros_namespace_conventions=False,
        )
    ]


class BagRecorder(Node):
    """Subscribes to topics (raw CDR) and writes them to a rosbag2 directory (MCAP)."""

    def __init__(self, path: str | Path, topic_types: dict[str, str] | None = None, **kwargs):
        super().__init__("activetrack_recorder", **kwargs)
        self.path = Path(path)
        self.topic_types = dict(topic_types or GRAPH_TOPICS)
        schemas = graph_schemas(self.topic_types.values())
        self.writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections = {}
        self.count = 0
        for topic, msgtype in self.topic_types.items():
            msgdef, rihs01 = schemas[msgtype]
            self.connections[topic] = self.writer.add_connection(
                topic, msgtype, msgdef=msgdef, rihs01=rihs01, offered_qos_profiles=_bag_qos(topic)
            )
            self.create_subscription(
                message_class(msgtype),
                topic,
                lambda data, t=topic: self._write(t, data),
                reader_qos(topic),
                raw=True,
            )

    def _write(self, topic: str, data: bytes) -> None:
        self.writer.write(self.connections[topic], time.time_ns(), data)
        self.count += 1

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None


def bag_info(path: str | Path) -> dict:
    """Topics, types and message counts of a bag (what `ros2 bag info` shows)."""
    with Reader(path) as reader:
        return {
            "duration_s": reader.duration * 1e-9,
            "messages": reader.message_count,
            "topics": {
                c.topic: {"type": c.msgtype, "count": c.msgcount} for c in reader.connections
            },
        }


class BagPlayer(Node):
    """Republishes a bag's raw messages with their recorded timing (scaled by ``rate``)."""

    def __init__(self, path: str | Path, topics_filter=None, rate: float = 1.0, **kwargs):
        if not rate > 0:
            raise ValueError(f"rate must be > 0, got {rate!r}")
        reader = Reader(path)
        reader.open()
        conns = [c for c in reader.connections if not topics_filter or c.topic in topics_filter]
        missing = set(topics_filter or ()) - {c.topic for c in conns}
        if missing:
            reader.close()
            raise ValueError(f"topics not in the bag: {sorted(missing)}")
        super().__init__("activetrack_player", **kwargs)
        self.rate = rate
        self.reader = reader
        self.pubs = {
            c.id: self.create_publisher(message_class(c.msgtype), c.topic, writer_qos(c.topic))
            for c in conns
        }
        self.messages = self.reader.messages(connections=conns)
        self.published = 0
        self.done = False
        self._t0_bag = None
        self._t0_wall = None

    def play_step(self, max_burst: int = 64) -> None:
        """Publish the messages whose (scaled) time has come, at most ``max_burst`` per call so
        that subscribers in the same executor keep up; call repeatedly."""
        if self.done:
            return
        now = time.monotonic()
        for _ in range(max_burst):
            if getattr(self, "_next", None) is None:
                try:
                    self._next = next(self.messages)
                except StopIteration:
                    self.done = True
                    self.reader.close()
                    return
            conn, stamp, data = self._next
            if self._t0_bag is None:
                self._t0_bag, self._t0_wall = stamp, now
            due = self._t0_wall + (stamp - self._t0_bag) * 1e-9 / self.rate
            if due > now:
                return
            self.pubs[conn.id].publish(bytes(data))
            self.published += 1
            self._next = None
