"""The archive's message classes by schema name, and time conversions for their timestamps."""

from __future__ import annotations

import struct
from typing import Any

from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from foxglove_schemas_protobuf.Log_pb2 import Log
from google.protobuf.timestamp_pb2 import Timestamp

from . import auvreplay_pb2 as pb

NS = 1_000_000_000

GnssStatus = pb.GnssStatus
InsState = pb.InsState
DvlVelocity = pb.DvlVelocity
AcousticRange = pb.AcousticRange
UsblObservation = pb.UsblObservation
Detection = pb.Detection
BellMembership = pb.BellMembership
AnfisSnapshot = pb.AnfisSnapshot

MESSAGE_CLASSES: dict[str, Any] = {
    cls.DESCRIPTOR.full_name: cls
    for cls in (
        LocationFix, Log, GnssStatus, InsState, DvlVelocity, AcousticRange,
        UsblObservation, Detection, AnfisSnapshot,
    )
}

# foxglove.LocationFix.position_covariance_type values
COVARIANCE_UNKNOWN = 0
COVARIANCE_APPROXIMATED = 1
COVARIANCE_DIAGONAL_KNOWN = 2
COVARIANCE_KNOWN = 3


def timestamp(ns: int) -> Timestamp:
    """A protobuf Timestamp for integer nanoseconds since the Unix epoch."""
    sec, nsec = divmod(int(ns), NS)
    return Timestamp(seconds=sec, nanos=nsec)


def to_ns(ts: Timestamp) -> int:
    """Integer nanoseconds since the Unix epoch of a protobuf Timestamp."""
    return ts.seconds * NS + ts.nanos


# latitude, longitude, altitude, position_covariance (packed, 9 doubles), position_covariance_type:
# foxglove.LocationFix's numeric fields as protobuf wire bytes, tags (field << 3 | wire type) included
_FIX_NUMBERS = struct.Struct("<BdBdBdBB9dBB")
_NAN9 = (float("nan"),) * 9


def location_fix(
    t_ns: int,
    frame_id: str,
    latitude: float,
    longitude: float,
    altitude: float = float("nan"),
    covariance_enu_m2: tuple[float, ...] | None = None,
    covariance_type: int = COVARIANCE_UNKNOWN,
) -> LocationFix:
    """A foxglove.LocationFix; covariance is the 9-element ENU matrix in m² (row-major)."""
    if covariance_enu_m2 is None:
        covariance_enu_m2, covariance_type = _NAN9, COVARIANCE_UNKNOWN
    if len(covariance_enu_m2) == 9 and 0 <= covariance_type < 128:
        # One parse of packed wire bytes: upb sets a repeated double ~0.1 us per element
        # through extend() or a constructor keyword, and a nested Timestamp keyword costs
        # a copy; this way the fix costs about half (bench/bench_nmea.py).
        fix = LocationFix.FromString(_FIX_NUMBERS.pack(
            0x09, latitude, 0x11, longitude, 0x19, altitude, 0x22, 72, *covariance_enu_m2, 0x28, covariance_type))
    else:
        fix = LocationFix(latitude=latitude, longitude=longitude, altitude=altitude,
                          position_covariance=covariance_enu_m2, position_covariance_type=covariance_type)
    fix.frame_id = frame_id
    ts = fix.timestamp
    ts.seconds, ts.nanos = divmod(int(t_ns), NS)
    return fix
