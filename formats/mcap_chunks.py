"""Reading MCAP chunks fast: messages as plain tuples, merged across chunks in log-time order.

Only what the time-ordered read needs, written from the MCAP spec: a Chunk
record's header, its (zstd/lz4/none) records, and the Message records in it.
Everything else (summary, schemas, channels, attachments) stays with the
`mcap` library.
"""

from __future__ import annotations

import heapq
import struct
import zlib
from typing import BinaryIO, Iterable, Iterator

import zstandard

from .records import FormatError

OP_CHUNK, OP_MESSAGE = 0x06, 0x05
_CHUNK_HEAD = struct.Struct("<BQQQQI")      # opcode, length, start, end, uncompressed size, crc
_RECORD_HEAD = struct.Struct("<BQ")
_MESSAGE_HEAD = struct.Struct("<HIQQ")      # channel, sequence, log time, publish time
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")

# (log_time, publish_time, channel_id, data)
RawMessage = tuple[int, int, int, bytes]


def chunk_messages(f: BinaryIO, offset: int, length: int, channels: set[int] | None, validate_crc: bool,
                   start_ns: int | None, end_ns: int | None) -> list[RawMessage]:
    """The messages of the chunk at `offset`, sorted by log time (stable), filtered by channel and window."""
    f.seek(offset)
    raw = f.read(length)
    op, _, _, _, size, crc = _CHUNK_HEAD.unpack_from(raw, 0)
    if op != OP_CHUNK:
        raise FormatError(f"byte {offset}: expected a chunk record, found opcode {op:#x}")
    pos = _CHUNK_HEAD.size
    (n,) = _U32.unpack_from(raw, pos)
    compression = raw[pos + 4:pos + 4 + n].decode()
    pos += 4 + n
    (records_len,) = _U64.unpack_from(raw, pos)
    body = raw[pos + 8:pos + 8 + records_len]
    data = _decompress(compression, body, size, offset)
    if validate_crc and crc and zlib.crc32(data) != crc:
        raise FormatError(f"byte {offset}: chunk CRC mismatch")
    out: list[RawMessage] = []
    pos, end = 0, len(data)
    head, msg_head = _RECORD_HEAD.unpack_from, _MESSAGE_HEAD.unpack_from
    while pos < end:
        op, rlen = head(data, pos)
        pos += 9
        if op == OP_MESSAGE:
            channel, _, log_time, publish_time = msg_head(data, pos)
            if (channels is None or channel in channels) and (start_ns is None or log_time >= start_ns) \
                    and (end_ns is None or log_time < end_ns):
                out.append((log_time, publish_time, channel, data[pos + 22:pos + rlen]))
        pos += rlen
    out.sort(key=_log_time)
    return out


def _log_time(m: RawMessage) -> int:
    return m[0]


def _decompress(compression: str, body: bytes, size: int, offset: int) -> bytes:
    if compression == "zstd":
        return zstandard.ZstdDecompressor().decompress(body, max_output_size=size)
    if compression == "":
        return body
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.decompress(body)
    raise FormatError(f"byte {offset}: unsupported chunk compression {compression!r}")


def ordered_messages(f: BinaryIO, chunk_indexes: Iterable, channels: set[int] | None, validate_crc: bool,
                     start_ns: int | None = None, end_ns: int | None = None) -> Iterator[RawMessage]:
    """Messages of every matching chunk in log-time order; a chunk is read only when its time comes.

    Memory holds the chunks whose time spans overlap the current instant,
    never the whole file.
    """
    todo = sorted(
        (ci for ci in chunk_indexes
         if (channels is None or channels & ci.message_index_offsets.keys() or not ci.message_index_offsets)
         and (start_ns is None or ci.message_end_time >= start_ns)
         and (end_ns is None or ci.message_start_time < end_ns)),
        key=lambda ci: (ci.message_start_time, ci.chunk_start_offset))
    # (log time, chunk offset, index in chunk): ties break by file position, as mcap's reader does
    heap: list[tuple[int, int, int, RawMessage, list[RawMessage]]] = []
    nxt = 0
    while heap or nxt < len(todo):
        while nxt < len(todo) and (not heap or todo[nxt].message_start_time <= heap[0][0]):
            ci = todo[nxt]
            msgs = chunk_messages(f, ci.chunk_start_offset, ci.chunk_length, channels, validate_crc,
                                  start_ns, end_ns)
            if msgs:
                heapq.heappush(heap, (msgs[0][0], ci.chunk_start_offset, 0, msgs[0], msgs))
            nxt += 1
        if not heap:
            continue
        _, order, i, msg, msgs = heap[0]
        yield msg
        if i + 1 < len(msgs):
            heapq.heapreplace(heap, (msgs[i + 1][0], order, i + 1, msgs[i + 1], msgs))
        else:
            heapq.heappop(heap)
