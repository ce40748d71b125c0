"""Reading archives: time-ordered streaming, decoded messages, DataFrames, damage recovery.

A complete file is read through its index (chunks merged in log-time order,
CRCs validated). A file without a valid summary (a write that was cut off)
is read sequentially: every complete chunk is recovered, the damage is
reported in `ArchiveReader.problems`, and nothing raises.
"""

from __future__ import annotations

import heapq
import json
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap_protobuf.decoder import DecoderFactory
import zstandard

from .mcap_chunks import ordered_messages
from .records import FormatError
from .schemas import MESSAGE_CLASSES

MAGIC = b"\x89MCAP0\r\n"


@dataclass(frozen=True, slots=True)
class ArchiveMessage:
    """One message: topic, schema name, times (ns, UTC) and the decoded protobuf message."""

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


def _check_magic(path: Path) -> None:
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


class _Decoders:
    """Per-schema decoders: our generated classes first, mcap-protobuf's dynamic ones otherwise."""

    def __init__(self) -> None:
        self._cache: dict[int, Callable[[bytes], Any]] = {}
        self._factory = DecoderFactory()

    def __call__(self, schema: Schema | None, channel: Channel, data: bytes) -> Any:
        fn = self._cache.get(channel.id)
        if fn is None:
            fn = self._make(schema, channel)
            self._cache[channel.id] = fn
        return fn(data)

    def _make(self, schema: Schema | None, channel: Channel) -> Callable[[bytes], Any]:
        if schema is not None and channel.message_encoding == "protobuf":
            cls = MESSAGE_CLASSES.get(schema.name)
            if cls is not None:
                return cls.FromString
            fn = self._factory.decoder_for(channel.message_encoding, schema)
            if fn is not None:
                return fn
        return bytes


