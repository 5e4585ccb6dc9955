"""``activetrack bag recover BAG``: rebuild a readable bag from whatever of it verifies (a writer
that died, corrupt chunks, a missing, stale or garbled ``metadata.yaml``): the messages of every
verified chunk go to a clean MCAP file with a summary and a fresh ``metadata.yaml``. Nothing is
deleted: the originals are kept as ``<name>.mcap.damaged`` and ``metadata.yaml.old``. The report
names what was kept per topic and, one line each, what was lost.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path, PurePath

from activetrack_bringup.bag_io import (
    UNLISTED,
    BagError,
    Rosbag2Writer,
    TopicSpec,
    _parse_qos,
    listed_topics,
    open_bag,
    read_metadata,
)
from activetrack_bringup.mcap_reader import INCOMPLETE, LOST, McapFileError, McapScan

RECOVER_CHUNK_SIZE = 1 << 20  # the recovered file is written at once: larger chunks


@dataclass
class RecoverReport:
    bag: Path
    changed: bool  # False: the bag was intact, nothing was written
    kept: dict[str, int] = field(default_factory=dict)  # topic -> messages kept
    types: dict[str, str] = field(default_factory=dict)
    lost: list[str] = field(default_factory=list)  # one line each
    backups: list[Path] = field(default_factory=list)  # the originals, renamed

    @property
    def messages(self) -> int:
        return sum(self.kept.values())

    def to_json(self) -> dict:
        return {
            "bag": str(self.bag),
            "changed": self.changed,
            "messages": self.messages,
            "kept": self.kept,
            "types": self.types,
            "lost": self.lost,
            "backups": [str(p) for p in self.backups],
        }


def _move_aside(path: Path, suffix: str, report: RecoverReport) -> None:
    """Rename ``path`` to the first free ``<name><suffix>[.n]``, listed in ``report.backups``."""
    backup = path.with_name(path.name + suffix)
    n = 1
    while backup.exists():
        backup = path.with_name(f"{path.name}{suffix}.{n}")
        n += 1
    os.replace(path, backup)
    report.backups.append(backup)


def _mcap_file(bag_dir: Path) -> tuple[Path, dict | None, str | None]:
    """The bag's MCAP file, its metadata if readable, and why not if not."""
    try:
        meta = read_metadata(bag_dir)
    except BagError as exc:
        meta, why = None, str(exc)
    else:
        why = None
        names = [PurePath(n).name for n in meta["relative_file_paths"]]
        if len(names) == 1 and (bag_dir / names[0]).is_file():
            return bag_dir / names[0], meta, None
        if len(names) != 1:
            raise BagError(f"{bag_dir} is split into {len(names)} files: recover reads one")
    files = sorted(p for p in bag_dir.glob("*.mcap") if p.is_file())
    if not files:
        raise BagError(f"{bag_dir}: no .mcap file to recover from")
    if len(files) > 1:
        raise BagError(f"{bag_dir} holds {len(files)} .mcap files: recover reads one")
    return files[0], meta, why


