"""An MCAP writer for recordings that must stay readable while they grow.

The file is only ever appended to, and every chunk reaches the OS whole before the next one
starts, so a writer that dies (kill -9, a crash, a full disk) leaves a file whose every
complete chunk is readable and verified by its CRC; ``activetrack bag recover`` rewrites it with
a summary. Layout, as the MCAP specification (https://mcap.dev/spec) allows:

* magic, Header (profile ``ros2``);
* a definitions chunk: the Schema and Channel records alone, CRC-protected, written and flushed
  at :meth:`McapWriter.start` (a new definition later gets a chunk of its own), so that the
  definitions are on disk before the first message and a damaged message chunk never takes
  them along;
* message chunks, each closed when it holds ``chunk_size`` bytes or its first message is
  ``chunk_age_s`` old (checked on each write and by :meth:`McapWriter.flush_if_older`, which a
  timer calls), followed by its MessageIndex records, all in one ``write(2)``;
* at :meth:`McapWriter.close`: Metadata records, DataEnd with the CRC of the whole data section,
  the summary (schemas, channels, statistics, chunk and metadata indexes, summary offsets) and
  the footer with the summary's CRC.

Records are encoded with the ``mcap`` library's record classes, except Message and
MessageIndex records, which are packed here directly: the hot path costs a few microseconds per
message (one ``struct.pack`` and two ``bytearray`` appends). ``mcap.writer.Writer`` is not used
because (mcap 1.6) it keeps Schema and Channel records inside the first *message* chunk, and
only writes them with the first message, so one damaged chunk of a killed recording would
lose every channel definition; and it has no time-based chunk close.
"""

from __future__ import annotations

import os
import struct
import time
import zlib
from collections import defaultdict

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
CHUNK_SIZE = 64 * 1024  # bytes of records per message chunk (a larger message gets one alone)
CHUNK_AGE_S = 0.5  # seconds after its first message a chunk is closed at the latest

_MESSAGE = struct.Struct("<BQHIQQ")  # opcode, record length, channel, sequence, log, publish
_MESSAGE_INDEX = struct.Struct("<BQHI")  # opcode, record length, channel, records length
_CHUNK_HEAD = struct.Struct("<BQQQQII")  # opcode, length, start, end, size, crc, compression len


def _zstd():
    import zstandard

    return zstandard.ZstdCompressor(level=1).compress


