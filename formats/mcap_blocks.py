"""Reading an archive as blocks of columns: the messages of a time window, decoded by topic, in log-time order.

`ArchiveReader.messages` hands out one decoded message object at a time,
merged across chunks by a heap. A consumer that computes on columns (the
replay engine's INS, DVL and GPS intake) wants instead, per window, each
topic's fields as numpy columns and the window's stream order as two arrays
(topic index and row within the topic). `read_blocks` gives that: the window
ends where the next chunk starts (every message before it is in hand, as in
the heap merge) once `BLOCK_MESSAGES` are in hand, so memory holds those and
the chunks that overlap in time. The
stream order is the heap merge's exactly: log time, then chunk position in
the file, then position in the chunk.

A topic asked for as columns has the fields of COLUMN_FIELDS (what a consumer
reads of every row) decoded straight from the wire into float64 columns
(formats.proto_columns, the runtime for any message the walk does not vouch
for); a row's message object is decoded only when asked (`message`). No
message is cut out of its chunk for that: a chunk's messages stay positions
in its inflated bytes, and a block's are one buffer (its chunks' spans joined)
the column walk reads in place. Any
other topic's messages are decoded objects. What does not decode is skipped and
counted as `messages` counts it.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from operator import attrgetter
from typing import Any, BinaryIO

import numpy as np

from .mcap_chunks import (
    _MESSAGE_HEAD,
    _RECORD_HEAD,
    MAX_CHUNK_BYTES,
    OP_MESSAGE,
    ChunkError,
    OnDamage,
    chunk_records,
    read_chunk,
)
from .proto_columns import PAD, decode_columns_at
from .schemas import MESSAGE_CLASSES

BLOCK_MESSAGES = 1 << 16     # messages in hand before a block is cut: numpy steps per block are amortized

# the fields a columnar consumer reads of each schema (float64 columns; booleans and enums as 0/1, ints)
COLUMN_FIELDS: dict[str, tuple[str, ...]] = {
    "auvreplay.InsState": ("latitude", "longitude", "depth_m", "heading_deg", "velocity_north_mps",
                           "velocity_east_mps"),
    "auvreplay.DvlVelocity": ("velocity_x_mps", "velocity_y_mps", "valid", "frame", "altitude_m"),
    "foxglove.LocationFix": ("latitude", "longitude"),
}


@dataclass
class MessageBlock:
    """The messages of one time window: stream order as arrays, each topic's rows as columns or objects."""

    topics: list[str]                        # topic index -> topic
    schemas: list[str]                       # topic index -> schema name
    topic_index: np.ndarray                  # per message in stream order: its topic index (int32)
    row: np.ndarray                          # per message in stream order: its row within its topic (int64)
    log_ns: np.ndarray                       # per message in stream order: log time (int64)
    columns: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)   # topic -> field -> column
    messages: dict[str, list[Any]] = field(default_factory=dict)    # topic -> decoded objects (not columnar)
    # columnar topic -> its rows' bytes: the block's buffer, each row's start and end in it
    raw: dict[str, tuple[bytes, np.ndarray, np.ndarray]] = field(default_factory=dict)
    decoders: dict[str, Callable[[bytes], Any]] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.log_ns.size)

    def message(self, topic: str, row: int) -> Any:
        """One row's decoded message (a columnar topic's is decoded now: most are never asked for)."""
        held = self.messages.get(topic)
        if held is not None:
            return held[row]
        data, start, end = self.raw[topic]
        return self.decoders[topic](data[int(start[row]):int(end[row])])


