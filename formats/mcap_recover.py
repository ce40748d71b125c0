"""Salvaging a damaged MCAP file: every intact record kept, also past a damaged chunk, indexes rebuilt.

The scan walks the records from the magic. A record that does not parse
(a length past the end, a chunk whose zstd stream or CRC fails, records
inside a chunk that do not add up) is damage: the scan resyncs at the next
position where a record validates (a chunk or attachment by its CRC, any
other record by parsing whole and being followed by a plausible record
header), and the bytes between are reported lost with the time span they
held as far as it can be told. Schemas and channels come from wherever
they are found (chunks, the data section, a surviving summary), so
messages after a lost chunk keep their topics; messages whose channel was
only defined in lost bytes go to `/recovered/channel-<id>`.

The output is written with the `mcap` library's writer (chunks, message
indexes, statistics, summary), under a temporary name renamed at the end.

Memory is bounded whatever the file holds: the scan keeps the schemas,
channels and the file offsets of what it found, never messages; the write
reads the kept records again, one at a time, so at most one chunk is in
memory. A chunk is decompressed under the same cap as the readers'
(`formats.mcap_chunks.MAX_CHUNK_BYTES`): one declaring more is lost, with
its reason.
This module never changes `formats.mcap_reader`: that one reads archives,
this one repairs them.
"""

from __future__ import annotations

import mmap
import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.writer import CompressionType, Writer

from formats.mcap_chunks import MAX_CHUNK_BYTES, ChunkError, mib
from formats.mcap_chunks import decompress as chunk_decompress
from formats.output_files import OutputClaim
from formats.records import FormatError

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
OP_CHUNK, OP_ATTACHMENT, OP_METADATA, OP_DATA_END = 0x06, 0x09, 0x0C, 0x0F
KNOWN = frozenset(range(0x01, 0x10))
_RECORD = struct.Struct("<BQ")
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_MESSAGE = struct.Struct("<HIQQ")
_CHUNK = struct.Struct("<QQQI")
# zstd and lz4 add a few bytes per block to data that does not compress: a chunk's compressed bytes beyond this
# cannot hold MAX_CHUNK_BYTES or less, and are not read
MAX_COMPRESSED = MAX_CHUNK_BYTES + (MAX_CHUNK_BYTES >> 6) + 4096


class _Bad(Exception):
    """The bytes at hand are not a valid record."""


@dataclass
class LostRange:
    """Bytes that did not survive: where, why, and the message time span they held when known (ns)."""

    start: int
    end: int
    reason: str
    start_ns: int | None = None
    end_ns: int | None = None
    chunk: bool = False


@dataclass
class RecoveryReport:
    """What recover kept and what it lost."""

    source: str
    output: str
    size: int = 0
    chunks_kept: int = 0
    messages: int = 0
    attachments: int = 0
    metadata: int = 0
    orphan_messages: int = 0          # channel defined only in lost bytes: kept under /recovered/...
    had_summary: bool = False
    lost: list[LostRange] = field(default_factory=list)
    start_ns: int | None = None
    end_ns: int | None = None

    @property
    def bytes_lost(self) -> int:
        """Bytes in damaged or missing ranges."""
        return sum(r.end - r.start for r in self.lost)

    @property
    def chunks_lost(self) -> int:
        """Damaged chunks (whose header could still be read)."""
        return sum(r.chunk for r in self.lost)


class _Reader:
    """Bounds-checked reads from a buffer; every overrun is `_Bad`."""

    __slots__ = ("buf", "end", "pos")

    def __init__(self, buf: bytes | mmap.mmap | memoryview, pos: int = 0, end: int | None = None):
        self.buf, self.pos, self.end = buf, pos, len(buf) if end is None else end

    def take(self, n: int) -> bytes:
        return bytes(self.view(n))

    def view(self, n: int) -> memoryview:
        """The next n bytes without a copy (of a memoryview or bytes buffer)."""
        if n < 0 or self.pos + n > self.end:
            raise _Bad("record runs past its end")
        out = memoryview(self.buf)[self.pos:self.pos + n]
        self.pos += n
        return out

    def unpack(self, st: struct.Struct) -> tuple:
        return st.unpack(self.take(st.size))

    def string(self) -> str:
        (n,) = self.unpack(_U32)
        try:
            return self.take(n).decode("utf-8")
        except UnicodeDecodeError:
            raise _Bad("string is not UTF-8") from None

    def string_map(self) -> dict[str, str]:
        (n,) = self.unpack(_U32)
        sub = _Reader(self.take(n))
        out = {}
        while sub.pos < sub.end:
            k = sub.string()
            out[k] = sub.string()
        return out


