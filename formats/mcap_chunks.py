"""Reading MCAP chunks fast and bounded: messages as plain tuples, merged across chunks in log-time order.

Only what the time-ordered read needs, written from the MCAP spec: a Chunk
record's header, its (zstd/lz4/none) records, and the Message records in it.
Archives come from other people's machines, so a chunk is decompressed only
up to the size it declares, and only when that size is under a cap
(`MAX_CHUNK_BYTES`): a 134 KB chunk that inflates to 4 GiB, or one that
declares 16 GiB, is refused as a `ChunkError` (the caller counts it and goes
on with the next chunk), never held in memory.
"""

from __future__ import annotations

import heapq
import struct
import zlib
from bisect import bisect_left
from collections.abc import Callable, Iterable, Iterator
from operator import itemgetter
from typing import BinaryIO

import lz4.frame
import zstandard

from .records import FormatError

OP_CHUNK, OP_MESSAGE = 0x06, 0x05
MAX_CHUNK_BYTES = 64 << 20                  # our writer's chunks are 1 MiB; the mcap CLI's a few MiB
_CHUNK_HEAD = struct.Struct("<BQQQQI")      # opcode, length, start, end, uncompressed size, crc
_RECORD_HEAD = struct.Struct("<BQ")
_MESSAGE_HEAD = struct.Struct("<HIQQ")      # channel, sequence, log time, publish time
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")
_MESSAGE_MIN = _MESSAGE_HEAD.size

# (log_time, publish_time, channel_id, data)
RawMessage = tuple[int, int, int, bytes]
_log_time = itemgetter(0)   # a RawMessage's log time: the sort key of a chunk's messages
# (chunk offset, reason): how a damaged chunk is reported while the read goes on
OnDamage = Callable[[int, str], None]


class ChunkError(FormatError):
    """A chunk that cannot be used (bad header, over the size cap, does not decompress, CRC mismatch)."""


def lz4_bounded(body: bytes, size: int) -> bytes:
    """An lz4 frame inflated to at most `size` bytes; ValueError ('inflates past ...') when it holds more."""
    d = lz4.frame.LZ4FrameDecompressor()
    out = d.decompress(body, max_length=size)
    if not d.eof and d.decompress(b"", max_length=1):
        raise ValueError(f"inflates past the {mib(size)} declared")
    return out


def mib(n: int) -> str:
    """A byte count for a message: '64 MiB', '4.0 GiB', '1234 bytes'."""
    if n >= 1 << 30:
        return f"{n / (1 << 30):.1f} GiB"
    if n >= 1 << 20:
        return f"{n >> 20} MiB"
    return f"{n} bytes"


def read_chunk(f: BinaryIO, offset: int, length: int, file_size: int, validate_crc: bool,
               limit: int = MAX_CHUNK_BYTES) -> tuple[int, int, bytes]:
    """(start time, end time, uncompressed records) of the chunk record at `offset`, `length` bytes long.

    Raises ChunkError when the record runs past the end of the file, declares
    more than `limit` bytes, does not decompress to exactly its declared size,
    or fails its CRC.
    """
    if offset < 0 or length < _CHUNK_HEAD.size + 12 or offset + length > file_size:
        raise ChunkError(f"byte {offset}: chunk of {length} bytes does not fit in the file ({file_size} bytes)")
    f.seek(offset)
    raw = f.read(length)
    op, rlen, start, end, size, crc = _CHUNK_HEAD.unpack_from(raw, 0)
    if op != OP_CHUNK:
        raise ChunkError(f"byte {offset}: expected a chunk record, found opcode {op:#x}")
    return start, end, chunk_payload(raw, offset, size, crc, validate_crc, limit)


