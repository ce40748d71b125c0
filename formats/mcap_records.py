"""MCAP records framed by us and bounded by the file: the summary section and the sequential scan.

Every length is checked against the bytes that are really there before it is
read, so a damaged or crafted file costs at most its own size in memory. A
record whose fields do not parse is reported and skipped (its framing still
holds); a record that runs past the end of the file ends the scan. Either
way the answer is an `mcap.summary.Summary` (chunk, attachment and metadata
indexes, schemas, channels, statistics) that the time-ordered reader
(`formats.mcap_chunks`) walks the same way for a whole file and a damaged one.
Field layouts are parsed by the `mcap` library's record classes.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from io import BytesIO
from typing import Any, BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    ChunkIndex,
    Footer,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
)
from mcap.summary import Summary

from .mcap_chunks import ChunkError, RawMessage, chunk_payload, inner_records, mib

MAGIC = b"\x89MCAP0\r\n"
OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x02, 0x03, 0x04, 0x05, 0x06
OP_CHUNK_INDEX, OP_ATTACHMENT, OP_ATTACHMENT_INDEX, OP_STATISTICS = 0x08, 0x09, 0x0A, 0x0B
OP_METADATA, OP_METADATA_INDEX, OP_DATA_END = 0x0C, 0x0D, 0x0F
_HEAD = struct.Struct("<BQ")
_CHUNK_FIELDS = struct.Struct("<QQQI")     # start, end, uncompressed size, crc (after the record head)
_MESSAGE_HEAD = struct.Struct("<HIQQ")
_FOOTER = struct.Struct("<BQQQI")          # opcode, length (20), summary start, summary offset start, crc
FOOTER_SIZE = _FOOTER.size + len(MAGIC)

# (where, what): a damage report; the scan goes on unless it says the file ends there
Report = Callable[[str, str], None]

_PARSERS: dict[int, Callable[[ReadDataStream], Any]] = {
    OP_SCHEMA: Schema.read, OP_CHANNEL: Channel.read, OP_CHUNK_INDEX: ChunkIndex.read,
    OP_ATTACHMENT_INDEX: AttachmentIndex.read, OP_METADATA_INDEX: MetadataIndex.read,
    OP_STATISTICS: Statistics.read, OP_METADATA: Metadata.read, OP_ATTACHMENT: Attachment.read,
}
_KIND = {OP_SCHEMA: "schema", OP_CHANNEL: "channel", OP_METADATA: "metadata", OP_ATTACHMENT: "attachment",
         OP_CHUNK_INDEX: "chunk index", OP_ATTACHMENT_INDEX: "attachment index",
         OP_METADATA_INDEX: "metadata index", OP_STATISTICS: "statistics"}


# what damaged fields raise in the mcap library's readers (UnicodeDecodeError is a ValueError)
_FIELD_ERRORS = (McapError, EOFError, struct.error, ValueError, OverflowError)


class RecordError(ValueError):
    """A record whose fields do not parse."""


def parse(op: int, body: bytes) -> Any:
    """The `mcap.records` object of one record body; RecordError when its fields do not parse."""
    stream = ReadDataStream(BytesIO(body))
    try:
        rec = _PARSERS[op](stream)
    except _FIELD_ERRORS as exc:
        raise RecordError(f"unreadable {_KIND.get(op, hex(op))} record ({type(exc).__name__})") from exc
    if stream.count > len(body):
        raise RecordError(f"{_KIND.get(op, hex(op))} record fields run past its length")
    return rec


def frames(f: BinaryIO, start: int, end: int, report: Report) -> Iterator[tuple[int, int, bytes]]:
    """(offset, opcode, body) of the records in [start, end); stops, reporting, at one that overruns `end`."""
    pos = start
    f.seek(pos)
    while pos < end:
        if end - pos < _HEAD.size:
            report(f"byte {pos}", f"truncated: {end - pos} bytes left, not a whole record")
            return
        op, length = _HEAD.unpack(f.read(_HEAD.size))
        if length > end - pos - _HEAD.size:
            report(f"byte {pos}", f"truncated or damaged: a record (opcode {op:#x}) declares {mib(length)}, "
                   f"{mib(end - pos - _HEAD.size)} remain")
            return
        body = f.read(length)
        yield pos, op, body
        pos += _HEAD.size + length


def read_footer(f: BinaryIO, size: int) -> Footer | None:
    """The footer of a whole file, or None when the file does not end with footer and magic."""
    if size < len(MAGIC) + FOOTER_SIZE:
        return None
    f.seek(size - FOOTER_SIZE)
    tail = f.read(FOOTER_SIZE)
    if tail[-len(MAGIC):] != MAGIC:
        return None
    op, length, summary_start, offset_start, crc = _FOOTER.unpack_from(tail, 0)
    if op != OP_FOOTER or length != 20:
        return None
    return Footer(summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc)


def read_summary(f: BinaryIO, size: int, validate_crc: bool) -> tuple[Summary | None, str | None]:
    """(the summary section, None) of a whole file, or (None, why not) when it is missing or damaged."""
    footer = read_footer(f, size)
    if footer is None:
        return None, "no footer (a cut-off write?)"
    footer_at = size - FOOTER_SIZE
    if footer.summary_start == 0:
        return None, "no summary section"
    if not len(MAGIC) <= footer.summary_start < footer_at:
        return None, f"footer points to a summary at byte {footer.summary_start}, outside the file"
    if validate_crc and footer.summary_crc:
        f.seek(footer.summary_start)
        crc = zlib.crc32(f.read(footer_at - footer.summary_start))
        crc = zlib.crc32(_FOOTER.pack(OP_FOOTER, 20, footer.summary_start, footer.summary_offset_start, 0)[:-4], crc)
        if crc != footer.summary_crc:
            return None, "summary section CRC mismatch"
    problems: list[str] = []
    summary = Summary()
    for pos, op, body in frames(f, footer.summary_start, footer_at, lambda where, what: problems.append(what)):
        if op not in _PARSERS or op in (OP_METADATA, OP_ATTACHMENT):
            continue
        try:
            rec = parse(op, body)
        except RecordError as exc:
            return None, f"summary byte {pos}: {exc}"
        _add(summary, rec)
    if problems:
        return None, f"summary section damaged ({problems[0]})"
    return summary, None


def _add(summary: Summary, rec: Any) -> None:
    if isinstance(rec, Schema):
        summary.schemas[rec.id] = rec
    elif isinstance(rec, Channel):
        summary.channels[rec.id] = rec
    elif isinstance(rec, ChunkIndex):
        summary.chunk_indexes.append(rec)
    elif isinstance(rec, AttachmentIndex):
        summary.attachment_indexes.append(rec)
    elif isinstance(rec, MetadataIndex):
        summary.metadata_indexes.append(rec)
    elif isinstance(rec, Statistics):
        summary.statistics = rec


@dataclass
class Scan:
    """What a sequential scan found: an index like a summary's, and messages outside any chunk."""

    summary: Summary = field(default_factory=Summary)
    loose: list[RawMessage] = field(default_factory=list)