@dataclass
class _Found:
    """What the scan salvaged: schemas and channels, and where each kept record is (read again to write it)."""

    profile: str = ""
    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)
    channels: dict[int, tuple[str, str, int, dict[str, str]]] = field(default_factory=dict)
    kept: list[tuple[int, int]] = field(default_factory=list)  # (opcode, file offset) of kept records, in file order
    messages: int = 0
    attachments: int = 0
    metadata: int = 0
    chunk_spans: list[tuple[int, int, int]] = field(default_factory=list)  # file offset, start ns, end ns


def _schema(r: _Reader, found: _Found) -> None:
    (sid,) = r.unpack(_U16)
    name, encoding = r.string(), r.string()
    (n,) = r.unpack(_U32)
    if sid:
        found.schemas.setdefault(sid, (name, encoding, r.take(n)))


def _channel(r: _Reader, found: _Found) -> None:
    cid, sid = struct.unpack("<HH", r.take(4))
    topic, encoding = r.string(), r.string()
    found.channels.setdefault(cid, (topic, encoding, sid, r.string_map()))


def _message(r: _Reader, length: int) -> tuple[int, int, int, int, bytes]:
    cid, seq, log_time, publish_time = r.unpack(_MESSAGE)
    return cid, seq, log_time, publish_time, r.take(length - _MESSAGE.size)


def _chunk_head(r: _Reader, capped: bool = True) -> tuple[int, int, int, int, str, int]:
    start, end, size, crc = r.unpack(_CHUNK)
    compression = r.string()
    (n,) = r.unpack(_U64)
    if start > end:
        raise _Bad("implausible chunk header")
    if capped and (size > MAX_CHUNK_BYTES or n > MAX_COMPRESSED):
        raise _Bad(f"chunk of {mib(max(size, n))}, over the {mib(MAX_CHUNK_BYTES)} limit")
    return start, end, size, crc, compression, n


def _chunk_records(r: _Reader, offset: int) -> tuple[int, int, bytes]:
    """(start, end, uncompressed records) of a chunk whose data decompresses to its size and CRC."""
    start, end, size, crc, compression, n = _chunk_head(r)
    try:    # one bounded decompression for every reader of ours: a frame claiming 4 GiB is refused unread
        records = chunk_decompress(compression, r.take(n), size, offset)
    except ChunkError as exc:
        raise _Bad(str(exc)) from None
    if len(records) != size:
        raise _Bad("uncompressed size differs from the header")
    if crc and zlib.crc32(records) != crc:
        raise _Bad("chunk CRC mismatch")
    return start, end, records


def _data_record(op: int, body: _Reader, length: int, found: _Found) -> None:
    """A schema, channel or message record (at the top level or in a chunk) read into `found`; others ignored."""
    if op == OP_SCHEMA:
        _schema(body, found)
    elif op == OP_CHANNEL:
        _channel(body, found)
    elif op == OP_MESSAGE:
        _message_head(body, length)
        found.messages += 1


def _chunk(r: _Reader, found: _Found, offset: int) -> None:
    """A chunk whose records all parse and whose CRC holds; its schemas and channels go into `found` only then."""
    start, end, records = _chunk_records(r, offset)
    inner = _Found(schemas=dict(found.schemas), channels=dict(found.channels))
    sub = _Reader(records)
    while sub.pos < sub.end:
        op, length = sub.unpack(_RECORD)
        _data_record(op, _Reader(sub.view(length)), length, inner)
    found.schemas, found.channels = inner.schemas, inner.channels
    found.messages += inner.messages
    found.chunk_spans.append((offset, start, end))


def _chunk_messages(r: _Reader, offset: int) -> list[tuple[int, int, int, int, bytes]]:
    """The messages of a chunk the scan kept (read again: one chunk at a time in memory)."""
    _, _, records = _chunk_records(r, offset)
    out = []
    sub = _Reader(records)
    while sub.pos < sub.end:
        op, length = sub.unpack(_RECORD)
        body = _Reader(sub.view(length))
        if op == OP_MESSAGE:
            out.append(_message(body, length))
    return out


def _message_head(r: _Reader, length: int) -> None:
    """A message record's fixed part is there (its data is checked by length only)."""
    r.unpack(_MESSAGE)
    r.view(length - _MESSAGE.size)