def chunk_payload(raw: bytes, offset: int, size: int, crc: int, validate_crc: bool, limit: int) -> bytes:
    """The uncompressed records of a chunk record `raw` (opcode and length included); see `read_chunk`."""
    if size > limit:
        raise ChunkError(f"byte {offset}: chunk declares {mib(size)} uncompressed, over the {mib(limit)} limit")
    pos = _CHUNK_HEAD.size
    try:
        (n,) = _U32.unpack_from(raw, pos)
        compression = raw[pos + 4:pos + 4 + n].decode()
        pos += 4 + n
        (records_len,) = _U64.unpack_from(raw, pos)
    except (struct.error, UnicodeDecodeError) as exc:
        raise ChunkError(f"byte {offset}: unreadable chunk header") from exc
    body = raw[pos + 8:pos + 8 + records_len]
    if len(body) != records_len:
        raise ChunkError(f"byte {offset}: chunk data of {records_len} bytes runs past its record")
    data = decompress(compression, body, size, offset)
    if len(data) != size:
        raise ChunkError(f"byte {offset}: chunk decompresses to {mib(len(data))}, not the {mib(size)} declared")
    if validate_crc and crc and zlib.crc32(data) != crc:
        raise ChunkError(f"byte {offset}: chunk CRC mismatch")
    return data


def decompress(compression: str, body: bytes, size: int, offset: int) -> bytes:
    """At most `size` bytes out of a chunk's `body` (more is a ChunkError: the caller has checked `size` is sane)."""
    try:
        if compression == "zstd":
            # python-zstandard allocates a frame's own content size, whatever max_output_size says
            declared = zstandard.get_frame_parameters(body).content_size
            if declared not in (zstandard.CONTENTSIZE_UNKNOWN, size):
                raise ChunkError(f"byte {offset}: zstd frame holds {mib(declared)}, the chunk declares {mib(size)}")
            return zstandard.ZstdDecompressor().decompress(body, max_output_size=size)
        if compression == "":
            return body
        if compression == "lz4":
            try:
                return lz4_bounded(body, size)
            except ValueError as exc:
                raise ChunkError(f"byte {offset}: lz4 data {exc}") from None
    except (zstandard.ZstdError, RuntimeError, ValueError) as exc:
        if isinstance(exc, ChunkError):
            raise
        # zstd says "did not decompress full frame" when the output limit stops it: a bomb or damage
        raise ChunkError(f"byte {offset}: {compression} data does not decompress within the {mib(size)} "
                         f"declared ({exc})") from exc
    raise ChunkError(f"byte {offset}: unsupported chunk compression {compression!r}")


def inner_records(data: bytes, offset: int) -> Iterator[tuple[int, bytes]]:
    """(opcode, body) of every record in a chunk's uncompressed data; a record that overruns is a ChunkError."""
    pos, end = 0, len(data)
    head = _RECORD_HEAD.unpack_from
    while pos < end:
        if pos + 9 > end:
            raise ChunkError(f"byte {offset}: chunk ends inside a record header")
        op, rlen = head(data, pos)
        pos += 9
        if rlen > end - pos:
            raise ChunkError(f"byte {offset}: a record of {rlen} bytes overruns its chunk")
        yield op, data[pos:pos + rlen]
        pos += rlen


def chunk_messages(f: BinaryIO, offset: int, length: int, channels: set[int] | None, validate_crc: bool,
                   start_ns: int | None, end_ns: int | None, file_size: int | None = None,
                   on_damage: OnDamage | None = None, limit: int = MAX_CHUNK_BYTES) -> list[RawMessage]:
    """The messages of the chunk at `offset`, sorted by log time (stable), filtered by channel and window.

    A damaged chunk raises ChunkError; with `on_damage`, a record that
    overruns the chunk is reported there and the messages before it are kept.
    """
    if file_size is None:
        f.seek(0, 2)
        file_size = f.tell()
    _, _, data = read_chunk(f, offset, length, file_size, validate_crc, limit)
    return chunk_records(data, offset, channels, start_ns, end_ns, on_damage)


