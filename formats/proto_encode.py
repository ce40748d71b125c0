"""Protobuf messages of one type encoded from numpy columns, many at a time: the reverse of `formats.proto_columns`.

Building a protobuf object per archive message, then serializing it, costs a
few microseconds a message on the recording hot path. Here a block of
messages is encoded at once: per field one numpy step makes its bytes for
every message (tag, then the value), and one boolean mask cuts the rows'
fields together into one blob, message after message.

The bytes are those of upb's ``SerializeToString`` of the same message
(tests/test_proto_encode.py checks with hypothesis): fields in field-number
order; a proto3 scalar equal to its default is left out, a double only when
its bits are zero (so -0.0 is written, NaN too); a negative int32 or int64 is
a ten-byte varint; a string as UTF-8 after its length, left out when empty; a
packed repeated double as one length-delimited run, left out when empty; a
`google.protobuf.Timestamp` is present where the time is archivable
(`formats.units.archivable_ns`, as `formats.schemas.set_timestamp` sets it),
its seconds and nanos left out when zero; a double with explicit presence (proto3
``optional``) is written wherever it is set, even at 0, and left out only where a
masked column (`numpy.ma`) masks it. Tags are read from the message's
descriptor, never written by hand. Fields not given stay unset.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

from .units import NS, TIME_MAX_NS, TIME_MIN_NS
from .wire import varint

# descriptor field types (google.protobuf.descriptor.FieldDescriptor.TYPE_*)
_T_DOUBLE, _T_INT64, _T_INT32, _T_BOOL, _T_STRING, _T_MESSAGE, _T_ENUM = 1, 3, 5, 8, 9, 11, 14
_T_OPTIONAL_DOUBLE = -2  # ours: a double with explicit presence (proto3 `optional`)
_INTS = (_T_INT64, _T_INT32, _T_ENUM)  # varints of a signed value: a negative one takes ten bytes
_SHIFTS = np.arange(0, 70, 7, dtype=np.uint64)  # the ten 7-bit groups of a 64-bit varint

Segment = tuple[np.ndarray, np.ndarray]  # (uint8 matrix: a row's bytes left-aligned, byte count per row)


@lru_cache(maxsize=32)
def _fields(cls: Any) -> tuple[tuple[str, int, int, bool, bytes], ...]:
    """Per field, in number order: (name, number, descriptor type, repeated, tag bytes by wire type); a double
    with explicit presence (proto3 `optional`: written when set, even at 0) has type _T_OPTIONAL_DOUBLE, any other
    such scalar type -1, not encoded."""
    out = []
    for f in sorted(cls.DESCRIPTOR.fields, key=lambda f: f.number):
        repeated = getattr(f, "is_repeated", None)
        repeated = repeated if repeated is not None else f.label == 3
        if not repeated and f.type != _T_MESSAGE and f.has_presence:
            if f.type == _T_DOUBLE:
                out.append((f.name, f.number, _T_OPTIONAL_DOUBLE, False, varint(f.number << 3 | 1)))
            else:
                out.append((f.name, f.number, -1, False, b""))
            continue
        if f.type == _T_DOUBLE and not repeated:
            wire = 1
        elif f.type in (*_INTS, _T_BOOL) and not repeated:
            wire = 0
        else:
            wire = 2  # strings, sub-messages, packed repeated doubles
        out.append((f.name, f.number, f.type, bool(repeated), varint(f.number << 3 | wire)))
    return tuple(out)


def varints(values: np.ndarray) -> Segment:
    """Base-128 varints of uint64 values (a negative int64 as its two's complement: ten bytes)."""
    v = np.asarray(values).astype(np.uint64, copy=False)[:, None]
    groups = (v >> _SHIFTS) & np.uint64(0x7F)
    higher = (v >> _SHIFTS) > np.uint64(0x7F)  # another group follows this one
    lens = 1 + higher.sum(axis=1, dtype=np.int64)
    return (groups | np.where(higher, np.uint64(0x80), np.uint64(0))).astype(np.uint8), lens


def _strings(n: int, tag: bytes, values: Sequence[str]) -> Segment:
    """Tag, length and UTF-8 bytes per row; nothing for an empty string. One encoding per distinct value."""
    # the distinct values in order of first use (a dict keeps it), each row's number among them: C loops only
    codes = {s: k for k, s in enumerate(dict.fromkeys(values))}
    index = np.fromiter(map(codes.__getitem__, values), dtype=np.int64, count=n)
    pieces = []
    for s in codes:
        text = s.encode("utf-8")
        pieces.append(tag + varint(len(text)) + text if text else b"")
    width = max(map(len, pieces), default=0)
    table = np.zeros((len(pieces), width), dtype=np.uint8)
    for i, piece in enumerate(pieces):
        table[i, : len(piece)] = np.frombuffer(piece, dtype=np.uint8)
    lens = np.array([len(p) for p in pieces], dtype=np.int64)
    return table[index], lens[index]


def _tagged(n: int, tag: bytes, width: int) -> np.ndarray:
    """An (n, len(tag) + width) byte matrix with the tag in every row's first bytes, the rest to fill."""
    out = np.empty((n, len(tag) + width), dtype=np.uint8)
    out[:, :len(tag)] = np.frombuffer(tag, dtype=np.uint8)
    return out


def _doubles(n: int, tag: bytes, values: Any) -> Segment:
    """Tag and 8 little-endian bytes per row; nothing where the bits are zero (0.0, not -0.0)."""
    v = np.ascontiguousarray(values, dtype="<f8")
    if v.shape != (n,):
        v = np.ascontiguousarray(np.broadcast_to(v, (n,)))
    out = _tagged(n, tag, 8)
    out[:, len(tag):] = v.view(np.uint8).reshape(n, 8)
    return out, (v.view(np.uint64) != 0) * (len(tag) + 8)


def _optional_doubles(n: int, tag: bytes, values: Any) -> Segment:
    """Tag and 8 little-endian bytes per row where the value is set (every row, but those a masked array masks),
    zero included: explicit presence."""
    mask = np.ma.getmaskarray(values)
    v = np.ascontiguousarray(np.ma.getdata(values), dtype="<f8")
    if v.shape != (n,):
        v = np.ascontiguousarray(np.broadcast_to(v, (n,)))
    out = _tagged(n, tag, 8)
    out[:, len(tag):] = v.view(np.uint8).reshape(n, 8)
    if not mask.any():
        return out, np.full(n, len(tag) + 8, dtype=np.int64)
    return out, np.where(np.broadcast_to(mask, (n,)), 0, len(tag) + 8)


def _ints(n: int, tag: bytes, values: Any) -> Segment:
    """Tag and varint per row; nothing where the value is 0."""
    v = np.broadcast_to(np.asarray(values, dtype=np.int64), (n,))
    mat, lens = varints(v)
    out = _tagged(n, tag, mat.shape[1])
    out[:, len(tag):] = mat
    return out, np.where(v != 0, len(tag) + lens, 0)


def _packed(n: int, tag: bytes, values: Any) -> Segment:
    """A packed repeated double: tag, byte length and the values per row (an (n, k) array); nothing when k = 0."""
    v = np.ascontiguousarray(np.asarray(values, dtype="<f8").reshape(n, -1))
    k = v.shape[1]
    if not k:
        return np.zeros((n, 0), dtype=np.uint8), np.zeros(n, dtype=np.int64)
    head = tag + varint(8 * k)
    out = _tagged(n, head, 8 * k)
    out[:, len(head):] = v.view(np.uint8).reshape(n, 8 * k)
    return out, np.full(n, len(head) + 8 * k)


def _timestamps(n: int, tag: bytes, values: Any) -> Segment:
    """A Timestamp sub-message of integer ns per row, where archivable; seconds and nanos left out when 0."""
    t = np.broadcast_to(np.asarray(values, dtype=np.int64), (n,))
    present = (t >= TIME_MIN_NS) & (t < TIME_MAX_NS)
    sec, nanos = np.divmod(np.where(present, t, 0), NS)
    (sec_mat, sec_lens), nanos_part = _ints(n, b"\x08", sec), _ints(n, b"\x10", nanos)
    size = sec_lens + nanos_part[1]  # at most 6 + 5 bytes: the length is one varint byte
    head = _tagged(n, tag, 1 + sec_mat.shape[1])   # tag, length, then the seconds: left-aligned as they are
    head[:, len(tag)] = size
    head[:, len(tag) + 1:] = sec_mat
    return _join([(head, len(tag) + 1 + sec_lens), nanos_part], present)


def _join(segments: list[Segment], present: np.ndarray | None = None) -> Segment:
    """Segments side by side, each row's bytes packed to the left; a row is empty where `present` is False."""
    n = len(segments[0][1])
    lens = [np.asarray(seg[1], dtype=np.int64) for seg in segments]
    if present is not None:
        lens = [np.where(present, seg_lens, 0) for seg_lens in lens]
    total = np.sum(lens, axis=0) if lens else np.zeros(n, dtype=np.int64)
    width = int(total.max()) if n else 0
    out = np.zeros((n, width), dtype=np.uint8)
    keep = np.concatenate([np.arange(seg[0].shape[1])[None, :] < seg_lens[:, None]
                           for seg, seg_lens in zip(segments, lens)], axis=1)
    out[np.arange(width)[None, :] < total[:, None]] = np.concatenate([seg[0] for seg in segments], axis=1)[keep]
    return out, total


def _join_flat(segments: list[Segment]) -> tuple[np.ndarray, np.ndarray]:
    """`flatten(*_join(segments))` as a uint8 array, and each row's length: the kept bytes of the segments side by
    side, taken row after row at once (no padded matrix between)."""
    lens = [np.asarray(seg[1], dtype=np.int64) for seg in segments]
    keep = np.concatenate([np.arange(seg[0].shape[1])[None, :] < seg_lens[:, None]
                           for seg, seg_lens in zip(segments, lens)], axis=1)
    return np.concatenate([seg[0] for seg in segments], axis=1)[keep], np.sum(lens, axis=0)


def encode_rows(cls: Any, n: int, columns: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """`n` messages of `cls` from columns as rows: an (n, width) byte matrix, each message's bytes at the left of
    its row, and each message's length.

    `columns` maps field names to a value per row (a numpy array or sequence of
    length n) or one value for every row: doubles, ints and bools; str or str
    sequences; int ns for a Timestamp; an (n, k) array for a packed repeated
    double; for a double with explicit presence, a masked array (`numpy.ma`) leaves it unset where masked.
    Fields not named stay unset. Raises TypeError for a field this
    encoder does not write (another sub-message, bytes, a repeated non-double).
    """
    segments = _segments(cls, n, columns)
    if segments is None:  # no rows: nothing to encode (an empty (0, k) column has no row length to reshape by)
        return np.zeros((0, 0), dtype=np.uint8), np.zeros(0, dtype=np.int64)
    if not segments:
        return np.zeros((n, 0), dtype=np.uint8), np.zeros(n, dtype=np.int64)
    return segments[0] if len(segments) == 1 else _join(segments)


def encode_flat(cls: Any, n: int, columns: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """`n` messages of `cls` from `encode_rows`' columns: their bytes one after the other (a uint8 array) and each
    one's length; `flatten` of `encode_rows`, without its padded rows."""
    segments = _segments(cls, n, columns)
    if not segments:
        return np.zeros(0, dtype=np.uint8), np.zeros(n, dtype=np.int64)
    return _join_flat(segments)


def _segments(cls: Any, n: int, columns: Mapping[str, Any]) -> list[Segment] | None:
    """Each given field's segment in field-number order, runs of fields every row writes whole merged into one;
    None without rows."""
    if not n:
        return None
    # runs of fields every row writes whole (one value for all rows, a double never zero...) are put side by side
    # at once; only the fields whose length differs between rows go through `_join`'s mask
    segments: list[Segment] = []
    whole: list[np.ndarray] = []   # the current run of whole fields' matrices
    const = b""                    # the bytes of the run's latest fields of one value for every row
    for name, _number, kind, repeated, tag in _fields(cls):
        if name not in columns:
            continue
        values = columns[name]
        if repeated:
            if kind != _T_DOUBLE:
                raise TypeError(f"{cls.DESCRIPTOR.full_name}.{name}: only packed repeated doubles are encoded")
            seg: Segment | bytes | None = _packed(n, tag, values)
        elif type(values) in _SCALARS and kind in _SCALAR_KINDS:
            seg = _scalar(kind, tag, values)
        elif kind == _T_DOUBLE:
            seg = _doubles(n, tag, values)
        elif kind == _T_OPTIONAL_DOUBLE:
            seg = _optional_doubles(n, tag, values)
        elif kind in _INTS or kind == _T_BOOL:
            seg = _ints(n, tag, values)
        elif kind == _T_STRING:
            seg = _strings(n, tag, values)
        elif kind == _T_MESSAGE and _is_timestamp(cls, name):
            seg = _timestamps(n, tag, values)
        else:
            raise TypeError(f"{cls.DESCRIPTOR.full_name}.{name}: type {kind} is not encoded from columns")
        if type(seg) is bytes:
            const += seg
            continue
        assert isinstance(seg, tuple)
        mat, lens = seg
        if const:
            whole.append(_row(n, const))
            const = b""
        high = lens.max()
        if not high:   # written in no row
            continue
        if high == mat.shape[1] == lens.min():
            whole.append(mat)
            continue
        if whole:   # a run of whole fields before this one: its fixed prefix
            prefix = _whole(n, whole)
            seg = np.concatenate([prefix[0], mat], axis=1), prefix[1] + lens
            whole = []
        segments.append(seg)
    if const:
        whole.append(_row(n, const))
    if whole:
        segments.append(_whole(n, whole))
    return segments


# scalars given as one value for every row, and the field kinds `_scalar` encodes from one
_SCALARS = frozenset({float, int, bool, str, np.float64, np.int64, np.int32, np.bool_})
_SCALAR_KINDS = frozenset({_T_DOUBLE, _T_OPTIONAL_DOUBLE, *_INTS, _T_BOOL, _T_STRING})
_F8 = struct.Struct("<d")
_U64_MASK = (1 << 64) - 1


def _scalar(kind: int, tag: bytes, value: Any) -> bytes:
    """The bytes of a field of one value for every row, as the column encoders give each row."""
    if kind == _T_STRING:
        if not isinstance(value, str):
            raise TypeError(f"a string field given {type(value).__name__}")
        text = value.encode("utf-8")
        return tag + varint(len(text)) + text if text else b""
    if kind == _T_DOUBLE or kind == _T_OPTIONAL_DOUBLE:
        if isinstance(value, str):
            raise TypeError("a double field given a string")
        bits = _F8.pack(float(value))
        return tag + bits if kind == _T_OPTIONAL_DOUBLE or bits != bytes(8) else b""
    v = int(np.int64(value))   # as the int64 column would hold it (a bool is 0 or 1)
    return tag + varint(v & _U64_MASK) if v else b""


def _row(n: int, data: bytes) -> np.ndarray:
    return np.broadcast_to(np.frombuffer(data, dtype=np.uint8), (n, len(data)))


def _whole(n: int, mats: list[np.ndarray]) -> Segment:
    """A run of whole segments side by side: one segment."""
    mat = mats[0] if len(mats) == 1 else np.concatenate(mats, axis=1)
    return mat, np.full(n, mat.shape[1], dtype=np.int64)


def encode_columns(cls: Any, n: int, columns: Mapping[str, Any]) -> tuple[bytes, np.ndarray]:
    """`n` messages of `cls` from columns: (their bytes one after the other, each one's end offset in them).

    The columns are those `encode_rows` takes.
    """
    blob, lens = encode_flat(cls, n, columns)
    return blob.tobytes(), np.cumsum(lens)


def flatten(rows: np.ndarray, lens: np.ndarray) -> bytes:
    """The first lens[i] bytes of each row of a byte matrix, one row after the other."""
    return rows[np.arange(rows.shape[1])[None, :] < lens[:, None]].tobytes()


def _is_timestamp(cls: Any, name: str) -> bool:
    return bool(cls.DESCRIPTOR.fields_by_name[name].message_type.full_name == "google.protobuf.Timestamp")


def split(blob: bytes, ends: np.ndarray) -> list[bytes]:
    """The messages of `encode_columns`' blob, each its own bytes."""
    out, start = [], 0
    for end in ends.tolist():
        out.append(blob[start:end])
        start = end
    return out
