"""Protobuf wire bytes of archive messages built directly, for writers that never need the message object.

`location_fix_bytes` gives exactly what `schemas.location_fix(...).SerializeToString()`
gives (field order, proto3 default-skipping, -0.0 and NaN kept), at a third of
the cost: the replay writes a foxglove.LocationFix per method and estimate.
"""

from __future__ import annotations

import struct

NS = 1_000_000_000
_DOUBLE = struct.Struct("<d")
_COVARIANCE = struct.Struct("<BB9d")
_ZERO = bytes(8)
_TAG_LATITUDE, _TAG_LONGITUDE, _TAG_ALTITUDE = b"\x09", b"\x11", b"\x19"   # fields 1-3, 64-bit


def varint(value: int) -> bytes:
    """Base-128 varint of an int64/uint64 (negative numbers as their 64-bit two's complement)."""
    if value < 0:
        value += 1 << 64
    out = bytearray()
    while value > 0x7F:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def _double(tag: bytes, value: float) -> bytes:
    """A double field, or nothing for +0.0 (proto3 skips a default; -0.0 and NaN are written)."""
    raw = _DOUBLE.pack(value)
    return b"" if raw == _ZERO else tag + raw


def timestamp_bytes(t_ns: int) -> bytes:
    """google.protobuf.Timestamp as the payload of its field (seconds 1, nanos 2)."""
    seconds, nanos = divmod(int(t_ns), NS)
    return (b"\x08" + varint(seconds) if seconds else b"") + (b"\x10" + varint(nanos) if nanos else b"")


def location_fix_bytes(
    t_ns: int, frame_id: str, latitude: float, longitude: float, altitude: float,
    covariance_enu_m2: tuple[float, ...], covariance_type: int,
) -> bytes:
    """A serialized foxglove.LocationFix with a 9-element covariance (fields 1-7 of its schema)."""
    stamp = timestamp_bytes(t_ns)
    name = frame_id.encode()
    return b"".join((
        _double(_TAG_LATITUDE, latitude), _double(_TAG_LONGITUDE, longitude), _double(_TAG_ALTITUDE, altitude),
        _COVARIANCE.pack(0x22, 72, *covariance_enu_m2),
        b"\x28" + varint(covariance_type) if covariance_type else b"",
        b"\x32" + varint(len(stamp)) + stamp,
        b"\x3a" + varint(len(name)) + name if name else b"",
    ))
