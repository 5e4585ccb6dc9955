"""An MCAP writer for recordings that must stay readable while they grow.

The file is only appended to, and every chunk reaches the OS whole (one ``writev``), so a writer
that dies (kill -9, a crash, a full disk) leaves every complete chunk readable and verified by
its CRC; ``activetrack bag recover`` adds the summary. Layout (https://mcap.dev/spec):

* magic, Header (profile ``ros2``);
* a definitions chunk: the Schema and Channel records alone, flushed at :meth:`McapWriter.start`
  (a later definition gets a chunk of its own), so a damaged message chunk never takes them along;
* message chunks, each closed when it holds ``chunk_size`` bytes or its first message is
  ``chunk_age_s`` old, followed by its MessageIndex records;
* at :meth:`McapWriter.close`: Metadata, DataEnd (CRC of the data section), the summary and the
  footer (CRC of the summary).

Message and MessageIndex records are packed here (a few microseconds per message), the others
by ``mcap``'s record classes. ``mcap.writer.Writer`` (1.6) is not used: it puts the definitions
in the first *message* chunk, so one damaged chunk of a killed recording loses them all, and it
has no time-based chunk close.
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
# opcode, length, start, end, size, crc, compression ('': length 0), records length
_CHUNK_HEAD = struct.Struct("<BQQQQIIQ")


def _encoded(*records) -> bytes:
    """The records as MCAP bytes (the ``mcap`` library's encoding)."""
    builder = RecordBuilder()
    for record in records:
        record.write(builder)
    return builder.end()


class McapWriter:
    """Appends an MCAP file chunk by chunk (module docstring); not thread-safe by itself."""

    def __init__(
        self,
        path,
        *,
        chunk_size: int = CHUNK_SIZE,
        chunk_age_s: float = CHUNK_AGE_S,
    ):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self.chunk_size = int(chunk_size)
        self.chunk_age_ns = int(chunk_age_s * 1e9)
        self._pos = 0  # bytes written so far
        self._crc = 0  # CRC of the data section so far
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._pending_defs: list = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
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
        self.started = False
        self.closed = False

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
        self._out([MAGIC, _encoded(Header("ros2", "activetrack"))])
        self.started = True
        self._write_definitions()

    def _write_definitions(self) -> None:
        if not self._pending_defs:
            return
        self._close_chunk()  # messages before definitions keep their order in the file
        records = _encoded(*self._pending_defs)
        self._pending_defs.clear()
        self._write_chunk(records, 0, 0, {})

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
        publish = log_time if publish_time is None else publish_time
        buf += _MESSAGE.pack(
            Opcode.MESSAGE, 22 + len(data), channel_id, seq & 0xFFFFFFFF, log_time, publish
        )
        buf += data
        # Age by the monotonic clock, not log time (sim time can run far faster or slower).
        if len(buf) >= self.chunk_size or (
            time.monotonic_ns() - self._chunk_opened_mono >= self.chunk_age_ns
        ):
            self._close_chunk()

    def flush_if_older(self) -> None:
        """Close the open chunk if it is ``chunk_age_s`` old (for a timer: the last messages
        before a quiet spell reach the disk too)."""
        if self._buf and time.monotonic_ns() - self._chunk_opened_mono >= self.chunk_age_ns:
            self._close_chunk()

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
        size, crc = len(records), zlib.crc32(records)
        head = _CHUNK_HEAD.pack(Opcode.CHUNK, 40 + size, start, end, size, crc, 0, size)
        chunk_offset = self._pos
        parts = [head, records]
        offsets = {}
        at = chunk_offset + len(head) + size
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
                chunk_length=len(head) + size,
                message_index_offsets=offsets,
                message_index_length=at - chunk_offset - len(head) - size,
                compression="",
                compressed_size=size,
                uncompressed_size=size,
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

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A Metadata record in the data section (rosbag2 stores its metadata this way)."""
        self._close_chunk()
        record = _encoded(Metadata(name=name, metadata=dict(data)))
        index = MetadataIndex(offset=self._pos, length=len(record), name=name)
        self._metadata_indexes.append(index)
        self._out([record])

    def close(self) -> None:
        """Close the open chunk, write DataEnd, summary and footer, and close the file."""
        if self.closed:
            return
        try:
            if not self.started:
                self.start()
            self._write_definitions()
            self._close_chunk()
            self._out([_encoded(DataEnd(self._crc))])
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
        statistics = Statistics(
            attachment_count=0,
            channel_count=len(self._channels),
            channel_message_counts=counts,
            chunk_count=len(self._chunk_indexes),
            message_count=sum(counts.values()),
            message_end_time=self.flushed_end,
            message_start_time=0 if self.flushed_start is None else self.flushed_start,
            metadata_count=len(self._metadata_indexes),
            schema_count=len(self._schemas),
        )
        group(Opcode.STATISTICS, [statistics])
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
        return summary + _encoded(Footer(summary_start, summary_offset_start, crc)) + MAGIC
