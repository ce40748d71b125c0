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
RawBytes = pb.RawBytes

MESSAGE_CLASSES: dict[str, Any] = {
    cls.DESCRIPTOR.full_name: cls
    for cls in (
        LocationFix, Log, GnssStatus, InsState, DvlVelocity, AcousticRange,
        UsblObservation, Detection, AnfisSnapshot, RawBytes,
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


# auvreplay.InsState's doubles as wire bytes: fields 3..14 (one-byte tags), then 17..19 (two-byte tags)
_INS_NUMBERS = struct.Struct("<" + "Bd" * 12 + "BBd" * 3)
_INS_TAGS_LOW = tuple((n << 3) | 1 for n in range(3, 15))


def ins_state(
    t_ns: int, frame_id: str, source_format: str, status: str,
    latitude: float, longitude: float, depth_m: float, roll_deg: float, pitch_deg: float, heading_deg: float,
    velocity_north_mps: float, velocity_east_mps: float, velocity_down_mps: float,
    heading_std_deg: float, position_std_north_m: float, position_std_east_m: float,
    roll_std_deg: float, pitch_std_deg: float, altitude_m: float,
) -> InsState:
    """An auvreplay.InsState from every field (NaN where absent), built from packed wire bytes."""
    # one parse of packed doubles costs a third of fifteen keyword arguments (see location_fix)
    t = _INS_TAGS_LOW
    msg = InsState.FromString(_INS_NUMBERS.pack(
        t[0], latitude, t[1], longitude, t[2], depth_m, t[3], roll_deg, t[4], pitch_deg, t[5], heading_deg,
        t[6], velocity_north_mps, t[7], velocity_east_mps, t[8], velocity_down_mps, t[9], heading_std_deg,
        t[10], position_std_north_m, t[11], position_std_east_m,
        0x89, 0x01, roll_std_deg, 0x91, 0x01, pitch_std_deg, 0x99, 0x01, altitude_m))
    msg.frame_id = frame_id
    msg.status = status
    msg.source_format = source_format
    ts = msg.timestamp
    ts.seconds, ts.nanos = divmod(int(t_ns), NS)
    return msg


_GNSS_NUMBERS = struct.Struct("<BdBdBdBd")  # auvreplay.GnssStatus doubles: hdop (5), speed, course, heading (7..9)


def gnss_status(
    t_ns: int, frame_id: str, fix_quality: int, satellites: int, hdop: float, source_format: str,
    speed_mps: float, course_deg: float, heading_deg: float,
) -> GnssStatus:
    """An auvreplay.GnssStatus, its doubles parsed from packed wire bytes (as `ins_state`)."""
    msg = GnssStatus.FromString(_GNSS_NUMBERS.pack(0x29, hdop, 0x39, speed_mps, 0x41, course_deg, 0x49, heading_deg))
    msg.frame_id = frame_id
    msg.fix_quality = fix_quality
    msg.satellites = satellites
    msg.source_format = source_format
    ts = msg.timestamp
    ts.seconds, ts.nanos = divmod(int(t_ns), NS)
    return msg
