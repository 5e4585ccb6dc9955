"""rosbag2 directories (``metadata.yaml`` version 9 + MCAP storage), written so that they stay
readable while they grow and read so that damage is reported, never decoded.

Writing (:class:`Rosbag2Writer`): ``metadata.yaml`` is rewritten atomically (temporary file,
rename) at most once a second while messages reach the disk, and at close; it counts only the
messages in complete chunks, and ``custom_data.activetrack_state`` says ``recording`` until the
bag is ``closed`` or ``recovered``.

Reading (:func:`open_bag`): the MCAP files are the truth (a scan that checks every CRC,
:mod:`mcap_reader`); ``metadata.yaml`` must be valid and is compared with them. Problems:
:class:`BagError` (nothing usable), damage (:class:`mcap_reader.Damage` kinds plus ``metadata``:
a metadata.yaml that disagrees with the files) and notes (a topic that cannot be used, skipped).
"""

from __future__ import annotations

import functools
import math
import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import NamedTuple

import yaml

from activetrack.limits import MAX_RATE, MIN_RATE
from activetrack_bringup.mcap_reader import INCOMPLETE, LOST, Damage, McapFileError, McapScan
from activetrack_bringup.mcap_writer import CHUNK_AGE_S, CHUNK_SIZE, McapWriter

METADATA = "metadata"  # damage kind: metadata.yaml disagrees with the MCAP file(s)
METADATA_VERSION = 9
STATE_KEY = "activetrack_state"  # custom_data: recording | closed | recovered
METADATA_INTERVAL_NS = 1_000_000_000  # metadata.yaml is rewritten at most this often
_TYPE_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*/(msg|srv|action)/[A-Za-z][A-Za-z0-9_]*$")
_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class BagError(ValueError):
    """A bag (or an argument about it) that cannot be used; the message is one line."""


# --- writing -----------------------------------------------------------------------------


@dataclass
class TopicSpec:
    """What a rosbag2 bag stores about a topic."""

    topic: str
    msgtype: str
    msgdef: str  # the message definition text (ros2msg, dependencies included)
    rihs01: str  # RIHS01 type hash ("" if unknown)
    qos: list[dict] = field(default_factory=list)  # offered QoS, rosbag2 v9 dictionaries
    serialization_format: str = "cdr"
    schema_encoding: str = "ros2msg"
    schema_data: bytes | None = None  # the schema bytes as stored (default: msgdef encoded)


def qos_yaml(qos: list[dict]) -> str:
    """Offered QoS as rosbag2 stores them in an MCAP channel's metadata (a YAML string)."""
    key = repr(qos)
    text = _QOS_YAML.get(key)
    if text is None:
        text = yaml.dump(qos, Dumper=_Dumper, default_flow_style=False, sort_keys=False).strip()
        if len(_QOS_YAML) < 256:
            _QOS_YAML[key] = text
    return text


_QOS_YAML: dict[str, str] = {}


