"""Reading archives: time-ordered streaming, decoded messages, DataFrames, damage as data.

A complete file is read through its summary (chunks merged in log-time order,
CRCs validated). A file without a valid summary (a write that was cut off, a
damaged footer) is indexed by a sequential scan and then read the same way:
every complete chunk is recovered. Archives come from other people's
machines, so nothing in them raises past this reader and memory stays
bounded: a chunk over the size cap or that inflates past what it declares, a
chunk that fails its CRC, a message that does not decode, a channel of an
unknown encoding or schema, an unreadable metadata or attachment record are
all skipped and counted in `ArchiveReader.damage`, whose `line()` says in one
line what was skipped.
"""

from __future__ import annotations

import heapq
import io
import json
import os
import struct
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, NamedTuple

from google.protobuf.message import DecodeError
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.summary import Summary
from mcap_protobuf.decoder import DecoderFactory

from .json_messages import MESSAGE_ENCODING as JSON_ENCODING
from .json_messages import SCHEMA_ENCODING as JSON_SCHEMA_ENCODING
from .json_messages import JsonMessage
from .mcap_blocks import MessageBlock, read_blocks
from .mcap_chunks import MAX_CHUNK_BYTES, RawMessage, ordered_messages
from .mcap_records import MAGIC, OP_ATTACHMENT, OP_METADATA, RecordError, read_record, read_summary, scan
from .records import FormatError
from .ros_messages import ENCODINGS as ROS_ENCODINGS
from .ros_messages import RosMessage, RosSchema
from .schemas import MESSAGE_CLASSES

# what a protobuf decoder raises on bytes that are not its message
_DECODE_ERRORS = (DecodeError, ValueError, TypeError, KeyError, IndexError, struct.error, EOFError, McapError)
_KEEP = 20  # damage texts kept in full; the rest are counted


class ArchiveMessage(NamedTuple):
    """One message: topic, schema name, times (ns, UTC) and the decoded protobuf message."""

    # a NamedTuple, not a frozen dataclass: one per message read, built in less than half the time
    topic: str
    schema: str
    log_time_ns: int
    publish_time_ns: int
    message: Any


@dataclass(frozen=True, slots=True)
class AttachmentInfo:
    """An attachment's name, size in bytes and media type."""

    name: str
    size: int
    media_type: str


@dataclass
class ArchiveSummary:
    """What is inside an archive, without reading its messages."""

    topics: dict[str, dict[str, Any]] = field(default_factory=dict)  # topic -> {count, schema}
    start_ns: int | None = None
    end_ns: int | None = None
    attachments: list[AttachmentInfo] = field(default_factory=list)
    metadata_names: list[str] = field(default_factory=list)
    message_count: int = 0


@dataclass
class Damage:
    """What reading an archive skipped: messages per (topic, reason), bad chunks, bad records, problems.

    `problems` are what was wrong with the file as a whole (no summary, cut
    off at byte N); the first few texts of each kind are kept, the rest counted.
    """

    messages: Counter[tuple[str, str]] = field(default_factory=Counter)
    chunks: dict[int, str] = field(default_factory=dict)         # chunk offset -> reason
    records: Counter[str] = field(default_factory=Counter)       # record kind -> count
    record_texts: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    def skip_message(self, topic: str, reason: str) -> None:
        """Count one message skipped."""
        self.messages[(topic, reason)] += 1

    def bad_chunk(self, offset: int, reason: str) -> None:
        """Note a chunk skipped (once per chunk, however often it is read)."""
        self.chunks.setdefault(offset, reason)

    def bad_record(self, kind: str, text: str) -> None:
        """Count a record (metadata, attachment, schema, ...) skipped."""
        self.records[kind] += 1
        if len(self.record_texts) < _KEEP and text not in self.record_texts:
            self.record_texts.append(text)

    def problem(self, text: str) -> None:
        """Note damage to the file as a whole."""
        if text not in self.problems and len(self.problems) < _KEEP:
            self.problems.append(text)

    def __bool__(self) -> bool:
        return bool(self.messages or self.chunks or self.records or self.problems)

    def line(self) -> str | None:
        """One line saying everything that was skipped, or None when nothing was."""
        if not self:
            return None
        parts = []
        if self.messages:
            by_topic: dict[str, list[str]] = {}
            for (topic, reason), n in sorted(self.messages.items()):
                by_topic.setdefault(topic, []).append(f"{n} {reason}")
            total = sum(self.messages.values())
            parts.append(f"skipped {total} message{'s' * (total != 1)} ("
                         + "; ".join(f"{t}: {', '.join(r)}" for t, r in by_topic.items()) + ")")
        if self.chunks:
            first = next(iter(self.chunks.values()))
            n = len(self.chunks)
            parts.append(f"skipped {n} chunk{'s' * (n != 1)} ({first}{', ...' if n > 1 else ''})")
        if self.records:
            kinds = ", ".join(f"{n} {k} record{'s' * (n != 1)}" for k, n in sorted(self.records.items()))
            parts.append(f"skipped {kinds} ({self.record_texts[0]})")
        parts.extend(self.problems)
        return "; ".join(parts)


