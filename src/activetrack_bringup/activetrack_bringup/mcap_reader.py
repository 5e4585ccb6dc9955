"""Read MCAP files defensively: every CRC the format has is checked, damage is located (file and
offset) and described in one line, and a damaged file never raises anything but
:class:`McapFileError` (nothing readable at all) while the rest of it stays readable.

What is checked, and what a failure means:

* each chunk: its length fields, compression, uncompressed size and CRC (of the uncompressed
  records); a chunk that fails is skipped and reported, never decoded;
* the data section's CRC (DataEnd), once the scan reaches it;
* the summary's CRC (footer); a valid summary is then compared with what the scan found
  (chunks, message counts, schemas and channels), which tells harmless damage (a message index,
  the header) from lost data;
* record boundaries: after a record that cannot be parsed, reading resumes only at the next
  chunk whose CRC verifies (from the summary's chunk index if there is one, else by search).

Damage kinds: ``lost`` (messages or definitions may be missing), ``incomplete`` (the writer
stopped: no summary, a record cut off at the end), ``harmless`` (detected, and proven not to
touch messages or definitions: they all come from verified chunks or the verified summary).
"""

from __future__ import annotations

import mmap
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

MAGIC = b"\x89MCAP0\r\n"
LOST, INCOMPLETE, HARMLESS = "lost", "incomplete", "harmless"
MAX_CHUNK_SIZE = 1 << 31  # a larger uncompressed size is taken for damage, not allocated

_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_RECORD = struct.Struct("<BQ")
_MESSAGE = struct.Struct("<HIQQ")
_CHUNK = struct.Struct("<QQQII")

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 1, 2, 3, 4, 5, 6
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_ATTACHMENT, OP_ATTACHMENT_INDEX = 7, 8, 9, 10
OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX, OP_SUMMARY_OFFSET, OP_DATA_END = 11, 12, 13, 14, 15
_KNOWN_DATA_OPS = {OP_HEADER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX}
_KNOWN_DATA_OPS |= {OP_ATTACHMENT, OP_METADATA, OP_DATA_END}


class McapFileError(ValueError):
    """Nothing of the file is readable (missing, empty, not MCAP); the message is one line."""


class _Bad(Exception):
    """A record that does not parse; the message says why."""


@dataclass
class Damage:
    kind: str  # LOST, INCOMPLETE or HARMLESS
    text: str  # one line, naming the file and the offset
    offset: int | None = None
    region: bool = False  # an unreadable stretch of the data section (what it held unknown)

    def __str__(self) -> str:
        return self.text


@dataclass(frozen=True)
class SchemaInfo:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class ChannelInfo:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: tuple  # ((key, value), ...), hashable

    @property
    def meta(self) -> dict[str, str]:
        return dict(self.metadata)


@dataclass
class ChunkInfo:
    """A chunk that verified: where it is and what it holds."""

    offset: int
    counts: dict[int, int] = field(default_factory=dict)


# --- field parsing (bounds-checked) -------------------------------------------------------


def _string(buf, pos: int, end: int) -> tuple[str, int]:
    raw, pos = _prefixed(buf, pos, end)
    try:
        return raw.decode("utf-8"), pos
    except UnicodeDecodeError:
        raise _Bad("a string field is not UTF-8") from None


def _span(buf, pos: int, end: int, what: str) -> tuple[int, int]:
    """``(start, stop)`` of the u32-length-prefixed field at ``pos``, inside ``end``."""
    if pos + 4 > end:
        raise _Bad(f"a {what} runs past its record")
    (n,) = _U32.unpack_from(buf, pos)
    if pos + 4 + n > end:
        raise _Bad(f"a {what} runs past its record")
    return pos + 4, pos + 4 + n


def _prefixed(buf, pos: int, end: int) -> tuple[bytes, int]:
    start, stop = _span(buf, pos, end, "field")
    return bytes(buf[start:stop]), stop