class _Run:
    """One chunk's (or the loose messages') wanted messages, sorted by log time, with a read position: log times,
    channel ids, and each message's bytes as (start, end) in the chunk's data."""

    __slots__ = ("order", "log", "cid", "data", "start", "end", "pos")

    def __init__(self, order: int, log: np.ndarray, cid: np.ndarray, data: bytes, start: np.ndarray,
                 end: np.ndarray):
        self.order, self.log, self.cid, self.data, self.start, self.end = order, log, cid, data, start, end
        self.pos = 0

    @classmethod
    def of_messages(cls, order: int, messages: Sequence[tuple[int, Any, int, bytes]]) -> _Run:
        """A run of (log time, _, channel id, data) messages sorted by log time, their bytes joined."""
        lens = np.fromiter((len(m[3]) for m in messages), dtype=np.int64, count=len(messages))
        start = np.zeros(lens.size, dtype=np.int64)
        np.cumsum(lens[:-1], out=start[1:])
        return cls(order, _times([m[0] for m in messages]), np.array([m[2] for m in messages], dtype=np.int64),
                   b"".join(m[3] for m in messages), start, start + lens)

    def first(self) -> int:
        """The log time of the next message not yet taken."""
        return int(self.log[self.pos])


def _compact(r: _Run) -> None:
    """Keep only the bytes and rows of `r` not yet taken, when they are under half of its chunk: a chunk whose
    last wanted message lies hours ahead (a slow topic's, or one that ends a topic and starts another) would
    otherwise hold its whole data that long, and a long mission holds more of them (docs/benchmarks.md)."""
    p = r.pos
    lo, hi = int(r.start[p:].min()), int(r.end[p:].max())
    if 2 * (hi - lo) >= len(r.data):
        return
    r.data = bytes(memoryview(r.data)[lo:hi])
    r.log, r.cid = r.log[p:].copy(), r.cid[p:].copy()
    r.start, r.end = r.start[p:] - lo, r.end[p:] - lo
    r.pos = 0


def _times(log: list[int]) -> np.ndarray:
    """Log times as int64 (a time past 2**63 - 1 raises OverflowError, as numpy does)."""
    return np.array(log, dtype=np.int64)


def _chunk_run(f: BinaryIO, ci: Any, channels: set[int], validate_crc: bool, start_ns: int | None,
               end_ns: int | None, file_size: int, on_damage: OnDamage | None, limit: int) -> _Run | None:
    """The wanted messages of one chunk as a sorted run (the loop of `mcap_chunks.chunk_messages`, as columns)."""
    offset = ci.chunk_start_offset
    _, _, data = read_chunk(f, offset, ci.chunk_length, file_size, validate_crc, limit)
    found = _indexed(f, ci, data, file_size)
    if found is not None:
        return _indexed_run(offset, data, *found, channels, start_ns, end_ns)
    records = chunk_records(data, offset, channels, start_ns, end_ns, on_damage)   # sorted by log time
    if not records:
        return None
    return _Run.of_messages(offset, records)


def _u64(data: bytes, at: np.ndarray) -> np.ndarray:
    """Little-endian u64 at each (unaligned) byte position of `data` (each position at most len(data) - 8)."""
    every = np.ndarray(shape=(max(len(data) - 7, 0),), dtype="<u8", buffer=data, strides=(1,))
    return every[at]


