"""Protobuf messages of one type decoded straight into numpy columns, many at a time.

Decoding message by message (the protobuf runtime's `FromString`) and reading
each field costs a few microseconds per message, which is most of a replay's
reading of INS and DVL samples. Here every message of a block is walked at
once: one numpy step per field position reads the tags, skips what is not
wanted and gathers the wanted doubles and varints (wire format: the protobuf
encoding guide, protobuf.dev/programming-guides/encoding).

The fast walk only vouches for what it fully understands: fields of the
message's own descriptor with their usual wire type, strings that are ASCII,
`google.protobuf.Timestamp` sub-messages of two varints, packed doubles.
Any other message (an unknown field, a non-ASCII string that must be checked
as UTF-8, a varint of ten bytes, bytes past the end) is marked and decoded by
`FromString` instead, so the columns are always what the runtime gives, and a
message it refuses stays refused. So is a message of more than `MAX_STEPS`
fields: a crafted one of a million tiny fields costs the runtime, not a
million numpy steps.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np

# what the walk accepts of a field
_DOUBLE, _VARINT, _STRING, _BYTES, _TIMESTAMP, _PACKED_DOUBLES = 1, 2, 3, 4, 5, 6
_WIRE = {_DOUBLE: 1, _VARINT: 0, _STRING: 2, _BYTES: 2, _TIMESTAMP: 2, _PACKED_DOUBLES: 2}
# descriptor field types (google.protobuf.descriptor.FieldDescriptor.TYPE_*)
_T_DOUBLE, _T_INT64, _T_UINT64, _T_INT32, _T_BOOL, _T_STRING, _T_MESSAGE, _T_BYTES, _T_UINT32, _T_ENUM = \
    1, 3, 4, 5, 8, 9, 11, 12, 13, 14
_VARINT_TYPES = (_T_INT64, _T_UINT64, _T_INT32, _T_BOOL, _T_UINT32, _T_ENUM)


@lru_cache(maxsize=32)
def _plan(cls: Any) -> tuple[np.ndarray, dict[str, tuple[int, int]]]:
    """(field number -> what the walk accepts, 0 for nothing) and name -> (number, descriptor type)."""
    d = cls.DESCRIPTOR
    top = max((f.number for f in d.fields), default=0)
    table = np.zeros(top + 2, dtype=np.int8)
    names: dict[str, tuple[int, int]] = {}
    for f in d.fields:
        repeated = getattr(f, "is_repeated", None)
        repeated = repeated if repeated is not None else f.label == 3
        kind = 0
        if repeated:
            kind = _PACKED_DOUBLES if f.type == _T_DOUBLE else 0
        elif f.type == _T_DOUBLE:
            kind = _DOUBLE
        elif f.type in _VARINT_TYPES:
            kind = _VARINT
        elif f.type == _T_STRING:
            kind = _STRING
        elif f.type == _T_BYTES:
            kind = _BYTES
        elif f.type == _T_MESSAGE and f.message_type.full_name == "google.protobuf.Timestamp":
            kind = _TIMESTAMP
        table[f.number] = kind
        names[f.name] = (f.number, f.type)
    return table, names


MAX_STEPS = 64     # fields walked per message at most (ours have up to 25); the runtime decodes longer ones
_TIMESTAMP_TABLE = np.array([0, _VARINT, _VARINT], dtype=np.int8)


PAD = 16          # bytes a buffer holds after its last message: a walk step reads up to 10 bytes past a position
_SHORT = 64       # strings up to this long are checked for ASCII 8 bytes a word, longer ones by a prefix count
# the high bit of each of the first k bytes of a little-endian 8-byte word, k = 0..8
_HIGH_BITS = np.array([sum(0x80 << (8 * i) for i in range(k)) for k in range(9)], dtype=np.uint64)


class _Bytes:
    """A buffer of messages as numpy sees it: bytes, doubles at every byte offset, and ASCII checks of ranges."""

    def __init__(self, data: bytes):
        self.u8 = np.frombuffer(data, dtype=np.uint8)
        # a little-endian double starting at every byte (stride 1): one gather reads a field of every message
        self.f8 = np.ndarray(shape=(max(len(data) - 7, 0),), dtype="<f8", buffer=data, strides=(1,))
        self.u64 = np.ndarray(shape=(max(len(data) - 7, 0),), dtype="<u8", buffer=data, strides=(1,))
        self._high: np.ndarray | None = None

    def ascii(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Per range [a, b): True when no byte is >= 0x80 (b clipped to the buffer, a range past it is empty)."""
        size = self.u8.size
        b = np.minimum(b, size)
        a = np.minimum(a, b)
        width = int((b - a).max()) if a.size else 0
        if width <= _SHORT:
            # 8 bytes at a time: the high bits of the range's bytes in each little-endian word
            length = b - a
            high = np.zeros(a.size, dtype=np.uint64)
            for k in range(0, width, 8):
                at = np.minimum(a + k, self.u64.size - 1)
                high |= self.u64[at] & _HIGH_BITS[np.clip(length - k, 0, 8)]
            return high == 0
        if self._high is None:     # high[b] - high[a]: the bytes >= 0x80 in [a, b), counted once per buffer
            self._high = np.concatenate(([0], np.cumsum(self.u8 >= 0x80)))
        return self._high[b] == self._high[a]