def _json_decoder(schema: Schema | None) -> Callable[[bytes], JsonMessage]:
    """A json channel's messages as JsonMessages, checked to be JSON (text that is not is a message that does not
    decode)."""
    name = schema.name if schema is not None else ""
    text = schema.data.decode("utf-8", "replace") if schema is not None else ""

    def decode(data: bytes) -> JsonMessage:
        raw = bytes(data)
        json.loads(raw)  # ValueError (JSONDecodeError, UnicodeDecodeError) on bytes that are no JSON
        return JsonMessage(name, text, raw)
    return decode


def _ros_decoder(channel: Channel, schema: Schema) -> Callable[[bytes], RosMessage]:
    """A ROS channel's messages as RosMessages: the bytes as the bag stored them (the replay reads none of them;
    Foxglove, Rerun and the mcap library's ROS decoders do)."""
    kind = RosSchema(schema.name, schema.encoding, schema.data.decode("utf-8", "replace"), channel.message_encoding)

    def decode(data: bytes) -> RosMessage:
        return RosMessage(kind, bytes(data))
    return decode


def _check_magic(path: Path) -> int:
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise FormatError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    if path.is_dir():
        raise FormatError(f"{path}: a directory, not an MCAP archive")
    if size == 0:
        raise FormatError(f"{path}: empty file, not an MCAP archive")
    with open(path, "rb") as f:
        head = f.read(len(MAGIC))
    if head != MAGIC:
        raise FormatError(f"{path}: not an MCAP file (no MCAP magic at the start)")
    return size


def _check_magic_bytes(data: bytes | bytearray | memoryview) -> int:
    """`_check_magic` of an archive held in memory: its size."""
    if not len(data):
        raise FormatError("<bytes>: empty, not an MCAP archive")
    if bytes(data[:len(MAGIC)]) != MAGIC:
        raise FormatError("<bytes>: not an MCAP archive (no MCAP magic at the start)")
    return len(data)