def recover(path: str | Path) -> RecoverReport:
    """Rebuild ``path`` (a rosbag2 directory) from what of it verifies; see the module doc."""
    bag_dir = Path(path)
    if not bag_dir.exists():
        raise BagError(f"{bag_dir}: no such bag (the path does not exist)")
    if not bag_dir.is_dir():
        raise BagError(f"{bag_dir} is not a bag directory")
    try:
        with open_bag(bag_dir) as bag:
            if bag.intact:
                return RecoverReport(
                    bag_dir,
                    changed=False,
                    kept={t.topic: t.count for t in bag.topics.values()},
                    types={t.topic: t.msgtype for t in bag.topics.values()},
                )
    except BagError:
        pass  # recover what it can below
    mcap_path, old_meta, meta_problem = _mcap_file(bag_dir)
    try:
        scan = McapScan(mcap_path)
    except McapFileError as exc:
        raise BagError(f"nothing to recover: {exc}") from None
    report = RecoverReport(bag_dir, changed=True)
    tmp = bag_dir / f".recover-{os.getpid()}"
    try:
        with scan:
            report.lost = [str(d) for d in scan.damage if d.kind in (LOST, INCOMPLETE)]
            specs, channel_topic = _topics(scan, old_meta, report)
            if not specs:
                raise BagError(f"nothing to recover: no channel definition of {mcap_path} survives")
            if tmp.exists():
                shutil.rmtree(tmp)
            writer = Rosbag2Writer(
                tmp,
                specs,
                chunk_size=RECOVER_CHUNK_SIZE,
                chunk_age_s=1e9,
                state="recovered",
                file_name=mcap_path.name,
            )
            try:
                ids = {cid: writer.channel_ids[topic] for cid, topic in channel_topic.items()}
                for cid, log_time, publish_time, data in scan.records(ids):
                    writer.write(ids[cid], log_time, data, publish_time)
                    report.kept[channel_topic[cid]] += 1
            except BaseException:
                writer.abandon()
                raise
            writer.close(state="recovered")
            mcap_damaged = bool(scan.damage)
        _note_metadata_losses(bag_dir, old_meta, meta_problem, report)
        _install(bag_dir, tmp, mcap_path, mcap_damaged, report)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return report


def _note_metadata_losses(
    bag_dir: Path, old_meta: dict | None, meta_problem: str | None, report: RecoverReport
) -> None:
    """Add to ``report.lost`` what the old metadata.yaml listed beyond what was kept."""
    if old_meta is not None:
        short = [
            f"{topic} {t.count} (kept {report.kept.get(topic, 0)})"
            for topic, t in sorted(listed_topics(old_meta).items())
            if t.count > report.kept.get(topic, 0)
        ]
        if short:
            report.lost.append(f"{bag_dir}/metadata.yaml listed more: {', '.join(short)}")
    elif meta_problem:
        report.lost.append(f"{meta_problem} (rebuilt from the .mcap file)")


def _install(
    bag_dir: Path, tmp: Path, mcap_path: Path, mcap_damaged: bool, report: RecoverReport
) -> None:
    """Move the rebuilt files from ``tmp`` into the bag; the originals keep their data under
    new names (listed in ``report.backups``), nothing is deleted."""
    if mcap_damaged:
        _move_aside(mcap_path, ".damaged", report)
        os.replace(tmp / mcap_path.name, mcap_path)
    meta_path = bag_dir / "metadata.yaml"
    if meta_path.exists():
        _move_aside(meta_path, ".old", report)
    os.replace(tmp / "metadata.yaml", meta_path)


def _topics(scan: McapScan, old_meta: dict | None, report: RecoverReport):
    """TopicSpecs for the channels that can be kept, and ``{channel id: topic}``."""
    listed = listed_topics(old_meta)
    specs, channel_topic, seen = [], {}, {}
    for cid, ch in sorted(scan.channels.items()):
        schema = scan.schemas.get(ch.schema_id)
        n = scan.counts.get(cid, 0)
        if schema is None:
            report.lost.append(
                f"{scan.path}: {n} messages of {ch.topic} dropped: their schema is lost"
            )
            continue
        if ch.topic in seen:
            if seen[ch.topic] != schema.name:
                report.lost.append(
                    f"{scan.path}: {n} messages of {ch.topic} ({schema.name}) dropped: the "
                    f"topic also has type {seen[ch.topic]}"
                )
                continue
            channel_topic[cid] = ch.topic  # a second channel of the same topic: merged
            continue
        seen[ch.topic] = schema.name
        meta = ch.meta
        specs.append(
            TopicSpec(
                topic=ch.topic,
                msgtype=schema.name,
                msgdef=schema.data.decode("utf-8", errors="replace"),
                rihs01=meta.get("topic_type_hash") or listed.get(ch.topic, UNLISTED).rihs01,
                qos=_parse_qos(meta.get("offered_qos_profiles", "")),
                serialization_format=ch.message_encoding,
                schema_encoding=schema.encoding,
                schema_data=schema.data,
            )
        )
        channel_topic[cid] = ch.topic
        report.kept[ch.topic] = 0
        report.types[ch.topic] = schema.name
    return specs, channel_topic