def scan(f: BinaryIO, size: int, validate_crc: bool, limit: int, report: Report) -> Scan:
    """Index a file record by record from its start, as far as its records are whole.

    Chunks are decompressed (bounded by `limit`) to find their channels,
    schemas and true time spans; the index built points at them, so messages
    are later read chunk by chunk as for a whole file.
    """
    out = Scan()
    counts: dict[int, int] = {}
    span = [None, None]
    stats = {"attachments": 0, "metadata": 0, "chunks": 0}
    for pos, op, body in frames(f, len(MAGIC), size, report):
        if op == OP_CHUNK:
            _scan_chunk(out, pos, body, validate_crc, limit, counts, span, report)
            stats["chunks"] += 1
        elif op == OP_MESSAGE:
            if len(body) < _MESSAGE_HEAD.size:
                report(f"byte {pos}", "message record too short")
                continue
            cid, _, log_time, publish_time = _MESSAGE_HEAD.unpack_from(body, 0)
            out.loose.append((log_time, publish_time, cid, body[_MESSAGE_HEAD.size:]))
            _count(counts, span, cid, log_time)
        elif op in (OP_SCHEMA, OP_CHANNEL):
            try:
                _add(out.summary, parse(op, body))
            except RecordError as exc:
                report(f"byte {pos}", str(exc))
        elif op == OP_ATTACHMENT:
            try:
                att = parse(op, body)
            except RecordError as exc:
                report(f"byte {pos}", str(exc))
                continue
            out.summary.attachment_indexes.append(AttachmentIndex(
                offset=pos, length=_HEAD.size + len(body), log_time=att.log_time, create_time=att.create_time,
                data_size=len(att.data), name=att.name, media_type=att.media_type))
            stats["attachments"] += 1
        elif op == OP_METADATA:
            try:
                meta = parse(op, body)
            except RecordError as exc:
                report(f"byte {pos}", str(exc))
                continue
            out.summary.metadata_indexes.append(MetadataIndex(offset=pos, length=_HEAD.size + len(body),
                                                              name=meta.name))
            stats["metadata"] += 1
        elif op == OP_DATA_END:
            break
    out.loose.sort(key=lambda m: m[0])
    out.summary.statistics = Statistics(
        attachment_count=stats["attachments"], channel_count=len(out.summary.channels),
        channel_message_counts=counts, chunk_count=stats["chunks"], message_count=sum(counts.values()),
        message_start_time=span[0] or 0, message_end_time=span[1] or 0,
        metadata_count=stats["metadata"], schema_count=len(out.summary.schemas))
    return out