class ArchiveReader:
    """Reads an MCAP archive, a file or its bytes (context manager); FormatError only if it is not MCAP at all."""

    def __init__(self, path: str | os.PathLike[str] | bytes | bytearray | memoryview, validate_crcs: bool = True,
                 max_chunk_bytes: int = MAX_CHUNK_BYTES):
        # an archive's bytes (`evaluate` keeps its trials in memory) are read as the file would be
        self._file: BinaryIO
        if isinstance(path, (bytes, bytearray, memoryview)):
            self.path = Path("<bytes>")
            self._size = _check_magic_bytes(path)
            self._file = io.BytesIO(path)
        else:
            self.path = Path(path)
            self._size = _check_magic(self.path)
            self._file = open(self.path, "rb")
        self.validate_crcs = validate_crcs
        self.max_chunk_bytes = max_chunk_bytes
        self.damage = Damage()
        self._factory = DecoderFactory()
        self._loose: list[RawMessage] = []
        summary, why = read_summary(self._file, self._size, validate_crcs)
        self._recovered = summary is None
        if summary is None or summary.statistics is None:
            found = scan(self._file, self._size, validate_crcs, max_chunk_bytes, self._scan_report)
            if summary is None:
                self.damage.problem(f"{why}: read sequentially as far as its records are whole")
                summary, self._loose = found.summary, found.loose
            else:
                summary.statistics = found.summary.statistics
        self._index: Summary = summary

    def _scan_report(self, where: str, what: str) -> None:
        if what.startswith("truncated"):
            self.damage.problem(f"{what} ({where})")
        elif "chunk" in what:
            self.damage.bad_chunk(int(where.split()[-1]), what)
        else:
            self.damage.bad_record(what.split(" record")[0].replace("unreadable ", ""), f"{where}: {what}")

    @property
    def recovered(self) -> bool:
        """True when the file had no valid summary and was indexed by a sequential scan."""
        return self._recovered

    @property
    def problems(self) -> list[str]:
        """What is wrong with the file as a whole (empty for a whole file)."""
        return self.damage.problems

    def warning(self) -> str | None:
        """One line saying what was skipped so far, or None."""
        return self.damage.line()

    # -- messages --------------------------------------------------------------
    def raw_messages(
        self, topics: Iterable[str] | None = None, start_ns: int | None = None, end_ns: int | None = None,
    ) -> Iterator[tuple[Schema | None, Channel, Message]]:
        """Undecoded (schema, channel, message) in log-time order through the mcap library itself.

        A reference for tests of `messages` on our own files; it is not
        bounded against crafted ones.
        """
        wanted = set(topics) if topics is not None else None
        self._file.seek(0)
        if not self._recovered:
            yield from SeekingReader(self._file, validate_crcs=self.validate_crcs).iter_messages(
                topics=list(wanted) if wanted is not None else None,
                starting_at=start_ns, ending_before=end_ns, log_time_order=True,
            )
            return
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        found: list[tuple[int, int, tuple[Schema | None, Channel, Message]]] = []
        try:
            for rec in StreamReader(self._file, validate_crcs=self.validate_crcs).records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Message) and rec.channel_id in channels:
                    c = channels[rec.channel_id]
                    if (wanted is None or c.topic in wanted) and (start_ns is None or rec.log_time >= start_ns) \
                            and (end_ns is None or rec.log_time < end_ns):
                        found.append((rec.log_time, len(found), (schemas.get(c.schema_id), c, rec)))
        except (McapError, ValueError, EOFError, struct.error):
            pass  # the reference stops at the damage, as the scan does
        heapq.heapify(found)
        while found:
            yield heapq.heappop(found)[2]

    def _decoder(self, channel: Channel, schema: Schema | None) -> tuple[Callable[[bytes], Any] | None, str]:
        """(decode function, "") for a channel, or (None, why its messages are skipped)."""
        if channel.message_encoding == JSON_ENCODING and (schema is None or schema.encoding == JSON_SCHEMA_ENCODING):
            return _json_decoder(schema), ""
        if schema is not None and ROS_ENCODINGS.get(channel.message_encoding) == schema.encoding:
            return _ros_decoder(channel, schema), ""
        if channel.message_encoding != "protobuf":
            return None, f"of encoding {channel.message_encoding[:40]!r}, not protobuf"
        if schema is None:
            return None, "without a schema record"
        cls = MESSAGE_CLASSES.get(schema.name)
        if cls is not None:
            return cls.FromString, ""
        try:
            fn = self._factory.decoder_for(channel.message_encoding, schema)
        except (*_DECODE_ERRORS, RecursionError):
            fn = None
        if fn is None:
            return None, f"of an unreadable schema {schema.name[:60]!r}"
        return fn, ""

    def _selection(self, topics: Iterable[str] | None, start_ns: int | None, end_ns: int | None,
                   ) -> tuple[dict[int, tuple[str, str, Callable[[bytes], Any] | None, str]], list[Any]]:
        """The chosen channels (id -> topic, schema name, decoder or None, why not) and the loose messages
        (outside chunks) of the window."""
        s = self._index
        wanted = set(topics) if topics is not None else None
        info: dict[int, tuple[str, str, Callable[[bytes], Any] | None, str]] = {}
        for cid, ch in s.channels.items():
            if wanted is None or ch.topic in wanted:
                schema = s.schemas.get(ch.schema_id)
                info[cid] = (ch.topic, schema.name if schema else "", *self._decoder(ch, schema))
        loose = [m for m in self._loose if m[2] in info and (start_ns is None or m[0] >= start_ns)
                 and (end_ns is None or m[0] < end_ns)]
        return info, loose

    def messages(
        self, topics: Iterable[str] | None = None, start_ns: int | None = None, end_ns: int | None = None,
    ) -> Iterator[ArchiveMessage]:
        """Decoded messages in log-time order over the chosen topics and window [start, end).

        What cannot be decoded is skipped and counted in `damage`.
        """
        s = self._index
        info, loose = self._selection(topics, start_ns, end_ns)
        skip = self.damage.skip_message
        for log_time, publish_time, cid, data in ordered_messages(
                self._file, s.chunk_indexes, set(info), self.validate_crcs, start_ns, end_ns,
                self.damage.bad_chunk, self.max_chunk_bytes, loose):
            topic, name, decode, why = info[cid]
            if decode is None:
                skip(topic, why)
                continue
            try:
                msg = decode(data)
            except _DECODE_ERRORS:
                skip(topic, "that do not decode")
                continue
            yield ArchiveMessage(topic, name, log_time, publish_time, msg)

    def blocks(
        self, topics: Iterable[str] | None = None, start_ns: int | None = None, end_ns: int | None = None,
        columns: Iterable[str] = (),
    ) -> Iterator[MessageBlock]:
        """The messages of `messages(topics, start_ns, end_ns)`, in the same order, as blocks of one time window
        each (formats.mcap_blocks): the topics in `columns` decoded into numpy columns, the others as objects."""
        s = self._index
        info, loose = self._selection(topics, start_ns, end_ns)
        yield from read_blocks(self._file, s.chunk_indexes, info, set(columns), self.validate_crcs, start_ns, end_ns,
                               self.damage.bad_chunk, self.damage.skip_message, self.max_chunk_bytes, loose,
                               _DECODE_ERRORS)

    # -- summary, metadata, attachments ---------------------------------------
    def summary(self) -> ArchiveSummary:
        """Topics with counts and schemas, time span, attachments and metadata names."""
        out = ArchiveSummary()
        s = self._index
        counts = s.statistics.channel_message_counts if s.statistics else {}
        for cid, ch in s.channels.items():
            schema = s.schemas.get(ch.schema_id)
            entry = out.topics.setdefault(ch.topic, {"count": 0, "schema": schema.name if schema else ""})
            entry["count"] += counts.get(cid, 0)
        if s.statistics and s.statistics.message_count:
            out.start_ns, out.end_ns = s.statistics.message_start_time, s.statistics.message_end_time
            out.message_count = s.statistics.message_count
        out.attachments = [AttachmentInfo(a.name, a.data_size, a.media_type) for a in s.attachment_indexes]
        out.metadata_names = [m.name for m in s.metadata_indexes]
        return out

    def metadata(self, name: str) -> dict[str, str] | None:
        """The last readable metadata record of that name (values as stored, strings), or None."""
        found = None
        for index in self._index.metadata_indexes:
            if index.name != name:
                continue
            try:
                rec: Metadata = read_record(self._file, index.offset, index.length, self._size, OP_METADATA)
            except RecordError as exc:
                self.damage.bad_record("metadata", str(exc))
                continue
            if rec.name == name:
                found = dict(rec.metadata)
        return found

    def metadata_json(self, name: str) -> dict[str, Any] | None:
        """A metadata record with values decoded from JSON where they are JSON."""
        raw = self.metadata(name)
        if raw is None:
            return None
        out: dict[str, Any] = {}
        for k, v in raw.items():
            try:
                out[k] = json.loads(v)
            except (ValueError, RecursionError):
                out[k] = v
        return out

    def attachments(self) -> Iterator[Attachment]:
        """Every readable attachment record, data included and CRC-checked; the rest counted in `damage`."""
        for index in self._index.attachment_indexes:
            try:
                yield read_record(self._file, index.offset, index.length, self._size, OP_ATTACHMENT)
            except RecordError as exc:
                self.damage.bad_record("attachment", str(exc))

    def to_dataframe(self, topic: str, start_ns: int | None = None, end_ns: int | None = None) -> Any:
        """A pandas DataFrame of one topic: UTC DatetimeIndex (log time), one column per field."""
        # pandas (through formats.dataframe) costs half a second to import: only for those who ask a frame
        from .dataframe import messages_to_dataframe

        return messages_to_dataframe(self.messages([topic], start_ns, end_ns))

    def close(self) -> None:
        """Close the file."""
        self._file.close()

    def __enter__(self) -> ArchiveReader:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