def _map(buf, pos: int, end: int) -> tuple[tuple, int]:
    pos, stop = _span(buf, pos, end, "map field")
    items = []
    while pos < stop:
        key, pos = _string(buf, pos, stop)
        value, pos = _string(buf, pos, stop)
        items.append((key, value))
    return tuple(items), pos


def parse_schema(buf, pos: int, end: int) -> SchemaInfo:
    if pos + 2 > end:
        raise _Bad("schema record too short")
    (sid,) = _U16.unpack_from(buf, pos)
    name, p = _string(buf, pos + 2, end)
    encoding, p = _string(buf, p, end)
    data, p = _prefixed(buf, p, end)
    if sid == 0:
        raise _Bad("schema id 0")
    return SchemaInfo(sid, name, encoding, data)


def parse_channel(buf, pos: int, end: int) -> ChannelInfo:
    if pos + 4 > end:
        raise _Bad("channel record too short")
    cid, sid = struct.unpack_from("<HH", buf, pos)
    topic, p = _string(buf, pos + 4, end)
    encoding, p = _string(buf, p, end)
    metadata, p = _map(buf, p, end)
    return ChannelInfo(cid, sid, topic, encoding, metadata)


def decompress(compression: str, data: bytes, size: int) -> bytes:
    """The records of a chunk, at most ``size`` bytes (a damaged size allocates nothing)."""
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        try:
            return zstandard.ZstdDecompressor().stream_reader(data).read(size + 1)
        except zstandard.ZstdError as exc:
            raise _Bad(f"zstd data does not decompress ({exc})") from None
    if compression == "lz4":
        import lz4.frame

        try:
            return lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=size + 1)
        except RuntimeError as exc:
            raise _Bad(f"lz4 data does not decompress ({exc})") from None
    raise _Bad(f"unknown compression {compression[:20]!r}")


def parse_chunk(buf, pos: int, end: int) -> tuple[int, int, bytes, int]:
    """``(start, end, records, crc)`` of the Chunk record body at ``buf[pos:end]``, verified."""
    if pos + 40 > end:
        raise _Bad("chunk record too short")
    start, stop, size, crc, clen = _CHUNK.unpack_from(buf, pos)
    p = pos + 32
    if clen > 64 or p + clen + 8 > end:
        raise _Bad("damaged compression field")
    try:
        compression = bytes(buf[p : p + clen]).decode("ascii")
    except UnicodeDecodeError:
        raise _Bad("damaged compression field") from None
    p += clen
    (csize,) = _U64.unpack_from(buf, p)
    p += 8
    if p + csize != end:
        raise _Bad("the chunk's length fields disagree")
    if size > MAX_CHUNK_SIZE or (compression == "" and csize != size):
        raise _Bad("damaged uncompressed size")
    records = decompress(compression, bytes(buf[p : p + csize]), size)
    if len(records) != size:
        raise _Bad(f"holds {len(records)} bytes of records, its header says {size}")
    if crc and zlib.crc32(records) != crc:
        raise _Bad("CRC mismatch")
    return start, stop, records, crc


def records_in(buf, pos: int, stop: int, what: str, past: str):
    """``(opcode, body_start, body_end)`` of each record in ``buf[pos:stop]``; ``_Bad`` naming
    ``what`` (the records) for one cut off or running ``past`` them."""
    while pos < stop:
        if pos + 9 > stop:
            raise _Bad(f"{what} is cut off")
        op, length = _RECORD.unpack_from(buf, pos)
        body = pos + 9
        if body + length > stop:
            raise _Bad(f"{what} runs past {past}")
        yield op, body, body + length
        pos = body + length


def chunk_records(records: bytes):
    """``(opcode, body_start, body_end)`` of each record inside a chunk's records."""
    return records_in(records, 0, len(records), "a record inside the chunk", "it")


# --- the scan ---------------------------------------------------------------------------


