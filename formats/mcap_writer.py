"""Writing archives: chunked, indexed, zstd-compressed MCAP with protobuf messages (and JSON and ROS ones).

The records are laid out as the MCAP specification (mcap.dev/spec, major
version 0) describes them; we build them ourselves because the per-message
path of the mcap library (a record object, a builder, several small writes)
costs more than serializing the message. A message here is one precompiled
`struct` pack and two bytearray appends; everything else happens once per
chunk (1 MiB by default): zstd compression, the CRC32 of the uncompressed
records, one Message Index record per channel and a Chunk Index for the
summary.

File layout::

    magic, Header,
    (Schema | Channel | Attachment | Metadata | Chunk + its Message Indexes)...,
    Data End (CRC32 of every byte before it, magic included),
    summary: Schemas, Channels, Statistics, Chunk Indexes, Attachment Indexes,
    Metadata Indexes, then one Summary Offset per non-empty group,
    Footer (CRC32 of the summary through the footer's own offsets), magic.

Schema and Channel records go into the open chunk as they are registered,
before the channel's first message (as the spec requires); a chunk left with
such records and no message is written out as plain records, so a channel
registered without messages is still in the data section.

A record of a source log kept as itself is a source message: a `formats.json_messages.JsonMessage` (a `json`
channel whose schema is a `jsonschema`) or a `formats.ros_messages.RosMessage` (a `ros1` or `cdr` channel whose
schema is a `ros1msg` or `ros2msg` definition). One class for many schemas, so a topic's schema is that of its
first message.

The file is written under a temporary name next to the target and renamed
only when `close()` finishes, so an interrupted write never leaves a file
that looks complete. Given a binary stream instead of a path (an
`io.BytesIO`: `evaluate` records its trials in memory), the writer writes
the same bytes into it and leaves it open: no claim, no rename, no fsync.
"""

from __future__ import annotations

import json
import os
import struct
import zlib
from collections.abc import Iterable, Mapping, Sequence
from itertools import chain
from pathlib import Path
from typing import Any, BinaryIO, cast

import numpy as np
import zstandard
from google.protobuf.message import Message
from mcap_protobuf.schema import build_file_descriptor_set

from .json_messages import JsonMessage
from .output_files import OutputClaim
from .ros_messages import RosMessage

PROFILE = ""  # protobuf-encoded MCAP has no well-known profile
CHUNK_SIZE = 1024 * 1024
ZSTD_LEVEL = 3  # zstandard's default, as the mcap library uses
MAGIC = b"\x89MCAP0\r\n"

# opcodes (MCAP spec, "Records")
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_ATTACHMENT, OP_ATTACHMENT_INDEX = 0x06, 0x07, 0x08, 0x09, 0x0A
OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX, OP_SUMMARY_OFFSET, OP_DATA_END = 0x0B, 0x0C, 0x0D, 0x0E, 0x0F