class Rosbag2Writer:
    """A rosbag2 directory written through :class:`McapWriter`, metadata kept current."""

    def __init__(
        self,
        path: str | Path,
        topics: list[TopicSpec],
        *,
        chunk_size: int = CHUNK_SIZE,
        chunk_age_s: float = CHUNK_AGE_S,
        state: str = "recording",
        file_name: str | None = None,
    ):
        self.path = Path(path)
        if self.path.exists() or self.path.is_symlink():
            raise BagError(f"{self.path} exists already: record into a new path")
        try:
            self.path.mkdir(parents=True)
        except OSError as exc:
            raise BagError(f"cannot create {self.path}: {exc.strerror or exc}") from None
        self.mcap_path = self.path / (file_name or f"{self.path.name}.mcap")
        self.metadata_path = self.path / "metadata.yaml"
        self.topics = list(topics)
        self.state = state
        self._mcap = McapWriter(self.mcap_path, chunk_size=chunk_size, chunk_age_s=chunk_age_s)
        self.write = self._mcap.write  # (channel_id, log_time, data, publish_time=None)
        schema_ids: dict[tuple, int] = {}
        self.channel_ids: dict[str, int] = {}
        for spec in self.topics:
            data = spec.schema_data if spec.schema_data is not None else spec.msgdef.encode()
            key = (spec.msgtype, spec.schema_encoding, data)
            if key not in schema_ids:
                schema_ids[key] = self._mcap.add_schema(spec.msgtype, spec.schema_encoding, data)
            meta = {"offered_qos_profiles": qos_yaml(spec.qos)}
            if spec.rihs01:
                meta["topic_type_hash"] = spec.rihs01
            self.channel_ids[spec.topic] = self._mcap.add_channel(
                spec.topic, spec.serialization_format, schema_ids[key], meta
            )
        self._mcap.start()
        self._written_counts: tuple | None = None
        self._metadata_at = 0
        self.write_metadata()

    def tick(self) -> None:
        """For a timer: close an old chunk, and rewrite metadata.yaml if the messages on disk
        changed and the last rewrite is METADATA_INTERVAL_NS old."""
        self._mcap.flush_if_older()
        if time.monotonic_ns() - self._metadata_at >= METADATA_INTERVAL_NS:
            self.write_metadata(only_if_changed=True)

    def metadata(self) -> dict:
        """The rosbag2 metadata of what is on disk now."""
        mcap = self._mcap
        counts = mcap.flushed_counts
        total = sum(counts.values())
        start = mcap.flushed_start if total else 0
        duration = mcap.flushed_end - mcap.flushed_start if total else 0
        name = self.mcap_path.name
        return {
            "rosbag2_bagfile_information": {
                "version": METADATA_VERSION,
                "storage_identifier": "mcap",
                "duration": {"nanoseconds": duration},
                "starting_time": {"nanoseconds_since_epoch": start},
                "message_count": total,
                "topics_with_message_count": [
                    {
                        "topic_metadata": {
                            "name": spec.topic,
                            "type": spec.msgtype,
                            "serialization_format": spec.serialization_format,
                            "offered_qos_profiles": spec.qos,
                            "type_description_hash": spec.rihs01,
                        },
                        "message_count": counts.get(self.channel_ids[spec.topic], 0),
                    }
                    for spec in self.topics
                ],
                "compression_format": "",
                "compression_mode": "",
                "relative_file_paths": [name],
                "files": [
                    {
                        "path": name,
                        "starting_time": {"nanoseconds_since_epoch": start},
                        "duration": {"nanoseconds": duration},
                        "message_count": total,
                    }
                ],
                "custom_data": {STATE_KEY: self.state},
                "ros_distro": "jazzy",
            }
        }

    def write_metadata(self, only_if_changed: bool = False) -> None:
        counts = tuple(sorted(self._mcap.flushed_counts.items()))
        if only_if_changed and counts == self._written_counts:
            return
        text = yaml.dump(self.metadata(), Dumper=_Dumper, default_flow_style=False, sort_keys=False)
        tmp = self.metadata_path.with_name("metadata.yaml.tmp")
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, self.metadata_path)
        self._written_counts = counts
        self._metadata_at = time.monotonic_ns()

    def close(self, state: str = "closed") -> None:
        if self._mcap.closed:
            return
        self._mcap.flush()
        self.state = state
        info = self.metadata()["rosbag2_bagfile_information"]
        # rosbag2 also keeps its metadata inside the MCAP file.
        self._mcap.add_metadata(
            "rosbag2",
            {"serialized_metadata": yaml.dump(info, Dumper=_Dumper, sort_keys=False).strip()},
        )
        self._mcap.close()
        self.write_metadata()

    def abandon(self) -> None:
        """Stop writing without a summary (tests: what a killed recorder leaves)."""
        self._mcap.abandon()


# --- reading -----------------------------------------------------------------------------


def _need(d: dict, key: str, kind, where: str, counts: bool = False):
    """``d[key]``, of type ``kind`` (and not negative if it ``counts``), else BagError."""
    if key not in d:
        raise BagError(f"{where}: '{key}' is missing")
    value = d[key]
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise BagError(f"{where}: '{key}' must be an integer, got {value!r:.40}")
    if kind is not int and not isinstance(value, kind):
        raise BagError(f"{where}: '{key}' must be a {kind.__name__}, got {value!r:.40}")
    if counts and value < 0:
        raise BagError(f"{where}: negative {key}")
    return value