def _attachment(r: _Reader, raw: memoryview) -> tuple[int, int, str, str, memoryview]:
    log_time, create_time = struct.unpack("<QQ", r.take(16))
    name, media = r.string(), r.string()
    (n,) = r.unpack(_U64)
    data = r.view(n)
    (crc,) = r.unpack(_U32)
    if crc and zlib.crc32(raw[:len(raw) - 4]) != crc:
        raise _Bad("attachment CRC mismatch")
    return log_time, create_time, name, media, data


def _parse(buf: mmap.mmap, pos: int, found: _Found) -> tuple[int, int]:
    """(opcode, end) of the valid record at `pos`, noted in `found`; `_Bad` otherwise."""
    if pos + _RECORD.size > len(buf):
        raise _Bad("truncated record header")
    op, length = _RECORD.unpack_from(buf, pos)
    end = pos + _RECORD.size + length
    if op not in KNOWN or end > len(buf):
        raise _Bad("truncated record" if op in KNOWN else f"unknown opcode {op:#x}")
    with memoryview(buf) as whole:
        raw = whole[pos + _RECORD.size:end]   # no copy: an attachment may be as large as the file
        try:
            r = _Reader(raw)
            if op == OP_HEADER:
                found.profile = r.string()
            elif op in (OP_SCHEMA, OP_CHANNEL, OP_MESSAGE):
                _data_record(op, r, length, found)
            elif op == OP_CHUNK:
                _chunk(r, found, pos)
            elif op == OP_ATTACHMENT:
                _attachment(r, raw)
                found.attachments += 1
            elif op == OP_METADATA:
                r.string()
                r.string_map()
                found.metadata += 1
        finally:
            raw.release()
    if op in (OP_MESSAGE, OP_CHUNK, OP_ATTACHMENT, OP_METADATA):
        found.kept.append((op, pos))
    return op, end


def _plausible_next(buf: mmap.mmap, end: int) -> bool:
    """A record header (known opcode, length inside the file) at `end`, or the file's end or closing magic."""
    if end == len(buf) or buf[end:end + len(MAGIC)] == MAGIC:
        return True
    if end + _RECORD.size > len(buf):
        return False
    op, length = _RECORD.unpack_from(buf, end)
    return op in KNOWN and end + _RECORD.size + length <= len(buf)


def _resync(buf: mmap.mmap, pos: int) -> int:
    """The next position after `pos` where a record validates, else the file's end."""
    n = len(buf)
    for q in range(pos + 1, n - _RECORD.size + 1):
        op = buf[q]
        if op not in KNOWN:
            continue
        (length,) = _U64.unpack_from(buf, q + 1)
        if q + _RECORD.size + length > n:
            continue
        probe = _Found()
        try:
            _, end = _parse(buf, q, probe)
        except _Bad:
            continue
        if op in (OP_CHUNK, OP_ATTACHMENT) or _plausible_next(buf, end):
            return q
    return n


def _skip_whole(buf: mmap.mmap, pos: int) -> int | None:
    """The end of a damaged record whose length still holds (a valid record starts there), else None."""
    op, length = _RECORD.unpack_from(buf, pos) if pos + _RECORD.size <= len(buf) else (0, 0)
    end = pos + _RECORD.size + length
    if op not in KNOWN or end >= len(buf):
        return None
    try:
        _parse(buf, end, _Found())
    except _Bad:
        return None
    return end


def _damaged_span(buf: mmap.mmap, pos: int) -> tuple[int | None, int | None, bool]:
    """The message time span a damaged chunk's header still tells, and whether it was a chunk at all."""
    try:
        op, _ = _RECORD.unpack_from(buf, pos)
        if op != OP_CHUNK:
            return None, None, False
        start, end, *_ = _chunk_head(_Reader(buf, pos + _RECORD.size), capped=False)
        return start, end, True
    except (_Bad, struct.error):
        return None, None, False


def scan(buf: mmap.mmap, report: RecoveryReport) -> _Found:
    """Every valid record of the file, the damaged ranges into `report.lost`."""
    found = _Found()
    pos, n = len(MAGIC), len(buf)
    while pos < n:
        if buf[pos:pos + len(MAGIC)] == MAGIC and pos + len(MAGIC) == n:
            break  # the closing magic
        try:
            op, end = _parse(buf, pos, found)
        except _Bad as exc:
            nxt = _skip_whole(buf, pos)
            if nxt is None:
                nxt = _resync(buf, pos)
            start_ns, end_ns, chunk = _damaged_span(buf, pos)
            reason = "truncated (the file ends inside it)" if nxt == n and "truncated" in str(exc) else str(exc)
            report.lost.append(LostRange(pos, nxt, reason, start_ns, end_ns, chunk))
            pos = nxt
            continue
        if op == OP_DATA_END:
            report.had_summary = True  # what follows is the summary: its schemas and channels help too
        if op == OP_FOOTER:
            break
        pos = end
    return found