class ArchiveReader:
    """Reads an MCAP archive (context manager). Raises FormatError if it is not MCAP at all."""

    def __init__(self, path: str | os.PathLike[str], validate_crcs: bool = True):
        self.path = Path(path)
        _check_magic(self.path)
        self._file = open(self.path, "rb")
        self._reader = SeekingReader(self._file, validate_crcs=validate_crcs)
        self.validate_crcs = validate_crcs
        self.problems: list[str] = []
        self._decode = _Decoders()
        try:
            self._summary = self._reader.get_summary()
        except Exception as exc:  # noqa: BLE001 - a damaged footer/summary raises many kinds
            self._summary = None
            self.problems.append(f"no valid summary ({type(exc).__name__}: {exc}); recovering complete chunks")
        if self._summary is None and not self.problems:
            self.problems.append("no summary section; reading sequentially")

    @property
    def recovered(self) -> bool:
        """True when the file had no valid summary and was read sequentially."""
        return self._summary is None

    # -- sequential recovery -------------------------------------------------
    def _scan(self) -> Iterator[Any]:
        """Every readable record in file order; stops (and reports) at the first damage."""
        self._file.seek(0)
        stream = StreamReader(self._file, validate_crcs=self.validate_crcs)
        try:
            yield from stream.records
        except Exception as exc:  # noqa: BLE001 - any parse error in damaged bytes ends the scan
            where = self._file.tell()
            msg = f"truncated or damaged near byte {where} ({type(exc).__name__}{': ' + str(exc) if str(exc) else ''})"
            if msg not in self.problems:
                self.problems.append(msg)

    def _scan_messages(self) -> Iterator[tuple[Schema | None, Channel, Message]]:
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        for rec in self._scan():
            if isinstance(rec, Schema):
                schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                channels[rec.id] = rec
            elif isinstance(rec, Message) and rec.channel_id in channels:
                ch = channels[rec.channel_id]
                yield schemas.get(ch.schema_id), ch, rec

    # -- messages --------------------------------------------------------------
    def raw_messages(
        self, topics: Iterable[str] | None = None, start_ns: int | None = None, end_ns: int | None = None,
    ) -> Iterator[tuple[Schema | None, Channel, Message]]:
        """Undecoded (schema, channel, message) in log-time order; end is exclusive."""
        wanted = set(topics) if topics is not None else None
        if self._summary is not None:
            yield from self._reader.iter_messages(
                topics=list(wanted) if wanted is not None else None,
                starting_at=start_ns, ending_before=end_ns, log_time_order=True,
            )
            return
        # A damaged file has no index: recovery buffers and sorts what it finds.
        found = [
            (m.log_time, i, (s, c, m))
            for i, (s, c, m) in enumerate(self._scan_messages())
            if (wanted is None or c.topic in wanted)
            and (start_ns is None or m.log_time >= start_ns)
            and (end_ns is None or m.log_time < end_ns)
        ]
        heapq.heapify(found)
        while found:
            yield heapq.heappop(found)[2]

    def messages(
        self, topics: Iterable[str] | None = None, start_ns: int | None = None, end_ns: int | None = None,
    ) -> Iterator[ArchiveMessage]:
        """Decoded messages in log-time order over the chosen topics and window [start, end)."""
        if self._summary is not None and self._summary.chunk_indexes:
            yield from self._indexed_messages(topics, start_ns, end_ns)
            return
        try:
            for schema, channel, msg in self.raw_messages(topics, start_ns, end_ns):
                yield ArchiveMessage(
                    channel.topic, schema.name if schema else "", msg.log_time, msg.publish_time,
                    self._decode(schema, channel, msg.data),
                )
        except (McapError, ValueError, EOFError, struct.error) as exc:
            raise FormatError(f"{self.path}: damaged archive ({type(exc).__name__}: {exc})") from exc

    def _indexed_messages(
        self, topics: Iterable[str] | None, start_ns: int | None, end_ns: int | None,
    ) -> Iterator[ArchiveMessage]:
        """The fast path of `messages` through the chunk index (see formats.mcap_chunks)."""
        s = self._summary
        wanted = set(topics) if topics is not None else None
        channels = {cid for cid, ch in s.channels.items() if wanted is None or ch.topic in wanted}
        info = {}
        for cid in channels:
            ch = s.channels[cid]
            schema = s.schemas.get(ch.schema_id)
            info[cid] = (ch.topic, schema.name if schema else "", schema, ch)
        try:
            for log_time, publish_time, cid, data in ordered_messages(
                    self._file, s.chunk_indexes, channels, self.validate_crcs, start_ns, end_ns):
                topic, name, schema, ch = info[cid]
                yield ArchiveMessage(topic, name, log_time, publish_time, self._decode(schema, ch, data))
        except (McapError, ValueError, EOFError, struct.error, zstandard.ZstdError) as exc:
            raise FormatError(f"{self.path}: damaged archive ({type(exc).__name__}: {exc})") from exc

    # -- summary, metadata, attachments ---------------------------------------
    def summary(self) -> ArchiveSummary:
        """Topics with counts and schemas, time span, attachments and metadata names."""
        out = ArchiveSummary()
        if self._summary is not None:
            s = self._summary
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
        return self._summary_by_scan(out)

    def _summary_by_scan(self, out: ArchiveSummary) -> ArchiveSummary:
        for schema, channel, msg in self._scan_messages():
            entry = out.topics.setdefault(channel.topic, {"count": 0, "schema": schema.name if schema else ""})
            entry["count"] += 1
            out.message_count += 1
            out.start_ns = msg.log_time if out.start_ns is None else min(out.start_ns, msg.log_time)
            out.end_ns = msg.log_time if out.end_ns is None else max(out.end_ns, msg.log_time)
        for rec in self._scan():
            if isinstance(rec, Attachment):
                out.attachments.append(AttachmentInfo(rec.name, len(rec.data), rec.media_type))
            elif isinstance(rec, Metadata):
                out.metadata_names.append(rec.name)
        return out

    def metadata(self, name: str) -> dict[str, str] | None:
        """The last metadata record of that name (values as stored, strings), or None."""
        found = None
        records = self._scan() if self._summary is None else self._reader.iter_metadata()
        for rec in records:
            if isinstance(rec, Metadata) and rec.name == name:
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
            except ValueError:
                out[k] = v
        return out

    def attachments(self) -> Iterator[Attachment]:
        """Every attachment record, data included, CRC-checked by the mcap library."""
        if self._summary is not None:
            yield from self._reader.iter_attachments()
        else:
            for rec in self._scan():
                if isinstance(rec, Attachment):
                    yield rec

    def to_dataframe(self, topic: str, start_ns: int | None = None, end_ns: int | None = None) -> "Any":
        """A pandas DataFrame of one topic: UTC DatetimeIndex (log time), one column per field."""
        from .dataframe import messages_to_dataframe

        return messages_to_dataframe(self.messages([topic], start_ns, end_ns))

    def close(self) -> None:
        """Close the file."""
        self._file.close()

    def __enter__(self) -> "ArchiveReader":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
