"""The archive's message classes by schema name, and time conversions for their timestamps."""

from __future__ import annotations

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
    fix = LocationFix(
        timestamp=timestamp(t_ns), frame_id=frame_id,
        latitude=latitude, longitude=longitude, altitude=altitude,
    )
    if covariance_enu_m2 is not None:
        fix.position_covariance.extend(covariance_enu_m2)
        fix.position_covariance_type = covariance_type
    else:
        fix.position_covariance.extend([float("nan")] * 9)
    return fix