class McapScan:
    """One pass over an MCAP file: definitions, verified chunks, counts and damage;
    ``records()`` reads the verified chunks again. A context manager (or call ``close()``)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.profile = ""
        self.library = ""
        self.schemas: dict[int, SchemaInfo] = {}
        self.channels: dict[int, ChannelInfo] = {}
        self.counts: dict[int, int] = {}
        self.start_time: int | None = None
        self.end_time: int | None = None
        self.chunks: list[ChunkInfo] = []
        self.loose: list[int] = []  # offsets of Message records outside chunks
        self.metadata: dict[str, dict[str, str]] = {}
        self.damage: list[Damage] = []
        self.summary: dict | None = None  # verified summary: schemas, channels, stats, chunks
        self.data_end: int | None = None  # offset of DataEnd, when reached
        self.data_crc_ok: bool | None = None
        self.unverified_chunks = 0  # chunks without CRC (not verifiable)
        self._sequences: dict[int, list[int]] = {}
        self._footer = "absent"
        self._unverified: set[str] = set()  # what was taken from outside verified chunks
        self._file = None
        self._mm = None
        try:
            self._open()
            self._scan()
        except BaseException:
            self.close()
            raise

    # --- opening ---------------------------------------------------------------------

    def _open(self) -> None:
        try:
            self._file = open(self.path, "rb")
            self.size = self.path.stat().st_size
        except IsADirectoryError:
            raise McapFileError(f"{self.path} is a directory, not an MCAP file") from None
        except OSError as exc:
            raise McapFileError(f"{self.path}: {exc.strerror or exc}") from None
        if self.size == 0:
            raise McapFileError(f"{self.path} is empty (0 bytes): nothing was recorded in it")
        self._mm = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ)
        head = self._mm[:17]
        if head[:8] != MAGIC:
            # One or two damaged bytes of the magic, a Header record after it: still MCAP.
            close = (
                len(head) == 17 and sum(a == b for a, b in zip(head[:8], MAGIC, strict=True)) >= 6
            )
            if not (close and head[8] == OP_HEADER and _U64.unpack_from(head, 9)[0] < 4096):
                raise McapFileError(f"{self.path} is not an MCAP file (no MCAP magic at offset 0)")
            self._damage(HARMLESS, "damaged MCAP magic (the rest reads)", 0)

    def close(self) -> None:
        if self._mm is not None:
            self._mm.close()
            self._mm = None
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> McapScan:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _damage(self, kind: str, what: str, offset: int | None = None, why: str = "") -> Damage:
        at = f" at offset {offset}" if offset is not None else ""
        damage = Damage(kind, f"{self.path}: {what}{at}{why}", offset)
        self.damage.append(damage)
        return damage

    # --- summary ---------------------------------------------------------------------

    def _read_summary(self) -> int:
        """Parse and verify footer and summary; return where the data section must end."""
        mm, size = self._mm, self.size
        if size < 8 + 9 + 37 or mm[size - 8 :] != MAGIC:
            self._footer = "absent"
            return size  # no footer: the writer did not finish (reported after the scan)
        self._footer = "present"
        footer = size - 37
        op, length = _RECORD.unpack_from(mm, footer)
        if op != OP_FOOTER or length != 20:
            self._damage(HARMLESS, "damaged footer record (summary ignored)", footer)
            return size
        summary_start, offset_start, crc = struct.unpack_from("<QQI", mm, footer + 9)
        if summary_start == 0:
            self.summary = {}  # a finished file without summary
            return footer
        if not 8 < summary_start <= footer or not (
            offset_start == 0 or summary_start <= offset_start <= footer
        ):
            self._damage(HARMLESS, "the footer's summary offsets are damaged (ignored)", footer)
            return size
        if crc and zlib.crc32(mm[summary_start : footer + 25]) != crc:
            self._damage(HARMLESS, "summary CRC mismatch (summary ignored)", summary_start)
            return summary_start
        summary = {"schemas": {}, "channels": {}, "chunks": [], "stats": None}
        try:
            records = records_in(mm, summary_start, footer, "a summary record", "the footer")
            for op, body, end in records:
                if op == OP_SCHEMA:
                    s = parse_schema(mm, body, end)
                    summary["schemas"][s.id] = s
                elif op == OP_CHANNEL:
                    c = parse_channel(mm, body, end)
                    summary["channels"][c.id] = c
                elif op == OP_CHUNK_INDEX:
                    summary["chunks"].append(self._parse_chunk_index(body, end))
                elif op == OP_STATISTICS:
                    summary["stats"] = self._parse_statistics(body, end)
        except (_Bad, struct.error, ValueError) as exc:
            self._damage(HARMLESS, f"unreadable summary ({exc}; ignored)", summary_start)
            return summary_start
        self.summary = summary
        return summary_start

    def _parse_chunk_index(self, pos: int, end: int) -> tuple[int, dict[int, int]]:
        """``(chunk offset, {channel: message count})`` from a ChunkIndex record."""
        mm = self._mm
        if pos + 36 > end:
            raise _Bad("chunk index too short")
        offset, chunk_length = struct.unpack_from("<QQ", mm, pos + 16)
        (n,) = _U32.unpack_from(mm, pos + 32)
        p = pos + 36
        if p + n + 8 > end or n % 10:
            raise _Bad("damaged chunk index")
        entries = sorted(
            (o, c) for c, o in (struct.unpack_from("<HQ", mm, p + i) for i in range(0, n, 10))
        )
        (index_length,) = _U64.unpack_from(mm, p + n)
        # Message counts from the index offsets, as rosbags does: records follow one another.
        stops = [o for o, _ in entries[1:]] + [offset + chunk_length + index_length]
        counts = {c: (stop - o - 15) // 16 for (o, c), stop in zip(entries, stops, strict=False)}
        return offset, counts

    def _parse_statistics(self, pos: int, end: int) -> dict:
        mm = self._mm
        if pos + 46 > end:
            raise _Bad("statistics too short")
        count = _U64.unpack_from(mm, pos)[0]
        (n,) = _U32.unpack_from(mm, pos + 42)
        if pos + 46 + n > end or n % 10:
            raise _Bad("damaged statistics")
        per = dict(struct.unpack_from("<HQ", mm, pos + 46 + i) for i in range(0, n, 10))
        return {"message_count": count, "channel_message_counts": per}

    # --- data section ----------------------------------------------------------------

    def _scan(self) -> None:
        limit = self._read_summary()
        mm = self._mm
        pos = 8
        previous = None  # the verified chunk the next MessageIndex records belong to
        while pos < limit:
            if pos + 9 > limit:
                if self.summary is None:
                    what = f"file ends inside a record ({limit - pos} bytes)"
                    self._damage(INCOMPLETE, what, pos)
                else:
                    self._damage(LOST, "damaged data section end", pos)
                break
            op, length = _RECORD.unpack_from(mm, pos)
            body, end = pos + 9, pos + 9 + length
            if end > limit or op not in _KNOWN_DATA_OPS or (pos == 8) != (op == OP_HEADER):
                resume = self._resync(pos + 1, limit)
                if resume is None and self.summary is None and end > limit >= self.size:
                    if op in _KNOWN_DATA_OPS:
                        self._damage(
                            INCOMPLETE,
                            f"file ends inside a record ({limit - pos} of {9 + length} bytes:"
                            " the writer stopped)",
                            pos,
                        )
                    else:
                        self._damage(LOST, f"unreadable bytes to the end ({limit - pos})", pos)
                    break
                self._lost_region(pos, resume, op)
                if resume is None:
                    break
                pos, previous = resume, None
                continue
            try:
                if op == OP_CHUNK:
                    previous = self._chunk(pos, body, end)
                elif op == OP_MESSAGE_INDEX:
                    self._message_index(previous, pos, body, end)
                else:
                    previous = None
                    if op == OP_DATA_END:
                        self._data_end(pos, body, end)
                        break
                    self._loose_record(op, pos, body, end)
            except (_Bad, struct.error, ValueError) as exc:  # ValueError: e.g. a bad enum
                what = "corrupt chunk" if op == OP_CHUNK else f"damaged record (opcode {op:#04x})"
                resume = self._resync(pos + 1, limit)
                self._lost_region(pos, resume, op, what, str(exc))
                if resume is None:
                    break
                pos, previous = resume, None
                continue
            pos = end
        self._finish()

    def _lost_region(self, pos, resume, op, what=None, reason="") -> None:
        if what is None:
            what = f"unreadable record (opcode {op:#04x})"
        if resume is None:
            skipped = "skipped the rest of the data section"
        else:
            skipped = f"skipped {resume - pos} bytes to the next verified chunk"
        why = f" ({reason}; {skipped})" if reason else f" ({skipped})"
        self._damage(LOST, what, pos, why).region = True

    def _resync(self, start: int, limit: int) -> int | None:
        """The offset of the next chunk after ``start`` that verifies, or None."""
        if self.summary:
            candidates = sorted(o for o, _ in self.summary["chunks"] if start <= o < limit)
            for offset in candidates:
                if self._verifies(offset, limit):
                    return offset
        mm = self._mm
        p = start
        while True:
            p = mm.find(b"\x06", p, limit - 49)
            if p < 0:
                return None
            if self._verifies(p, limit):
                return p
            p += 1

    def _verifies(self, pos: int, limit: int) -> bool:
        mm = self._mm
        if pos + 49 > limit:
            return False
        op, length = _RECORD.unpack_from(mm, pos)
        if op != OP_CHUNK or pos + 9 + length > limit or length < 40:
            return False
        (crc,) = _U32.unpack_from(mm, pos + 9 + 24)
        if crc == 0:
            return False  # an unverifiable "chunk" is no place to resume
        try:
            parse_chunk(mm, pos + 9, pos + 9 + length)
        except (_Bad, struct.error):
            return False
        return True

    def _chunk(self, pos: int, body: int, end: int) -> ChunkInfo:
        _, _, records, crc = parse_chunk(self._mm, body, end)
        if not crc:
            self.unverified_chunks += 1
        info = ChunkInfo(pos)
        defs, msgs = [], []
        for op, b, e in chunk_records(records):
            if op == OP_SCHEMA:
                defs.append(parse_schema(records, b, e))
            elif op == OP_CHANNEL:
                defs.append(parse_channel(records, b, e))
            elif op == OP_MESSAGE:
                if e - b < 22:
                    raise _Bad("a message record inside the chunk is too short")
                msgs.append(_MESSAGE.unpack_from(records, b))
        # Only a chunk that parsed whole counts.
        for d in defs:
            self._define(d, verified=bool(crc), offset=pos)
        for cid, seq, log_time, _ in msgs:
            self._count(cid, seq, log_time)
            info.counts[cid] = info.counts.get(cid, 0) + 1
        if not crc and msgs:
            self._unverified.add("messages")
        self.chunks.append(info)
        return info

    def _message_index(self, chunk: ChunkInfo | None, pos: int, body: int, end: int) -> None:
        """MessageIndex records follow their chunk; one elsewhere may be a damaged chunk."""
        mm = self._mm
        if end - body < 6:
            raise _Bad("message index too short")
        cid, n = struct.unpack_from("<HI", mm, body)
        if chunk is None:
            raise _Bad("a message index that follows no chunk")
        if body + 6 + n != end or n % 16:
            raise _Bad("damaged message index (or a chunk with a damaged opcode)")
        if chunk.counts.get(cid) != n // 16:
            self._damage(HARMLESS, "message index does not match its chunk (not used)", pos)

    def _loose_record(self, op: int, pos: int, body: int, end: int) -> None:
        mm = self._mm
        if op == OP_HEADER:
            self.profile, p = _string(mm, body, end)
            self.library, _ = _string(mm, p, end)
        elif op in (OP_SCHEMA, OP_CHANNEL):
            parse = parse_schema if op == OP_SCHEMA else parse_channel
            self._define(parse(mm, body, end), verified=False, offset=pos)
        elif op == OP_MESSAGE:
            if end - body < 22:
                raise _Bad("message record too short")
            if self.library.startswith("activetrack"):
                raise _Bad("a message outside chunks (this writer never writes one)")
            cid, seq, log_time, _ = _MESSAGE.unpack_from(mm, body)
            self._count(cid, seq, log_time)
            self.loose.append(pos)
            self._unverified.add("messages")
        elif op == OP_METADATA:
            name, p = _string(mm, body, end)
            values, _ = _map(mm, p, end)
            self.metadata[name] = dict(values)

    def _define(self, record, *, verified: bool, offset: int) -> None:
        table = self.schemas if isinstance(record, SchemaInfo) else self.channels
        kind = "schema" if isinstance(record, SchemaInfo) else "channel"
        old = table.get(record.id)
        if old is not None and old != record:
            self._damage(LOST, f"{kind} {record.id} is defined twice, differently", offset)
            return
        table[record.id] = record
        if not verified:
            self._unverified.add(f"{kind}s")

    def _count(self, cid: int, seq: int, log_time: int) -> None:
        self.counts[cid] = self.counts.get(cid, 0) + 1
        self._sequences.setdefault(cid, []).append(seq)
        if self.start_time is None or log_time < self.start_time:
            self.start_time = log_time
        if self.end_time is None or log_time > self.end_time:
            self.end_time = log_time

    def _data_end(self, pos: int, body: int, end: int) -> None:
        if end - body < 4:
            raise _Bad("DataEnd record too short")
        self.data_end = pos
        (expected,) = _U32.unpack_from(self._mm, body)
        if not expected:
            return
        crc = 0
        for i in range(0, pos, 1 << 20):
            crc = zlib.crc32(self._mm[i : min(i + (1 << 20), pos)], crc)
        self.data_crc_ok = crc == expected

    # --- after the scan: what the summary and the sequences say ------------------------

    def _finish(self) -> None:
        summary = self.summary
        if summary is None and self.data_end is None:
            has_tail = any(d.kind == INCOMPLETE for d in self.damage)
            self._damage(
                INCOMPLETE,
                "no summary: the writer did not finish (killed?); read by scanning its "
                f"{len(self.chunks)} complete chunks" + ("" if has_tail else ", nothing cut off"),
            )
        elif summary is None and self._footer == "absent":
            self._damage(HARMLESS, "no valid footer after the data section (summary ignored)")
        consistent = self._consistent_with_summary()
        if consistent:
            # Unreadable stretches between verified chunks held nothing the summary lists.
            for d in self.damage:
                if d.kind == LOST and d.region:
                    d.kind = HARMLESS
                    d.text += "; every indexed chunk verified, nothing is missing"
        explained = any(d.kind == LOST and d.region for d in self.damage)
        if self.data_crc_ok is False and not explained:  # (a skipped stretch explains it)
            if consistent and "messages" not in self._unverified:
                self._damage(
                    HARMLESS,
                    "data section CRC mismatch outside the messages and definitions (header, "
                    "message index or metadata record): every chunk verified and matches the "
                    "summary",
                    self.data_end,
                )
            else:
                self._damage(
                    LOST,
                    "data section CRC mismatch: records outside chunks "
                    f"({', '.join(sorted(self._unverified)) or 'boundaries'}) may be damaged",
                    self.data_end,
                )
        self._sequence_gaps()
        self._orphans()

    def _consistent_with_summary(self) -> bool:
        """Compare the scan with a verified summary (reporting what differs); True when every
        indexed chunk verified, counts agree and definitions equal the summary's copies."""
        summary = self.summary
        if not summary:
            return False
        ok = True
        found = {c.offset for c in self.chunks}
        reported = {d.offset for d in self.damage}
        for offset, counts in summary["chunks"]:
            if offset not in found:
                n = sum(counts.values())
                ok = ok and not n
                if offset not in reported:
                    held = f"{n} messages" if n else "definitions only"
                    self._damage(
                        LOST if n else HARMLESS, f"indexed chunk unreadable ({held})", offset
                    )
        for table, key in ((self.schemas, "schemas"), (self.channels, "channels")):
            for rid, record in summary[key].items():
                mine = table.get(rid)
                if mine is None:
                    table[rid] = record  # e.g. from a damaged definitions chunk
                elif mine != record:
                    ok = False
                    self._damage(LOST, f"{key[:-1]} {rid} differs from the summary's copy")
            ok = ok and set(table) == set(summary[key])
        stats = summary["stats"]
        if stats is not None:
            for cid in set(stats["channel_message_counts"]) | set(self.counts):
                n = stats["channel_message_counts"].get(cid, 0)
                if self.counts.get(cid, 0) != n:
                    ok = False
                    if not any(d.kind == LOST for d in self.damage):
                        self._damage(
                            LOST,
                            f"the summary counts {n} messages on {self._topic(cid)}, "
                            f"{self.counts.get(cid, 0)} are readable",
                        )
        return ok

    def _sequence_gaps(self) -> None:
        """This project's writer numbers each channel's messages 1, 2, ...: a gap is a loss."""
        if not self.library.startswith("activetrack"):
            return
        gaps = []
        for cid, seqs in sorted(self._sequences.items()):
            if not seqs or min(seqs) < 1:
                continue
            missing = max(seqs) - len(set(seqs))
            if missing > 0:
                gaps.append(f"{self._topic(cid)} {missing}")
        if gaps:
            self._damage(
                LOST, f"messages missing (gaps in their sequence numbers): {', '.join(gaps)}"
            )

    def _topic(self, cid: int) -> str:
        c = self.channels.get(cid)
        return c.topic if c else f"channel {cid}"

    def _orphans(self) -> None:
        for cid, n in sorted(self.counts.items()):
            if cid not in self.channels:
                self._damage(LOST, f"{n} messages on channel {cid}, whose definition is lost")

    # --- results ---------------------------------------------------------------------

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    @property
    def finished(self) -> bool:
        """The writer finished: the file has a valid footer (and DataEnd)."""
        return self.summary is not None

    def records(self, channel_ids=None):
        """``(channel_id, log_time, publish_time, data)`` of every readable message, chunk by
        chunk in file order, in log-time order within a chunk (as rosbags reads them)."""
        wanted = None if channel_ids is None else set(channel_ids)
        mm = self._mm
        sources = [(c.offset, c) for c in self.chunks] + [(o, None) for o in self.loose]
        for offset, chunk in sorted(sources, key=lambda s: s[0]):
            if chunk is not None and wanted is not None and not wanted & chunk.counts.keys():
                continue
            _, length = _RECORD.unpack_from(mm, offset)
            if chunk is None:
                cid, _, log_time, publish_time = _MESSAGE.unpack_from(mm, offset + 9)
                if wanted is None or cid in wanted:
                    yield cid, log_time, publish_time, mm[offset + 9 + 22 : offset + 9 + length]
                continue
            _, _, records, _ = parse_chunk(mm, offset + 9, offset + 9 + length)
            batch = []
            for op, b, e in chunk_records(records):
                if op == OP_MESSAGE:
                    cid, _, log_time, publish_time = _MESSAGE.unpack_from(records, b)
                    if wanted is None or cid in wanted:
                        batch.append((log_time, len(batch), cid, publish_time, b + 22, e))
            batch.sort()
            for log_time, _, cid, publish_time, b, e in batch:
                yield cid, log_time, publish_time, records[b:e]