def _count(counts: dict[int, int], span: list, cid: int, log_time: int) -> None:
    counts[cid] = counts.get(cid, 0) + 1
    span[0] = log_time if span[0] is None else min(span[0], log_time)
    span[1] = log_time if span[1] is None else max(span[1], log_time)


def _scan_chunk(out: Scan, pos: int, body: bytes, validate_crc: bool, limit: int,
                counts: dict[int, int], span: list, report: Report) -> None:
    if len(body) < _CHUNK_FIELDS.size:
        report(f"byte {pos}", "chunk record too short")
        return
    _, _, size, crc = _CHUNK_FIELDS.unpack_from(body, 0)
    try:
        data = chunk_payload(_HEAD.pack(OP_CHUNK, len(body)) + body, pos, size, crc, validate_crc, limit)
    except ChunkError as exc:
        report(f"byte {pos}", str(exc))
        return
    channels: dict[int, int] = {}
    lo: int | None = None
    hi: int | None = None
    try:
        for op, rec in inner_records(data, pos):
            if op == OP_MESSAGE and len(rec) >= _MESSAGE_HEAD.size:
                cid, _, log_time, _ = _MESSAGE_HEAD.unpack_from(rec, 0)
                channels[cid] = 0
                _count(counts, span, cid, log_time)
                lo = log_time if lo is None else min(lo, log_time)
                hi = log_time if hi is None else max(hi, log_time)
            elif op in (OP_SCHEMA, OP_CHANNEL):
                try:
                    _add(out.summary, parse(op, rec))
                except RecordError as exc:
                    report(f"byte {pos}", f"in a chunk: {exc}")
    except ChunkError as exc:
        report(f"byte {pos}", f"{exc}; the rest of the chunk skipped")
    if lo is not None and hi is not None:
        out.summary.chunk_indexes.append(ChunkIndex(
            message_start_time=lo, message_end_time=hi, chunk_start_offset=pos,
            chunk_length=_HEAD.size + len(body), message_index_offsets=channels, message_index_length=0,
            compression="", compressed_size=0, uncompressed_size=size))


def read_record(f: BinaryIO, offset: int, length: int, size: int, op: int) -> Any:
    """The record of opcode `op` at `offset` (an index's pointer); RecordError when it is not there or unreadable."""
    if offset < 0 or length < _HEAD.size or offset + length > size:
        raise RecordError(f"byte {offset}: a {_KIND.get(op, hex(op))} record of {length} bytes is not in the file")
    f.seek(offset)
    raw = f.read(length)
    got, rlen = _HEAD.unpack_from(raw, 0)
    if got != op or rlen != length - _HEAD.size:
        raise RecordError(f"byte {offset}: no {_KIND.get(op, hex(op))} record there")
    try:
        rec = parse(op, raw[_HEAD.size:])
    except RecordError as exc:
        raise RecordError(f"byte {offset}: {exc}") from exc
    if op == OP_ATTACHMENT:
        (crc,) = struct.unpack_from("<I", raw, length - 4)
        if crc and zlib.crc32(raw[_HEAD.size:-4]) != crc:
            raise RecordError(f"byte {offset}: attachment {rec.name!r} CRC mismatch")
    return rec