def read_metadata(bag_dir: Path) -> dict:
    """The validated ``rosbag2_bagfile_information`` of ``bag_dir/metadata.yaml``."""
    meta = bag_dir / "metadata.yaml"
    try:
        text = meta.read_text(encoding="utf-8")
    except FileNotFoundError:
        hint = ""
        if any(bag_dir.glob("*.mcap")):
            hint = f"; `activetrack bag recover {bag_dir}` rebuilds it from the .mcap file"
        raise BagError(f"{bag_dir}: no metadata.yaml (not a rosbag2 directory{hint})") from None
    except UnicodeDecodeError:
        raise BagError(f"{meta} is not text (damaged?)") from None
    except OSError as exc:
        raise BagError(f"{meta}: {exc.strerror or exc}") from None
    try:
        doc = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "unreadable"
        raise BagError(f"{meta} is not valid YAML{where}: {problem}") from None
    if not text.strip():
        raise BagError(f"{meta} is empty")
    if not isinstance(doc, dict) or not isinstance(doc.get("rosbag2_bagfile_information"), dict):
        raise BagError(f"{meta} has no 'rosbag2_bagfile_information' mapping (damaged?)")
    info = doc["rosbag2_bagfile_information"]
    where = str(meta)
    version = _need(info, "version", int, where)
    if not 1 <= version <= METADATA_VERSION:
        raise BagError(f"{meta}: version {version} is not one this tool reads (1..9)")
    storage = _need(info, "storage_identifier", str, where)
    if storage != "mcap":
        raise BagError(
            f"{meta}: storage {storage!r:.40} is not supported (activetrack reads MCAP bags)"
        )
    files = _need(info, "relative_file_paths", list, where)
    if not files or not all(isinstance(f, str) and f for f in files):
        raise BagError(f"{meta}: 'relative_file_paths' must list the bag's files")
    mode = info.get("compression_mode") or ""
    if not isinstance(mode, str) or mode.lower() not in ("", "none"):
        raise BagError(f"{meta}: compression mode {mode!r:.40} is not supported")
    topics = _need(info, "topics_with_message_count", list, where)
    for i, entry in enumerate(topics):
        at = f"{meta}: topics_with_message_count[{i}]"
        if not isinstance(entry, dict):
            raise BagError(f"{at} is not a mapping")
        tm = _need(entry, "topic_metadata", dict, at)
        _need(tm, "name", str, at)
        _need(tm, "type", str, at)
        _need(entry, "message_count", int, at, counts=True)
    _need(info, "message_count", int, where, counts=True)
    return info


class ListedTopic(NamedTuple):
    """A topic as a (validated) metadata.yaml lists it."""

    msgtype: str
    count: int
    rihs01: str  # "" when not given


UNLISTED = ListedTopic("", 0, "")


def listed_topics(info: dict | None) -> dict[str, ListedTopic]:
    """The topics of a :func:`read_metadata` result (None: none)."""
    listed = {}
    for entry in (info or {}).get("topics_with_message_count", ()):
        tm = entry["topic_metadata"]
        rihs01 = tm.get("type_description_hash")
        rihs01 = rihs01 if isinstance(rihs01, str) else ""
        listed[tm["name"]] = ListedTopic(tm["type"], entry["message_count"], rihs01)
    return listed


@dataclass
class BagTopic:
    topic: str
    msgtype: str
    count: int = 0
    rihs01: str = ""
    msgdef: str = ""
    schema_encoding: str = ""
    serialization_format: str = "cdr"
    qos: list = field(default_factory=list)
    problem: str | None = None  # why the topic cannot be used (skipped), or None
    channels: list = field(default_factory=list)  # (scan index, channel id)