def chunk_records(data: bytes, offset: int, channels: set[int] | None, start_ns: int | None, end_ns: int | None,
                  on_damage: OnDamage | None = None) -> list[RawMessage]:
    """The message records of an inflated chunk (the one at `offset`), filtered by channel and window, sorted
    by log time (stable); a record that overruns the chunk as `chunk_messages` says."""
    out: list[RawMessage] = []
    pos, end = 0, len(data)
    head, msg_head = _RECORD_HEAD.unpack_from, _MESSAGE_HEAD.unpack_from
    while pos < end:
        if pos + 9 > end:
            _overrun(offset, on_damage, "the chunk ends inside a record header")
            break
        op, rlen = head(data, pos)
        pos += 9
        if rlen > end - pos or (op == OP_MESSAGE and rlen < _MESSAGE_MIN):
            _overrun(offset, on_damage, f"a record of {rlen} bytes does not fit its chunk")
            break
        if op == OP_MESSAGE:
            channel, _, log_time, publish_time = msg_head(data, pos)
            if (channels is None or channel in channels) and (start_ns is None or log_time >= start_ns) \
                    and (end_ns is None or log_time < end_ns):
                out.append((log_time, publish_time, channel, data[pos + 22:pos + rlen]))
        pos += rlen
    out.sort(key=_log_time)
    return out


def _overrun(offset: int, on_damage: OnDamage | None, what: str) -> None:
    if on_damage is None:
        raise ChunkError(f"byte {offset}: {what}")
    on_damage(offset, f"byte {offset}: {what}; the rest of the chunk skipped")


def ordered_messages(f: BinaryIO, chunk_indexes: Iterable, channels: set[int] | None, validate_crc: bool,
                     start_ns: int | None = None, end_ns: int | None = None,
                     on_damage: OnDamage | None = None, limit: int = MAX_CHUNK_BYTES,
                     loose: list[RawMessage] | None = None) -> Iterator[RawMessage]:
    """Messages of every matching chunk in log-time order; a chunk is read only when its time comes.

    Memory holds the chunks whose time spans overlap the current instant,
    never the whole file. A damaged chunk raises ChunkError, or with
    `on_damage` is reported there and skipped. `loose` are messages found
    outside any chunk, already sorted by log time, merged in as one more run.
    """
    f.seek(0, 2)
    file_size = f.tell()
    todo = sorted(
        (ci for ci in chunk_indexes
         if (channels is None or channels & ci.message_index_offsets.keys() or not ci.message_index_offsets)
         and (start_ns is None or ci.message_end_time >= start_ns)
         and (end_ns is None or ci.message_start_time < end_ns)),
        key=lambda ci: (ci.message_start_time, ci.chunk_start_offset))
    # (log time, chunk offset, index in chunk): ties break by file position, as mcap's reader does
    heap: list[tuple[int, int, int, RawMessage, list[RawMessage]]] = []
    if loose:
        heap.append((loose[0][0], -1, 0, loose[0], loose))
    nxt = 0
    while heap or nxt < len(todo):
        while nxt < len(todo) and (not heap or todo[nxt].message_start_time <= heap[0][0]):
            ci = todo[nxt]
            nxt += 1
            try:
                msgs = chunk_messages(f, ci.chunk_start_offset, ci.chunk_length, channels, validate_crc,
                                      start_ns, end_ns, file_size, on_damage, limit)
            except ChunkError as exc:
                if on_damage is None:
                    raise
                on_damage(ci.chunk_start_offset, str(exc))
                continue
            if msgs:
                heapq.heappush(heap, (msgs[0][0], ci.chunk_start_offset, 0, msgs[0], msgs))
        if not heap:
            continue
        _, order, i, msg, msgs = heap[0]
        if len(heap) == 1:
            # one run open (chunks that do not overlap, the usual case): every message before the next
            # chunk's start comes first, in the run's order, without a heap step per message
            j = len(msgs) if nxt == len(todo) else bisect_left(msgs, todo[nxt].message_start_time, i + 1,
                                                                 key=_log_time)
            yield from msgs[i:j] if i or j < len(msgs) else msgs
            if j < len(msgs):
                heap[0] = (msgs[j][0], order, j, msgs[j], msgs)
            else:
                heap.pop()
            continue
        yield msg
        if i + 1 < len(msgs):
            heapq.heapreplace(heap, (msgs[i + 1][0], order, i + 1, msgs[i + 1], msgs))
        else:
            heapq.heappop(heap)