def _varint(buf: np.ndarray, q: np.ndarray, lim: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(value, position after it, ok) of the varints at positions q (ok: at most 9 bytes, none past lim)."""
    val = np.zeros(q.size, dtype=np.uint64)
    end = q.copy()
    done = np.zeros(q.size, dtype=bool)
    for i in range(9):      # 9 bytes hold 63 bits: a longer varint goes to the runtime (its overflow rules)
        b = buf[end]
        live = ~done
        val |= np.where(live, (b & 0x7F).astype(np.uint64) << np.uint64(7 * i), np.uint64(0))
        end = np.where(live, end + 1, end)
        done |= live & (b < 0x80)
        if done.all():
            break
    return val, end, done & (end <= lim)


def _walk(view: _Bytes, start: np.ndarray, end: np.ndarray, table: np.ndarray,
          wanted: dict[int, tuple[np.ndarray, int]]) -> np.ndarray:
    """Walk messages [start, end) of the buffer; fill wanted[number] = (column, type) in place; the ok mask."""
    buf = view.u8
    n = start.size
    ok = np.ones(n, dtype=bool)
    live = np.flatnonzero(start < end)
    p, lim = start[live], end[live]      # the live messages' positions and ends
    nested: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    steps = 0
    while live.size:
        steps += 1
        if steps > MAX_STEPS:
            ok[live] = False       # a message of very many fields: the runtime's, one numpy step per field is not
            break
        first = buf[p]
        if first[0] < 0x80 and (first == first[0]).all():
            # the usual step: every message has the same one-byte tag here (the same fields in the same order)
            after = _uniform_step(view, p, lim, int(first[0]), table, wanted, live, nested)
            if after is None:
                ok[live] = False
                break
            good = after <= lim
            more = good & (after < lim)
            if more.all():       # no message ends or fails here: the live set stays as it is
                p = after
                continue
            ok[live[~good]] = False
            live, p, lim = live[more], after[more], lim[more]
            continue
        tag, q, good = _varint(buf, p, lim)
        number = (tag >> np.uint64(3)).astype(np.int64)
        wire = (tag & np.uint64(7)).astype(np.int64)
        inside = number < table.size
        kind = np.where(inside, table[np.where(inside, number, 0)], 0)
        # the wire type each kind has (kind 0, a field the walk does not know, never matches)
        expect = np.array([-1, 1, 0, 2, 2, 2, 2], dtype=np.int64)[kind]
        good &= wire == expect
        after = q.copy()
        value = np.zeros(q.size, dtype=np.uint64)
        v0 = good & (wire == 0)
        if v0.any():
            val, nxt, g = _varint(buf, q[v0], lim[v0])
            value[v0], after[v0] = val, nxt
            good[np.flatnonzero(v0)[~g]] = False
        w1 = good & (wire == 1)
        after[w1] = q[w1] + 8
        w2 = good & (wire == 2)
        body = q.copy()
        if w2.any():
            size, nxt, g = _varint(buf, q[w2], lim[w2])
            idx = np.flatnonzero(w2)
            fits = g & (size <= (lim[w2] - nxt).astype(np.uint64))
            body[idx] = nxt
            after[idx] = nxt + np.where(fits, size, 0).astype(np.int64)
            good[idx[~fits]] = False
        good &= after <= lim
        # strings must be ASCII here (UTF-8 is the runtime's to check); packed doubles whole
        s = good & (kind == _STRING)
        if s.any():
            good[s] &= view.ascii(body[s], after[s])
        pk = good & (kind == _PACKED_DOUBLES)
        if pk.any():
            good[pk] &= (after[pk] - body[pk]) % 8 == 0
        ts = good & (kind == _TIMESTAMP)
        if ts.any():
            nested.append((live[ts], body[ts], after[ts]))
        for num, (col, ftype) in wanted.items():
            hit = good & (number == num)
            if not hit.any():
                continue
            rows = live[hit]
            if ftype == _T_DOUBLE:
                col[rows] = view.f8[q[hit]]
            elif ftype == _T_BOOL:
                col[rows] = (value[hit] != 0).astype(float)
            elif ftype in (_T_INT32, _T_ENUM):
                col[rows] = (value[hit] & np.uint64(0xFFFFFFFF)).astype(np.uint32).view(np.int32).astype(float)
            else:
                col[rows] = value[hit].astype(float)
        ok[live[~good]] = False
        more = good & (after < lim)
        live, p, lim = live[more], after[more], lim[more]
    for rows, a, b in nested:
        sub = _walk(view, a, b, _TIMESTAMP_TABLE, {})
        ok[rows[~sub]] = False
    return ok


def _uniform_step(view: _Bytes, p: np.ndarray, lim: np.ndarray, tag: int, table: np.ndarray,
                  wanted: dict[int, tuple[np.ndarray, int]], live: np.ndarray,
                  nested: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> np.ndarray | None:
    """One field of every live message, all with the one-byte `tag` at p: the positions after it (past `lim`
    where a message is not ok), or None when the field is one the walk leaves to the runtime."""
    buf = view.u8
    number, wire = tag >> 3, tag & 7
    kind = int(table[number]) if 0 < number < table.size else 0
    if kind == 0 or wire != _WIRE[kind]:
        return None
    q = p + 1
    bad = np.zeros(p.size, dtype=bool)
    value = None
    if wire == 1:
        after = q + 8
    elif wire == 0:
        b = buf[q]
        if (b < 0x80).all():
            value, after = b.astype(np.uint64), q + 1
        else:
            value, after, g = _varint(buf, q, lim)
            bad |= ~g
    else:
        b = buf[q]
        if (b < 0x80).all():
            size, body = b.astype(np.int64), q + 1
        else:
            usize, body, g = _varint(buf, q, lim)
            bad |= ~g | (usize > (lim - np.minimum(body, lim)).astype(np.uint64))
            size = np.where(bad, 0, usize).astype(np.int64)
        after = body + size
        if kind == _STRING:
            bad |= ~view.ascii(body, after)
        elif kind == _PACKED_DOUBLES:
            bad |= size % 8 != 0
        elif kind == _TIMESTAMP:
            fine = ~bad & (after <= lim)
            nested.append((live[fine], body[fine], after[fine]))
    bad |= after > lim
    clean = not bad.any()
    if number in wanted:
        col, ftype = wanted[number]
        fine = slice(None) if clean else ~bad
        rows = live[fine]
        if ftype == _T_DOUBLE:
            col[rows] = view.f8[q[fine]]
        elif value is not None:
            v = value[fine]
            if ftype == _T_BOOL:
                col[rows] = (v != 0).astype(float)
            elif ftype in (_T_INT32, _T_ENUM):
                col[rows] = (v & np.uint64(0xFFFFFFFF)).astype(np.uint32).view(np.int32).astype(float)
            else:
                col[rows] = v.astype(float)
    return after if clean else np.where(bad, lim + 1, after)


def decode_columns(datas: Sequence[bytes], cls: Any, names: Sequence[str]) -> tuple[dict[str, np.ndarray],
                                                                                       np.ndarray]:
    """(name -> float64 column, ok) of serialized messages of `cls`: ok False where the runtime must decode.

    A column holds the field as the runtime reads it (a bool or enum as 0/1/its number); an absent field is
    its proto3 default. Rows not ok hold defaults: decode those with `cls.FromString`.
    """
    n = len(datas)
    lens = np.fromiter(map(len, datas), dtype=np.int64, count=n)
    start = np.zeros(n, dtype=np.int64)
    if n:
        np.cumsum(lens[:-1], out=start[1:])
    return decode_columns_at(b"".join(datas) + bytes(PAD), start, start + lens, cls, names)


def decode_columns_at(data: bytes, start: np.ndarray, end: np.ndarray, cls: Any, names: Sequence[str]
                      ) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """`decode_columns` of the messages data[start[i]:end[i]] of one buffer (a chunk's, many messages' at once),
    which holds at least PAD bytes after the last message: reads past a message's end stay inside it."""
    n = start.size
    table, fields = _plan(cls)
    cols = {name: np.zeros(n) for name in names}
    if not n:
        return cols, np.ones(0, dtype=bool)
    if len(data) < int(end.max()) + PAD:
        raise ValueError("decode_columns_at: the buffer needs PAD bytes after its last message")
    wanted = {fields[name][0]: (cols[name], fields[name][1]) for name in names}
    ok = _walk(_Bytes(data), start.astype(np.int64, copy=False), end.astype(np.int64, copy=False), table, wanted)
    return cols, ok