def _indexed(f: BinaryIO, ci: Any, data: bytes, file_size: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(offset, length) of every message record of a chunk from its message index records, or None.

    The index (records after the chunk in the file) is only believed when its records are exactly the
    chunk's message records: each an 0x05 record that fits, none overlapping, and what lies between
    them (walked here) records of other kinds that tile the chunk. Otherwise the caller walks the chunk.
    """
    offsets = ci.message_index_offsets
    size = ci.message_index_length
    # an index entry (16 bytes) per message record (31 bytes at least): never more than the chunk's own size
    if not offsets or size <= 0 or size > len(data) + (1 << 16):
        return None
    first = min(offsets.values())
    if first < 0 or first + size > file_size:
        return None
    f.seek(first)
    raw = f.read(size)
    parts: list[np.ndarray] = []
    pos = 0
    try:
        while pos < len(raw):
            op, rlen = _RECORD_HEAD.unpack_from(raw, pos)
            if op != 0x07 or rlen < 6 or pos + 9 + rlen > len(raw):
                return None
            (n,) = struct.unpack_from("<I", raw, pos + 11)
            if n % 16 or 6 + n > rlen:
                return None
            parts.append(np.frombuffer(raw, dtype="<u8", count=n // 8, offset=pos + 15)[1::2].astype(np.int64))
            pos += 9 + rlen
    except struct.error:
        return None
    at = np.sort(np.concatenate(parts)) if parts else np.empty(0, dtype=np.int64)
    end = len(data)
    if not at.size or at[0] < 0 or at[-1] + 31 > end or (at.size > 1 and not (np.diff(at) > 0).all()):
        return None
    buf = np.frombuffer(data, dtype=np.uint8)
    if not (buf[at] == OP_MESSAGE).all():
        return None
    rlen_all = _u64(data, at + 1)
    if (rlen_all < _MESSAGE_HEAD.size).any() or (rlen_all > end).any():
        return None
    nxt = at + 9 + rlen_all.astype(np.int64)
    if nxt[-1] > end or (nxt[:-1] > at[1:]).any():
        return None
    # the gaps: before the first, between, after the last; records of other kinds only
    starts = np.concatenate(([0], nxt))
    stops = np.concatenate((at, [end]))
    for a, b in zip(*(x[starts < stops].tolist() for x in (starts, stops))):
        while a < b:
            if a + 9 > b:
                return None
            op, rlen = _RECORD_HEAD.unpack_from(data, a)
            if op == OP_MESSAGE or rlen > b - a - 9:
                return None
            a += 9 + rlen
    return at, rlen_all.astype(np.int64)


def _indexed_run(offset: int, data: bytes, at: np.ndarray, rlen: np.ndarray, channels: set[int],
                 start_ns: int | None, end_ns: int | None) -> _Run | None:
    """The wanted messages of a chunk whose message records are known (`_indexed`), as a sorted run."""
    buf = np.frombuffer(data, dtype=np.uint8)
    channel = buf[at + 9].astype(np.int64) | (buf[at + 10].astype(np.int64) << 8)
    log = _u64(data, at + 15)
    keep = np.isin(channel, np.fromiter(channels, dtype=np.int64, count=len(channels)))
    if start_ns is not None:
        keep &= log >= np.uint64(start_ns)
    if end_ns is not None:
        keep &= log < np.uint64(end_ns)
    if not keep.any():
        return None
    at, rlen, channel, log = at[keep], rlen[keep], channel[keep], log[keep]
    if not (log[:-1] <= log[1:]).all():
        order = np.argsort(log, kind="stable")
        at, rlen, channel, log = at[order], rlen[order], channel[order], log[order]
    if (log >> np.uint64(63)).any():
        raise OverflowError("a message's log time does not fit int64")
    return _Run(offset, log.astype(np.int64), channel, data, at + 31, at + 9 + rlen)


def read_blocks(f: BinaryIO, chunk_indexes: Iterable[Any], info: Mapping[int, tuple[str, str, Any, str]],
                columnar: set[str], validate_crc: bool, start_ns: int | None = None, end_ns: int | None = None,
                on_damage: OnDamage | None = None, skip: Callable[[str, str], None] | None = None,
                limit: int = MAX_CHUNK_BYTES, loose: Sequence[tuple[int, int, int, bytes]] = (),
                decode_errors: tuple[type[BaseException], ...] = (ValueError,)) -> Iterator[MessageBlock]:
    """Blocks of the channels in `info` (channel id -> topic, schema, decode function or None, why not) in
    log-time order; topics in `columnar` whose schema has COLUMN_FIELDS come as columns. See the module doc."""
    f.seek(0, 2)
    file_size = f.tell()
    channels = set(info)
    todo = sorted(
        (ci for ci in chunk_indexes
         if (channels & ci.message_index_offsets.keys() or not ci.message_index_offsets)
         and (start_ns is None or ci.message_end_time >= start_ns)
         and (end_ns is None or ci.message_start_time < end_ns)),
        key=lambda ci: (ci.message_start_time, ci.chunk_start_offset))
    runs: list[_Run] = []
    if loose:
        runs.append(_Run.of_messages(-1, loose))
    held = 0        # messages read and not yet handed out
    for ci in todo:
        # a block is what comes before the next chunk's start, once enough is in hand (a few chunks)
        if held >= BLOCK_MESSAGES and ci.message_start_time > min(r.first() for r in runs):
            block = _take(runs, ci.message_start_time, info, columnar, skip, decode_errors)
            held = sum(r.log.size - r.pos for r in runs)
            if block is not None:
                yield block
        try:
            run = _chunk_run(f, ci, channels, validate_crc, start_ns, end_ns, file_size, on_damage, limit)
        except ChunkError as exc:
            if on_damage is None:
                raise
            on_damage(ci.chunk_start_offset, str(exc))
            continue
        if run is not None:
            runs.append(run)
            held += run.log.size
    if runs:
        block = _take(runs, None, info, columnar, skip, decode_errors)
        if block is not None:
            yield block


def _take(runs: list[_Run], before: int | None, info: Mapping[int, tuple[str, str, Any, str]],
          columnar: set[str], skip: Callable[[str, str], None] | None,
          decode_errors: tuple[type[BaseException], ...]) -> MessageBlock | None:
    """The messages of every run with log time before `before` (all with None) as one block; runs consumed."""
    logs: list[np.ndarray] = []
    orders: list[np.ndarray] = []
    cids: list[np.ndarray] = []
    starts: list[np.ndarray] = []
    ends: list[np.ndarray] = []
    parts: list[memoryview] = []
    base = 0        # where the next run's bytes go in the block's buffer
    for r in runs:
        j = r.log.size if before is None else r.pos + int(np.searchsorted(r.log[r.pos:], before, "left"))
        if j > r.pos:
            st, en = r.start[r.pos:j], r.end[r.pos:j]
            lo, hi = int(st.min()), int(en.max())
            parts.append(memoryview(r.data)[lo:hi])
            logs.append(r.log[r.pos:j])
            cids.append(r.cid[r.pos:j])
            starts.append(st + (base - lo))
            ends.append(en + (base - lo))
            orders.append(np.full(j - r.pos, r.order, dtype=np.int64))
            base += hi - lo
            r.pos = j
            if j < r.log.size:
                _compact(r)
    runs[:] = [r for r in runs if r.pos < r.log.size]
    if not logs:
        return None
    # one buffer of the block's messages (and what lies between them in a chunk), PAD bytes after the last
    parts.append(memoryview(bytes(PAD)))
    data = b"".join(parts)     # one copy
    log = np.concatenate(logs)
    start, end = np.concatenate(starts), np.concatenate(ends)
    if len(runs) == 0 and before is None and len(logs) == 1:
        order = np.arange(log.size)
    else:
        # the heap merge's order: log time, then the chunk's file offset, then position in it (already in place)
        order = np.lexsort((np.arange(log.size), np.concatenate(orders), log))
    cid_arr = np.concatenate(cids)[order]
    log = log[order]
    if not (order[:-1] < order[1:]).all():
        start, end = start[order], end[order]
    keep = np.ones(log.size, dtype=bool)
    topics: list[str] = []
    schemas: list[str] = []
    topic_index = np.empty(log.size, dtype=np.int32)
    out_cols: dict[str, dict[str, np.ndarray]] = {}
    out_msgs: dict[str, list[Any]] = {}
    out_raw: dict[str, tuple[bytes, np.ndarray, np.ndarray]] = {}
    out_dec: dict[str, Callable[[bytes], Any]] = {}
    topic_of: dict[str, int] = {}
    for cid in np.unique(cid_arr).tolist():
        topic, schema, decode, why = info[cid]
        where = np.flatnonzero(cid_arr == cid)
        if decode is None:
            if skip is not None:
                for _ in range(where.size):
                    skip(topic, why)
            keep[where] = False
            continue
        names = COLUMN_FIELDS.get(schema) if topic in columnar else None
        cls = MESSAGE_CLASSES.get(schema) if names is not None else None
        raw: tuple[np.ndarray, np.ndarray] | None = None
        cols: dict[str, np.ndarray] | None = None
        if cls is not None and names is not None and decode == cls.FromString:
            # columns straight from the wire; a row the walk does not vouch for is the runtime's to decode
            st, en = start[where], end[where]
            cols, ok = decode_columns_at(data, st, en, cls, names)
            if not ok.all():
                good = np.ones(st.size, dtype=bool)
                for x in np.flatnonzero(~ok).tolist():
                    try:
                        m = decode(data[int(st[x]):int(en[x])])
                    except decode_errors:
                        good[x] = False
                        keep[where[x]] = False
                        if skip is not None:
                            skip(topic, "that do not decode")
                        continue
                    for name in names:
                        cols[name][x] = float(getattr(m, name))
                if not good.all():
                    st, en = st[good], en[good]
                    cols = {k: v[good] for k, v in cols.items()}
                    where = where[good]
            raw = (st, en)
            decoded: list[Any] = []
        else:
            spans = list(zip(start[where].tolist(), end[where].tolist()))
            try:
                decoded = [decode(data[a:b]) for a, b in spans]
            except decode_errors:
                decoded, kept = [], []
                for i, (a, b) in zip(where.tolist(), spans):
                    try:
                        decoded.append(decode(data[a:b]))
                    except decode_errors:
                        keep[i] = False
                        if skip is not None:
                            skip(topic, "that do not decode")
                        continue
                    kept.append(i)
                where = np.array(kept, dtype=np.int64)
            if names is not None and decoded:
                cols = {name: np.fromiter(map(attrgetter(name), decoded), dtype=float, count=len(decoded))
                        for name in names}
        if not where.size:
            continue
        if topic in topic_of:      # two channels of one topic: one topic index
            ti = topic_of[topic]
        else:
            ti = topic_of[topic] = len(topics)
            topics.append(topic)
            schemas.append(schema)
        topic_index[where] = ti
        if raw is not None:
            prev_raw = out_raw.get(topic)
            out_raw[topic] = ((data, *raw) if prev_raw is None
                              else (data, np.concatenate((prev_raw[1], raw[0])), np.concatenate((prev_raw[2], raw[1]))))
            out_dec[topic] = decode
        else:
            out_msgs.setdefault(topic, []).extend(decoded)
        if cols is not None:
            prev = out_cols.get(topic)
            out_cols[topic] = cols if prev is None else {k: np.concatenate((prev[k], v)) for k, v in cols.items()}
    log, topic_index = log[keep], topic_index[keep]
    if not log.size:
        return None
    # rows: a topic of two channels had its rows concatenated by channel, so rows are given in that order
    row = np.empty(log.size, dtype=np.int64)
    for ti in range(len(topics)):
        where = np.flatnonzero(topic_index == ti)
        row[where] = np.arange(where.size)
    block = MessageBlock(topics, schemas, topic_index, row, log, out_cols, out_msgs, out_raw, out_dec)
    _fix_two_channel_rows(block, cid_arr[keep])
    return block


def _fix_two_channel_rows(block: MessageBlock, cid: np.ndarray) -> None:
    """Rows of a topic held by several channels follow the channels' concatenation order, not the stream's."""
    for ti in range(len(block.topics)):
        where = np.flatnonzero(block.topic_index == ti)
        ids = cid[where]
        if where.size < 2 or np.all(ids == ids[0]):
            continue
        # the decoded rows were concatenated channel by channel (ascending id): stream row k -> that position
        rank = np.argsort(np.argsort(ids, kind="stable"), kind="stable")
        block.row[where] = rank