class McapWriter:
    """Appends an MCAP file chunk by chunk; see the module docstring for the layout.

    ``write`` is cheap and may be called from an executor thread; ``flush_if_older`` from a
    timer of the same thread. Not thread-safe by itself (the recorder calls it from one
    callback group).
    """

    def __init__(
        self,
        path,
        *,
        profile: str = "ros2",
        library: str = "activetrack",
        chunk_size: int = CHUNK_SIZE,
        chunk_age_s: float = CHUNK_AGE_S,
        compression: str = "",
    ):
        if compression not in ("", "zstd"):
            raise ValueError(f"compression must be '' or 'zstd', got {compression!r}")
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self.profile = profile
        self.library = library
        self.chunk_size = int(chunk_size)
        self.chunk_age_ns = int(chunk_age_s * 1e9)
        self.compression = compression
        self._compress = _zstd() if compression == "zstd" else None
        self._pos = 0  # bytes written so far
        self._crc = 0  # CRC of the data section so far
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._pending_defs: list = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._metadata_count = 0
        # The open message chunk.
        self._buf = bytearray()
        self._index: dict[int, list[int]] = defaultdict(list)  # channel -> [time, offset, ...]
        self._chunk_start = 0
        self._chunk_end = 0
        self._chunk_opened_mono = 0  # monotonic clock then (the timer's age: no clock jumps)
        self._seq: dict[int, int] = defaultdict(int)
        # What is on disk (complete chunks): counts per channel and time range (None: no
        # message yet; a start of 0, e.g. sim time 0, is a start like any other).
        self.flushed_counts: dict[int, int] = defaultdict(int)
        self.flushed_start: int | None = None
        self.flushed_end = 0
        self.written = 0  # messages handed to write()
        self.started = False
        self.closed = False

    # --- definitions ---------------------------------------------------------------------

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, data=data, encoding=encoding, name=name)
        self._schemas[schema.id] = schema
        self._define(schema)
        return schema.id

    def add_channel(
        self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]
    ) -> int:
        if schema_id and schema_id not in self._schemas:
            raise ValueError(f"unknown schema id {schema_id}")
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            metadata=dict(metadata),
            schema_id=schema_id,
        )
        self._channels[channel.id] = channel
        self._define(channel)
        return channel.id

    def _define(self, record) -> None:
        self._pending_defs.append(record)
        if self.started:  # a definition after start: a chunk of its own, now
            self._write_definitions()

    def start(self) -> None:
        """Write magic, header and the definitions so far, and flush them to the OS."""
        if self.started:
            return
        builder = RecordBuilder()
        Header(self.profile, self.library).write(builder)
        self._out([MAGIC, builder.end()])
        self.started = True
        self._write_definitions()

    def _write_definitions(self) -> None:
        if not self._pending_defs:
            return
        self._close_chunk()  # messages before definitions keep their order in the file
        builder = RecordBuilder()
        for record in self._pending_defs:
            record.write(builder)
        self._pending_defs.clear()
        self._write_chunk(builder.end(), 0, 0, {})

    # --- messages ------------------------------------------------------------------------

    def write(self, channel_id: int, log_time: int, data, publish_time: int | None = None) -> None:
        """Append one message (raw bytes) to the open chunk; closes the chunk when full/old."""
        buf = self._buf
        if not buf:
            self._chunk_start = self._chunk_end = log_time
            self._chunk_opened_mono = time.monotonic_ns()
        elif log_time < self._chunk_start:
            self._chunk_start = log_time
        elif log_time > self._chunk_end:
            self._chunk_end = log_time
        seq = self._seq[channel_id] = self._seq[channel_id] + 1
        self._index[channel_id] += (log_time, len(buf))
        buf += _MESSAGE.pack(
            Opcode.MESSAGE,
            22 + len(data),
            channel_id,
            seq & 0xFFFFFFFF,
            log_time,
            log_time if publish_time is None else publish_time,
        )
        buf += data
        self.written += 1
        # Age by the monotonic clock, not log time (sim time can run far faster or slower).
        if len(buf) >= self.chunk_size or (
            time.monotonic_ns() - self._chunk_opened_mono >= self.chunk_age_ns
        ):
            self._close_chunk()

    def flush_if_older(self, age_s: float | None = None) -> bool:
        """Close the open chunk if its first message came more than ``age_s`` ago (default:
        the chunk age, by the monotonic clock); for a timer, so that the last messages before a
        quiet spell reach the disk too."""
        if not self._buf:
            return False
        age_ns = self.chunk_age_ns if age_s is None else int(age_s * 1e9)
        if time.monotonic_ns() - self._chunk_opened_mono < age_ns:
            return False
        self._close_chunk()
        return True

    def flush(self) -> None:
        """Close the open chunk now (it reaches the OS)."""
        self._close_chunk()

    def _close_chunk(self) -> None:
        if not self._buf:
            return
        records, self._buf = self._buf, bytearray()
        index, self._index = self._index, defaultdict(list)
        start, end = self._chunk_start, self._chunk_end
        self._write_chunk(records, start, end, index)
        counts = self.flushed_counts
        for channel_id, entries in index.items():
            counts[channel_id] += len(entries) // 2
        if self.flushed_start is None or start < self.flushed_start:
            self.flushed_start = start
        self.flushed_end = max(self.flushed_end, end)

    def _write_chunk(self, records, start: int, end: int, index: dict[int, list[int]]) -> None:
        crc = zlib.crc32(records)
        data = records if self._compress is None else self._compress(bytes(records))
        compression = self.compression.encode() if self._compress is not None else b""
        length = 8 + 8 + 8 + 4 + 4 + len(compression) + 8 + len(data)
        head = (
            _CHUNK_HEAD.pack(Opcode.CHUNK, length, start, end, len(records), crc, len(compression))
            + compression
            + struct.pack("<Q", len(data))
        )
        chunk_offset = self._pos
        parts = [head, data]
        offsets = {}
        at = chunk_offset + len(head) + len(data)
        for channel_id in sorted(index):
            entries = index[channel_id]
            n = len(entries)
            offsets[channel_id] = at
            part = _MESSAGE_INDEX.pack(Opcode.MESSAGE_INDEX, 6 + 8 * n, channel_id, 8 * n)
            part += struct.pack(f"<{n}Q", *entries)
            parts.append(part)
            at += len(part)
        self._out(parts)
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_offset,
                chunk_length=len(head) + len(data),
                message_index_offsets=offsets,
                message_index_length=at - chunk_offset - len(head) - len(data),
                compression=self.compression if self._compress is not None else "",
                compressed_size=len(data),
                uncompressed_size=len(records),
            )
        )

    def _out(self, parts, data_section: bool = True) -> None:
        """Write ``parts`` at the end of the file, whole (one writev, retried if partial)."""
        total = sum(len(p) for p in parts)
        done = os.writev(self._fd, parts)
        if done < total:  # rare for a regular file (a signal, a full disk): finish it
            rest = memoryview(b"".join(parts))[done:]
            while rest:
                rest = rest[os.write(self._fd, rest) :]
        if data_section:
            for p in parts:
                self._crc = zlib.crc32(p, self._crc)
        self._pos += total

    # --- end -----------------------------------------------------------------------------

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A Metadata record in the data section (rosbag2 stores its metadata this way)."""
        self._close_chunk()
        builder = RecordBuilder()
        Metadata(name=name, metadata=dict(data)).write(builder)
        record = builder.end()
        index = MetadataIndex(offset=self._pos, length=len(record), name=name)
        self._metadata_indexes.append(index)
        self._metadata_count += 1
        self._out([record])

    @property
    def message_count(self) -> int:
        return sum(self.flushed_counts.values())

    def close(self) -> None:
        """Close the open chunk, write DataEnd, summary and footer, and close the file."""
        if self.closed:
            return
        try:
            if not self.started:
                self.start()
            self._write_definitions()
            self._close_chunk()
            builder = RecordBuilder()
            DataEnd(self._crc).write(builder)
            self._out([builder.end()])
            self._out([self._summary()], data_section=False)
        finally:
            self.closed = True
            os.close(self._fd)

    def abandon(self) -> None:
        """Close the file as it is (no summary), like a writer that died."""
        if not self.closed:
            self.closed = True
            os.close(self._fd)

    def _summary(self) -> bytes:
        summary_start = self._pos
        builder = RecordBuilder()
        offsets = []

        def group(opcode, records):
            if not records:
                return
            start = builder.count
            for record in records:
                record.write(builder)
            offsets.append(SummaryOffset(opcode, summary_start + start, builder.count - start))

        group(Opcode.SCHEMA, list(self._schemas.values()))
        group(Opcode.CHANNEL, list(self._channels.values()))
        counts = {c: n for c, n in sorted(self.flushed_counts.items()) if n}
        group(
            Opcode.STATISTICS,
            [
                Statistics(
                    attachment_count=0,
                    channel_count=len(self._channels),
                    channel_message_counts=counts,
                    chunk_count=len(self._chunk_indexes),
                    message_count=sum(counts.values()),
                    message_end_time=self.flushed_end,
                    message_start_time=0 if self.flushed_start is None else self.flushed_start,
                    metadata_count=self._metadata_count,
                    schema_count=len(self._schemas),
                )
            ],
        )
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        summary_offset_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(
            struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start), crc
        )
        builder = RecordBuilder()
        Footer(summary_start, summary_offset_start, crc).write(builder)
        return summary + builder.end() + MAGIC