# opcode, record length, channel id, sequence, log time, publish time; the data follows
_MESSAGE = struct.Struct("<BQHIQQ")
_MESSAGE_FIXED = 2 + 4 + 8 + 8
_pack_message = _MESSAGE.pack
_RECORD = struct.Struct("<BQ")
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, uncompressed CRC
_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, length, channel id, byte length of the entries
_U16_U64 = struct.Struct("<HQ")
_SEQUENCE_MASK = 0xFFFFFFFF
# a Message record's fixed part as _MESSAGE packs it, for headers made in numpy (`write_blob`)
_MESSAGE_DTYPE = np.dtype([("op", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"), ("log", "<u8"),
                           ("publish", "<u8")])
# messages that carry their schema (name, encoding, text) and channel encoding: a source log's records as themselves
SOURCE_CLASSES = (JsonMessage, RosMessage)


def _library() -> str:
    try:
        from importlib.metadata import version

        return f"auvreplay/{version('auvreplay')}"
    except Exception:  # noqa: BLE001 - running from a source tree
        return "auvreplay"


def _string(text: str) -> bytes:
    raw = text.encode("utf-8")
    return _U32.pack(len(raw)) + raw


def _string_map(entries: Mapping[str, str]) -> bytes:
    body = b"".join(_string(k) + _string(v) for k, v in entries.items())
    return _U32.pack(len(body)) + body


def _id_map(entries: Mapping[int, int]) -> bytes:
    body = b"".join(_U16_U64.pack(k, v) for k, v in entries.items())
    return _U32.pack(len(body)) + body


def record(opcode: int, body: bytes) -> bytes:
    """One MCAP record: opcode, uint64 content length, content."""
    return _RECORD.pack(opcode, len(body)) + body


class _StreamClaim:
    """OutputClaim's part for a caller's binary stream: written in place, never renamed, synced or closed."""

    def __init__(self, stream: BinaryIO):
        self.output = Path(f"<{type(stream).__name__}>")
        self.part = self.output
        self.removed: list[Path] = []
        self._stream = stream

    def open_part(self) -> BinaryIO:
        return cast(BinaryIO, _Unclosed(self._stream))

    def publish(self) -> None:
        """Nothing to rename: the stream holds the archive."""

    def abandon(self, keep_part: bool = False) -> None:
        """The caller's stream is the caller's: what was written stays in it."""


class _Unclosed:
    """A caller's stream as the writer's file: close() flushes it and leaves it open (a BytesIO keeps its bytes)."""

    def __init__(self, stream: BinaryIO):
        self._stream = stream
        self.write = stream.write

    def flush(self) -> None:
        self._stream.flush()

    def close(self) -> None:
        self._stream.flush()


class _Channel:
    """A registered channel: its id, message class, messages so far and the open chunk's index."""

    __slots__ = ("id", "cls", "count", "index", "blocks")

    def __init__(self, channel_id: int, cls: type[Message]):
        self.id = channel_id
        self.cls = cls
        self.count = 0
        self.index: list[tuple[int, int]] = []  # (log time, offset in the chunk) of the open chunk
        # the same entries of `write_blob`'s messages, as (k, 2) int64 arrays: no tuple per message
        self.blocks: list[np.ndarray] = []

    def entries(self) -> np.ndarray | list[tuple[int, int]]:
        """The open chunk's index entries sorted by (log time, offset), and a fresh start: the tuples as they are
        when no block was written, else one (n, 2) int64 array of all of them."""
        index, blocks = self.index, self.blocks
        self.index, self.blocks = [], []
        if not blocks:
            index.sort()  # already in order unless times went backwards: linear then
            return index
        table = np.concatenate([np.array(index, dtype=np.int64).reshape(-1, 2), *blocks]) if index \
            else blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
        # in chunk order (offsets rising) with times not going backwards, it is sorted already; else sorted as
        # the tuples sort, by time then offset
        if (np.diff(table[:, 0]) < 0).any() or (np.diff(table[:, 1]) < 0).any():
            table = table[np.lexsort((table[:, 1], table[:, 0]))]
        return table


class ArchiveWriter:
    """Writes protobuf messages, metadata and attachments to an MCAP archive.

    Use as a context manager; on an exception the partial file is removed.
    Times are integer nanoseconds (UTC); there is no wall-clock default.
    """

    def __init__(self, path: str | os.PathLike[str] | BinaryIO, chunk_size: int = CHUNK_SIZE,
                 part_path: Path | None = None, replace: bool = True, keep_on_error: bool = False):
        # the output is claimed (formats.output_files): a second writer of the same path is refused, and
        # without `replace` an existing file is never replaced, not even one that appears while we write.
        # A live capture grows under a name the user knows (TRIAL.mcap.part) to recover it after a crash.
        # A stream (not a path) is the caller's: written in place (_StreamClaim).
        self._claim: OutputClaim | _StreamClaim = OutputClaim(Path(path), replace, part_path) \
            if isinstance(path, (str, os.PathLike)) else _StreamClaim(path)
        self.path = self._claim.output
        self.temp_path = self._claim.part
        self._named_part = part_path is not None
        self.removed_parts: list[Path] = self._claim.removed  # part files of dead writers, removed
        # a live capture's part file is what was captured: a close that fails (a full disk) leaves it
        self.keep_on_error = keep_on_error
        try:
            self._stream = self._claim.open_part()
        except BaseException:
            self._claim.abandon(keep_part=True)
            raise
        self._pos = 0
        self._crc = 0  # CRC32 of the data section so far (magic included)
        self._chunk_size = chunk_size
        self._chunk = bytearray()
        self._zstd = zstandard.ZstdCompressor(level=ZSTD_LEVEL)
        self._topics: dict[str, _Channel] = {}
        self._by_id: dict[int, _Channel] = {}
        self._schemas: dict[str | tuple[str, str, str], int] = {}  # protobuf: by name; others: by encoding, name, text
        self._summary_schemas: list[bytes] = []
        self._summary_channels: list[bytes] = []
        self._chunk_indexes: list[bytes] = []
        self._attachment_indexes: list[bytes] = []
        self._metadata_indexes: list[bytes] = []
        self._span: tuple[int, int] | None = None  # earliest and latest message log time
        self._closed = False
        self._emit(MAGIC, record(OP_HEADER, _string(PROFILE) + _string(_library())))

    # -- data section ------------------------------------------------------------
    def _emit(self, *parts: bytes | bytearray) -> int:
        """Append bytes to the data section; returns the offset of the first."""
        start = self._pos
        for part in parts:
            self._stream.write(part)
            self._crc = zlib.crc32(part, self._crc)
            self._pos += len(part)
        return start

    def channel(self, topic: str, message_class: type[Message]) -> int:
        """The channel id for a topic, registering it (and its schema) on first use."""
        return self._channel(topic, message_class).id

    def json_channel(self, topic: str, schema_name: str, schema: str) -> int:
        """The channel id for a topic of JSON messages (`formats.json_messages`), registering it and its JSON
        Schema on first use."""
        return self._channel(topic, JsonMessage, JsonMessage(schema_name, schema, b"")).id

    def source_channel(self, topic: str, example: JsonMessage | RosMessage) -> int:
        """The channel id for a topic of source messages (JSON or ROS), registering it and the schema `example`
        carries on first use."""
        return self._channel(topic, type(example), example).id

    def _channel(self, topic: str, message_class: type[Message] | type[JsonMessage] | type[RosMessage],
                 example: Any = None) -> _Channel:
        if self._closed:
            raise ValueError(f"{self.path}: the archive is closed")
        known = self._topics.get(topic)
        if known is not None:
            if known.cls is not message_class:
                raise TypeError(
                    f"topic {topic} carries {getattr(getattr(known.cls, 'DESCRIPTOR', None), 'full_name', 'JSON')}, "
                    f"not {getattr(getattr(message_class, 'DESCRIPTOR', None), 'full_name', message_class)}"
                )
            return known
        key: str | tuple[str, str, str]
        source = message_class in SOURCE_CLASSES
        if source:  # one class for many schemas: the schema is the example message's
            name, encoding = example.schema_name, example.message_encoding
            key = (example.schema_encoding, name, example.schema)
        else:
            name = key = message_class.DESCRIPTOR.full_name  # type: ignore[union-attr]
            encoding = "protobuf"
        schema_id = self._schemas.get(key)
        if schema_id is None:
            schema_id = len(self._schemas) + 1  # 0 means "no schema"
            if source:
                data, schema_encoding = example.schema.encode("utf-8"), example.schema_encoding
            else:
                data, schema_encoding = build_file_descriptor_set(message_class).SerializeToString(), "protobuf"
            rec = record(OP_SCHEMA, _U16.pack(schema_id) + _string(name) + _string(schema_encoding)
                         + _U32.pack(len(data)) + data)
            self._chunk += rec
            self._summary_schemas.append(rec)
            self._schemas[key] = schema_id
        channel_id = len(self._topics) + 1
        if channel_id > 0xFFFF:
            raise ValueError(f"{self.path}: more than 65535 channels")
        rec = record(OP_CHANNEL, struct.pack("<HH", channel_id, schema_id) + _string(topic)
                     + _string(encoding) + _string_map({}))
        self._chunk += rec
        self._summary_channels.append(rec)
        ch = self._topics[topic] = self._by_id[channel_id] = _Channel(channel_id, message_class)
        return ch

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one message; publish time defaults to the log time (never the wall clock)."""
        ch = self._topics.get(topic)
        if ch is None or ch.cls is not type(message):
            ch = self._channel(topic, type(message), message)
        data = message.SerializeToString()
        buf = self._chunk
        offset = len(buf)
        count = ch.count
        # one append of header + data: the extra bytes object is cheaper than a second bytearray resize
        buf += _pack_message(OP_MESSAGE, _MESSAGE_FIXED + len(data), ch.id, count & 0xFFFFFFFF, log_time_ns,
                             log_time_ns if publish_time_ns is None else publish_time_ns) + data
        ch.count = count + 1
        ch.index.append((log_time_ns, offset))
        if len(buf) >= self._chunk_size:
            self._finish_chunk()

    def write_serialized(
        self, topic_or_channel: str | int, data: bytes | memoryview, log_time_ns: int,
        publish_time_ns: int | None = None,
    ) -> None:
        """Append one already-serialized message on a channel registered with `channel()` (topic or id)."""
        if type(topic_or_channel) is str:
            ch = self._topics.get(topic_or_channel)
        else:
            ch = self._by_id.get(topic_or_channel)  # type: ignore[arg-type]
        if ch is None or self._closed:
            raise KeyError(f"{topic_or_channel!r} is not a registered channel of {self.path}"
                           + (" (closed)" if self._closed else "; call channel(topic, message_class) first"))
        buf = self._chunk
        offset = len(buf)
        buf += _MESSAGE.pack(OP_MESSAGE, _MESSAGE_FIXED + len(data), ch.id, ch.count & _SEQUENCE_MASK, log_time_ns,
                             log_time_ns if publish_time_ns is None else publish_time_ns)
        buf += data
        ch.count += 1
        ch.index.append((log_time_ns, offset))
        if len(buf) >= self._chunk_size:
            self._finish_chunk()

    def write_serialized_batch(self, topic: str, payloads: Sequence[bytes], log_times_ns: Sequence[int],
                               publish_times_ns: Sequence[int] | None = None) -> None:
        """`write_serialized` of many messages on one registered topic, in order: the same bytes, one call.

        Publish times default to the log times; the chunk closes where the
        message-by-message writes would close it.
        """
        ch = self._topics.get(topic)
        if ch is None or self._closed:
            raise KeyError(f"{topic!r} is not a registered channel of {self.path}"
                           + (" (closed)" if self._closed else "; call channel(topic, message_class) first"))
        if len(payloads) != len(log_times_ns) or (publish_times_ns is not None
                                                  and len(publish_times_ns) != len(log_times_ns)):
            raise ValueError(f"{topic}: {len(payloads)} payloads, {len(log_times_ns)} log times"
                             + ("" if publish_times_ns is None else f", {len(publish_times_ns)} publish times"))
        pack, cid, limit = _MESSAGE.pack, ch.id, self._chunk_size
        buf, index, count = self._chunk, ch.index, ch.count
        for data, log_time, publish_time in zip(payloads, log_times_ns,
                                                log_times_ns if publish_times_ns is None else publish_times_ns):
            offset = len(buf)
            buf += pack(OP_MESSAGE, _MESSAGE_FIXED + len(data), cid, count & _SEQUENCE_MASK, log_time, publish_time)
            buf += data
            count += 1
            index.append((log_time, offset))
            if len(buf) >= limit:
                ch.count = count
                self._finish_chunk()
                buf, index = self._chunk, ch.index
        ch.count = count

    def write_blob(self, channel_ids: np.ndarray, blob: bytes | memoryview, ends: np.ndarray, log_times_ns: np.ndarray,
                   publish_times_ns: np.ndarray) -> None:
        """`write_serialized` of many messages on registered channels, in order, in a few numpy steps: message i
        is blob[ends[i - 1]:ends[i]] (from 0) on `channel_ids[i]`. The same bytes and chunks as one call each."""
        n = len(ends)
        ids = np.asarray(channel_ids, dtype=np.int64)
        log_ns, publish_ns = np.asarray(log_times_ns, dtype=np.int64), np.asarray(publish_times_ns, dtype=np.int64)
        unknown = set(np.unique(ids).tolist()) - self._by_id.keys()
        if self._closed or unknown or not n or (log_ns < 0).any() or (publish_ns < 0).any():
            # the message-by-message path: its errors (a closed archive, a channel not registered, a time the
            # record cannot hold), or nothing to write
            view, start = memoryview(blob), 0
            for cid, end, t, p in zip(ids.tolist(), np.asarray(ends).tolist(), log_ns.tolist(), publish_ns.tolist()):
                self.write_serialized(cid, view[start:end], t, p)
                start = end
            return
        ends = np.asarray(ends, dtype=np.int64)
        sizes = np.diff(ends, prepend=0)
        head = np.zeros(n, dtype=_MESSAGE_DTYPE)
        head["op"], head["length"], head["channel"] = OP_MESSAGE, _MESSAGE_FIXED + sizes, ids
        head["log"], head["publish"] = log_ns, publish_ns
        sequence = np.zeros(n, dtype=np.int64)
        by_channel = {cid: np.flatnonzero(ids == cid) for cid in np.unique(ids).tolist()}
        for cid, rows in by_channel.items():
            sequence[rows] = self._by_id[cid].count + np.arange(len(rows))
        head["sequence"] = sequence & _SEQUENCE_MASK
        records = np.cumsum(sizes + _MESSAGE.size)  # each message's record end, from the first
        data = np.frombuffer(blob, dtype=np.uint8)
        first = 0
        while first < n:
            before = int(records[first - 1]) if first else 0
            filled = len(self._chunk)
            # the chunk closes after the message that brings it to the size limit, as write_serialized closes it
            last = min(max(int(np.searchsorted(records, self._chunk_size - filled + before)), first), n - 1)
            at = filled + records[first:last + 1] - before - sizes[first:last + 1] - _MESSAGE.size
            out = np.empty(int(records[last]) - before, dtype=np.uint8)
            header = np.zeros(len(out), dtype=bool)
            header[((at - filled)[:, None] + np.arange(_MESSAGE.size)).ravel()] = True
            out[header] = head[first:last + 1].view(np.uint8)
            out[~header] = data[int(ends[first] - sizes[first]):int(ends[last])]
            self._chunk += out.data
            for cid, rows in by_channel.items():
                mine = rows[(rows >= first) & (rows <= last)]
                if len(mine):
                    ch = self._by_id[cid]
                    ch.blocks.append(np.stack([log_ns[mine], at[mine - first]], axis=1))
                    ch.count += len(mine)
            first = last + 1
            if len(self._chunk) >= self._chunk_size:
                self._finish_chunk()

    def _finish_chunk(self) -> None:
        """Compress the open chunk into a Chunk record, its Message Indexes and a Chunk Index."""
        buf = self._chunk
        if not buf:
            return
        indexes = []
        start = end = None
        for ch in self._by_id.values():
            if ch.index or ch.blocks:
                entries = ch.entries()
                first, last = int(entries[0][0]), int(entries[-1][0])
                start = first if start is None else min(start, first)
                end = last if end is None else max(end, last)
                indexes.append((ch.id, entries))
        self._chunk = bytearray()
        if start is None or end is None:
            self._emit(buf)  # only Schema/Channel records, no message: they stand outside any chunk
            return
        compressed = self._zstd.compress(buf)
        head = _CHUNK_HEAD.pack(start, end, len(buf), zlib.crc32(buf)) + _string("zstd") + _U64.pack(len(compressed))
        chunk_at = self._emit(_RECORD.pack(OP_CHUNK, len(head) + len(compressed)), head, compressed)
        chunk_length = self._pos - chunk_at
        offsets = {}
        for cid, idx in indexes:
            n = 2 * len(idx)
            packed = idx.astype("<u8").tobytes() if isinstance(idx, np.ndarray) \
                else struct.pack(f"<{n}Q", *chain.from_iterable(idx))
            offsets[cid] = self._emit(_INDEX_HEAD.pack(OP_MESSAGE_INDEX, 6 + 8 * n, cid, 8 * n) + packed)
        index_length = self._pos - chunk_at - chunk_length
        self._chunk_indexes.append(record(OP_CHUNK_INDEX, struct.pack("<QQQQ", start, end, chunk_at, chunk_length)
                                          + _id_map(offsets) + _U64.pack(index_length) + _string("zstd")
                                          + struct.pack("<QQ", len(compressed), len(buf))))
        self._span = (start, end) if self._span is None else (min(self._span[0], start), max(self._span[1], end))

    def flush(self) -> None:
        """Close the open chunk, write it out and fsync: everything written so far survives a crash."""
        self._finish_chunk()
        self._sync()

    def _sync(self) -> None:
        """Flush, and fsync a file of our own (a caller's stream is not synced)."""
        self._stream.flush()
        if isinstance(self._claim, OutputClaim):
            os.fsync(self._stream.fileno())

    def add_metadata(self, name: str, data: Mapping[str, Any]) -> None:
        """A metadata record; non-string values are stored as JSON text."""
        text = {k: v if isinstance(v, str) else json.dumps(v, sort_keys=True) for k, v in data.items()}
        rec = record(OP_METADATA, _string(name) + _string_map(text))
        at = self._emit(rec)
        self._metadata_indexes.append(record(OP_METADATA_INDEX, struct.pack("<QQ", at, len(rec)) + _string(name)))

    def add_attachment(
        self, name: str, data: bytes, media_type: str = "application/octet-stream",
        log_time_ns: int = 0, create_time_ns: int = 0,
    ) -> None:
        """An attachment, byte for byte (the record carries its own CRC)."""
        self.add_attachment_stream(name, len(data), (data,), media_type, log_time_ns, create_time_ns)

    def add_attachment_stream(
        self, name: str, size: int, pieces: Iterable[bytes], media_type: str = "application/octet-stream",
        log_time_ns: int = 0, create_time_ns: int = 0,
    ) -> None:
        """`add_attachment` of `size` bytes given in pieces, so that a large file is never held whole.

        Raises ValueError when the pieces add up to another size (the record would be corrupt).
        """
        head = (struct.pack("<QQ", log_time_ns, create_time_ns) + _string(name) + _string(media_type)
                + _U64.pack(size))
        length = len(head) + size + 4
        at = self._emit(_RECORD.pack(OP_ATTACHMENT, length), head)
        crc, written = zlib.crc32(head), 0
        for piece in pieces:
            self._emit(piece)
            crc = zlib.crc32(piece, crc)
            written += len(piece)
        if written != size:
            raise ValueError(f"attachment {name}: {written} bytes given, {size} declared")
        self._emit(_U32.pack(crc))
        self._attachment_indexes.append(record(
            OP_ATTACHMENT_INDEX,
            struct.pack("<QQQQQ", at, 9 + length, log_time_ns, create_time_ns, size)
            + _string(name) + _string(media_type),
        ))

    # -- summary -------------------------------------------------------------------
    def _statistics(self) -> bytes:
        counts = {ch.id: ch.count for ch in self._by_id.values() if ch.count}
        start, end = self._span if self._span is not None else (0, 0)
        body = struct.pack(
            "<QHIIIIQQ", sum(counts.values()), len(self._schemas), len(self._topics), len(self._attachment_indexes),
            len(self._metadata_indexes), len(self._chunk_indexes), start, end,
        )
        return record(OP_STATISTICS, body + _id_map(counts))

    def _finish(self) -> None:
        """Last chunk, Data End, summary, summary offsets, footer and closing magic."""
        self._finish_chunk()
        self._emit(record(OP_DATA_END, _U32.pack(self._crc)))
        summary_start = self._pos
        groups = [
            (OP_SCHEMA, self._summary_schemas), (OP_CHANNEL, self._summary_channels),
            (OP_STATISTICS, [self._statistics()]), (OP_CHUNK_INDEX, self._chunk_indexes),
            (OP_ATTACHMENT_INDEX, self._attachment_indexes), (OP_METADATA_INDEX, self._metadata_indexes),
        ]
        summary = bytearray()
        offsets = bytearray()
        for opcode, records in groups:
            if records:
                group = b"".join(records)
                offsets += record(OP_SUMMARY_OFFSET,
                                  struct.pack("<BQQ", opcode, summary_start + len(summary), len(group)))
                summary += group
        offset_start = summary_start + len(summary)
        summary += offsets
        summary += _RECORD.pack(OP_FOOTER, 20) + struct.pack("<QQ", summary_start, offset_start)
        summary += _U32.pack(zlib.crc32(summary))
        self._stream.write(summary)
        self._stream.write(MAGIC)

    def close(self) -> Path:
        """Finish the file (summary, indexes, footer) and move it to its final name."""
        if not self._closed:
            try:
                self._finish()
                self._sync()
            except BaseException:
                if self.keep_on_error:
                    self.leave()
                else:
                    self.abort()
                raise
            self._stream.close()
            self._mark_closed()
            try:
                self._claim.publish()
            except BaseException:
                if not self._named_part:  # a private part file is of no use; a capture's is kept for recover
                    self.temp_path.unlink(missing_ok=True)
                raise
        return self.path

    def abort(self) -> None:
        """Drop the partial file; the target name is never created."""
        if not self._closed:
            self._stream.close()
            self._claim.abandon()
            self._mark_closed()

    def leave(self) -> None:
        """Close the partial file and keep it where it is (`recover` reads it); a failing close is ignored."""
        if not self._closed:
            try:
                self._stream.close()
            except OSError:   # the buffer could not be written (a full disk): what is on disk stays
                pass
            self._claim.abandon(keep_part=True)
            self._mark_closed()

    def _mark_closed(self) -> None:
        # an emptied topic table sends a late write() through _channel(), which refuses it
        self._closed = True
        self._topics = {}
        self._by_id = {}

    def __enter__(self) -> ArchiveWriter:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()