def _fill_gap_times(report: RecoveryReport, found: _Found) -> None:
    """For lost ranges without a readable chunk header: the span between the kept chunks around them."""
    spans = sorted(found.chunk_spans)
    for lost in report.lost:
        if lost.start_ns is not None:
            continue
        before = [e for off, _, e in spans if off < lost.start]
        after = [s for off, s, _ in spans if off >= lost.end]
        lost.start_ns = max(before) if before else None
        lost.end_ns = min(after) if after else None


def _kept_records(buf: mmap.mmap, found: _Found) -> Iterator[tuple[int, _Reader, int]]:
    """(opcode, reader of its content, file offset) of every record the scan kept, in file order."""
    for op, pos in found.kept:
        _, length = _RECORD.unpack_from(buf, pos)
        with memoryview(buf) as whole:
            raw = whole[pos + _RECORD.size:pos + _RECORD.size + length]
            try:
                yield op, _Reader(raw), pos
            finally:
                raw.release()


def _write(buf: mmap.mmap, found: _Found, out: Path, report: RecoveryReport) -> None:
    """The kept records into a new file, read again one at a time (one chunk in memory at most)."""
    with open(out, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile=found.profile, library="auvreplay recover")
        schema_ids = {sid: w.register_schema(*s) for sid, s in found.schemas.items()}
        channel_ids: dict[int, int] = {}
        for cid, (topic, encoding, sid, meta) in found.channels.items():
            channel_ids[cid] = w.register_channel(topic, encoding, schema_ids.get(sid, 0), meta)

        def add(cid: int, seq: int, log_time: int, publish_time: int, data: bytes) -> None:
            new = channel_ids.get(cid)
            if new is None:
                new = channel_ids[cid] = w.register_channel(f"/recovered/channel-{cid}", "", 0)
            if cid not in found.channels:
                report.orphan_messages += 1
            w.add_message(new, log_time, data, publish_time, seq)
            report.start_ns = log_time if report.start_ns is None else min(report.start_ns, log_time)
            report.end_ns = log_time if report.end_ns is None else max(report.end_ns, log_time)

        for op, r, pos in _kept_records(buf, found):   # each parsed before: a _Bad here is a bug
            if op == OP_CHUNK:
                for message in _chunk_messages(r, pos):
                    add(*message)
            elif op == OP_MESSAGE:
                add(*_message(r, r.end))
            elif op == OP_ATTACHMENT:
                log_time, create_time, name, media, data = _attachment(r, r.buf)  # type: ignore[arg-type]
                w.add_attachment(create_time, log_time, name, media, bytes(data))
                data.release()
            elif op == OP_METADATA:
                name = r.string()
                w.add_metadata(name, r.string_map())
        w.finish()
        f.flush()
        os.fsync(f.fileno())


def recover(source: str | os.PathLike[str], output: str | os.PathLike[str], replace: bool = False) -> RecoveryReport:
    """Write every intact record of `source` to `output` with fresh indexes and summary; say what was lost.

    An existing `output` is replaced only with `replace` (formats.output_files)."""
    src, out = Path(source), Path(output)
    if src.resolve() == out.resolve():
        raise FormatError(f"{out}: recover writes a new file; give an output other than the input")
    report = RecoveryReport(str(src), str(out))
    try:
        f = open(src, "rb")
    except OSError as exc:
        raise FormatError(f"{src}: cannot read ({exc.strerror or exc})") from None
    with f:
        try:
            report.size = os.fstat(f.fileno()).st_size
            if report.size < len(MAGIC) or f.read(len(MAGIC)) != MAGIC:
                raise FormatError(f"{src}: not an MCAP file (no MCAP magic at the start)")
            buf = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except OSError as exc:
            raise FormatError(f"{src}: cannot read ({exc.strerror or exc})") from None
        with buf:
            found = scan(buf, report)
            report.chunks_kept = len(found.chunk_spans)
            report.messages = found.messages
            report.attachments, report.metadata = found.attachments, found.metadata
            _fill_gap_times(report, found)
            claim = OutputClaim(out, replace)  # one writer at a time; an existing file kept unless `replace`
            try:   # the file is read again as it is written: one chunk in memory at a time
                _write(buf, found, claim.part, report)
                claim.publish()
            finally:
                claim.part.unlink(missing_ok=True)
                claim.abandon()
    return report