class Bag:
    """An opened bag: topics, counts and damage from a CRC-checked scan; ``messages()``."""

    def __init__(self, path: Path, metadata: dict | None, scans: list[McapScan]):
        self.path = path
        self.metadata = metadata
        self.scans = scans
        self.damage: list[Damage] = [d for s in scans for d in s.damage]
        self.notes: list[str] = []
        self.topics: dict[str, BagTopic] = {}
        self._collect_topics()
        if metadata is not None:
            self._compare_metadata(metadata)

    def _collect_topics(self) -> None:
        listed = listed_topics(self.metadata)
        for i, scan in enumerate(self.scans):
            for cid, ch in sorted(scan.channels.items()):
                schema = scan.schemas.get(ch.schema_id)
                entry = listed.get(ch.topic, UNLISTED)
                msgtype = schema.name if schema else entry.msgtype
                meta = ch.meta
                topic = self.topics.get(ch.topic)
                if topic is None:
                    topic = self.topics[ch.topic] = BagTopic(ch.topic, msgtype)
                    topic.rihs01 = meta.get("topic_type_hash") or entry.rihs01
                    topic.serialization_format = ch.message_encoding
                    topic.qos = _parse_qos(meta.get("offered_qos_profiles", ""))
                    if schema is not None:
                        topic.schema_encoding = schema.encoding
                        try:
                            topic.msgdef = schema.data.decode("utf-8")
                        except UnicodeDecodeError:
                            topic.problem = "its schema text is not UTF-8"
                    topic.problem = topic.problem or _topic_problem(ch, schema, msgtype)
                elif topic.msgtype != msgtype:
                    topic.problem = f"it has several types ({topic.msgtype}, {msgtype})"
                topic.channels.append((i, cid))
                topic.count += scan.counts.get(cid, 0)
        for topic in self.topics.values():
            if topic.problem:
                self.notes.append(
                    f"{self.path}: topic {topic.topic} ({topic.msgtype or 'no type'}, "
                    f"{topic.count} messages) is skipped: {topic.problem}"
                )

    def _compare_metadata(self, info: dict) -> None:
        custom = info.get("custom_data")
        state = custom if isinstance(custom, dict) else {}
        recording = state.get(STATE_KEY) == "recording"
        unfinished = any(not s.finished for s in self.scans)
        listed = listed_topics(info)
        meta = self.path / "metadata.yaml"
        absent, types, counts = [], [], []
        for name, (msgtype, count, _) in listed.items():
            topic = self.topics.get(name)
            if topic is None:
                absent.append(name)
                continue
            if topic.msgtype and msgtype != topic.msgtype:
                types.append(f"{name} {msgtype} (file: {topic.msgtype})")
            if count > topic.count or (count < topic.count and not (recording or unfinished)):
                counts.append(f"{name} {count} (file: {topic.count})")
        for items, what in (
            (absent, "lists topics the bag's files do not hold"),
            (types, "gives other types"),
            (counts, "gives other message counts"),
        ):
            if items:
                self._meta(f"{meta} {what}: {', '.join(items)}")
        unlisted = sorted(self.topics.keys() - listed.keys())
        if unlisted:
            self._meta(f"{meta} does not list topics {', '.join(unlisted)} (stale or damaged)")
        if recording and not unfinished:
            self._meta(f"{meta} is from a recording in progress (stale: the file was closed)")
        if not (recording or unfinished):
            self._compare_span(info, meta)

    def _compare_span(self, info: dict, meta: Path) -> None:
        """A closed bag's metadata.yaml gives its messages' start and duration (bags written
        before a start of 0 counted as a start said 10 s later: `bag recover` rewrites them)."""
        start = (info.get("starting_time") or {}).get("nanoseconds_since_epoch")
        duration = (info.get("duration") or {}).get("nanoseconds")
        if not self.message_count or not all(isinstance(v, int) for v in (start, duration)):
            return
        if abs(start - self.start_time) > 1 or abs(duration - self.duration_ns) > 1:
            self._meta(
                f"{meta} gives start {start * 1e-9:.9g} s and duration {duration * 1e-9:.9g} s; "
                f"the messages start at {self.start_time * 1e-9:.9g} s and span "
                f"{self.duration_ns * 1e-9:.9g} s"
            )

    def _meta(self, text: str) -> None:
        self.damage.append(Damage(METADATA, text))

    @property
    def usable_topics(self) -> dict[str, BagTopic]:
        return {t: v for t, v in self.topics.items() if v.problem is None}

    @property
    def message_count(self) -> int:
        return sum(t.count for t in self.topics.values())

    @property
    def start_time(self) -> int | None:
        return min((s.start_time for s in self.scans if s.start_time is not None), default=None)

    @property
    def end_time(self) -> int | None:
        return max((s.end_time for s in self.scans if s.end_time is not None), default=None)

    @property
    def duration_ns(self) -> int:
        start, end = self.start_time, self.end_time
        return 0 if start is None else end - start

    @property
    def lost(self) -> list[Damage]:
        """Damage that may have cost messages or definitions."""
        return [d for d in self.damage if d.kind == LOST]

    @property
    def cut(self) -> list[Damage]:
        """A cut-off end (a killed recorder): the last messages are missing."""
        return [d for d in self.damage if d.kind == INCOMPLETE]

    @property
    def intact(self) -> bool:
        return not self.damage

    def messages(self, topics=None):
        """``(topic, log_time, data)`` of the readable messages of usable topics (all of them,
        or those named), file by file, chunk by chunk."""
        names = set(self.usable_topics if topics is None else topics)
        for i, scan in enumerate(self.scans):
            wanted = {
                cid: t.topic
                for t in self.topics.values()
                if t.topic in names and t.problem is None
                for j, cid in t.channels
                if j == i
            }
            if not wanted:
                continue
            for cid, log_time, _, data in scan.records(wanted):
                yield wanted[cid], log_time, data

    def close(self) -> None:
        for scan in self.scans:
            scan.close()

    def __enter__(self) -> Bag:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@functools.lru_cache(maxsize=256)
def _parse_qos(text: str) -> list:
    """Offered QoS from a channel's metadata (cached: every bag repeats the same few; the
    list is shared, do not modify it)."""
    if not text:
        return []
    try:
        qos = yaml.load(text, Loader=_Loader)
    except yaml.YAMLError:
        return []
    return qos if isinstance(qos, list) else []


def _topic_problem(channel, schema, msgtype: str) -> str | None:
    if channel.schema_id and schema is None:
        return f"its schema (id {channel.schema_id}) is lost"
    if channel.message_encoding != "cdr":
        return f"message encoding {channel.message_encoding!r:.30} is not cdr"
    if schema is not None and schema.encoding not in ("ros2msg", "ros2idl"):
        return f"schema encoding {schema.encoding!r:.30} is not ros2msg or ros2idl"
    if not _TYPE_NAME.match(msgtype):
        return f"{msgtype!r:.60} is not a ROS 2 message type name"
    return None


def open_bag(path: str | Path) -> Bag:
    """Open a rosbag2 directory (or a single .mcap file) for reading; :class:`BagError` when
    nothing of it is usable."""
    path = Path(path)
    if not path.exists():
        raise BagError(f"{path}: no such bag (the path does not exist)")
    if path.is_file():
        if path.suffix != ".mcap":
            raise BagError(f"{path} is neither a rosbag2 directory nor an .mcap file")
        metadata, files = None, [path]
    else:
        metadata = read_metadata(path)
        files = [path / PurePath(name).name for name in metadata["relative_file_paths"]]
        missing = [str(f) for f in files if not f.exists()]
        if missing:
            raise BagError(f"{missing[0]} is missing (metadata.yaml lists it)")
    scans = []
    try:
        for f in files:
            scans.append(McapScan(f))
    except McapFileError as exc:
        for s in scans:
            s.close()
        raise BagError(str(exc)) from None
    bag = Bag(path, metadata, scans)
    for scan in scans:
        if scan.unverified_chunks:
            bag.notes.append(
                f"{scan.path}: {scan.unverified_chunks} chunks carry no CRC (written without "
                "checksums): damage inside them cannot be detected"
            )
        if scan.profile and scan.profile != "ros2":
            bag.notes.append(f"{scan.path}: MCAP profile {scan.profile!r:.30} is not ros2")
    return bag


def check_rate(rate) -> float:
    """A playback rate: a finite number in [MIN_RATE, MAX_RATE] (ValueError otherwise)."""
    try:
        value = float(rate)
    except (TypeError, ValueError):
        raise ValueError(f"rate must be a positive number, got {rate!r}") from None
    if not (math.isfinite(value) and MIN_RATE <= value <= MAX_RATE):
        raise ValueError(
            f"rate must be a positive finite number in [{MIN_RATE:g}, {MAX_RATE:g}], got {rate!r}"
        )
    return value
