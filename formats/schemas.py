"""The archive's message classes by schema name, and time conversions for their timestamps."""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from foxglove_schemas_protobuf.Log_pb2 import Log
from google.protobuf.timestamp_pb2 import Timestamp

from . import auvreplay_pb2 as pb
from .units import NS, TIME_MAX_NS, TIME_MIN_NS
from .wire import DETECTION_EXTRA, DETECTION_SCORES, GNSS_STATUS, GNSS_VELOCITY, INS_STATE, LOCATION_FIX, varint

GnssStatus = pb.GnssStatus
InsState = pb.InsState
DvlVelocity = pb.DvlVelocity
AcousticRange = pb.AcousticRange
UsblObservation = pb.UsblObservation
Detection = pb.Detection
BellMembership = pb.BellMembership
AnfisSnapshot = pb.AnfisSnapshot
RawBytes = pb.RawBytes
GnssVelocity = pb.GnssVelocity

MESSAGE_CLASSES: dict[str, Any] = {
    cls.DESCRIPTOR.full_name: cls
    for cls in (
        LocationFix, Log, GnssStatus, InsState, DvlVelocity, AcousticRange,
        UsblObservation, Detection, AnfisSnapshot, RawBytes, GnssVelocity,
    )
}

# foxglove.LocationFix.position_covariance_type values, from the generated enum
COVARIANCE_UNKNOWN = LocationFix.UNKNOWN
COVARIANCE_APPROXIMATED = LocationFix.APPROXIMATED
COVARIANCE_DIAGONAL_KNOWN = LocationFix.DIAGONAL_KNOWN
COVARIANCE_KNOWN = LocationFix.KNOWN


def timestamp(ns: int) -> Timestamp | None:
    """A protobuf Timestamp for integer nanoseconds since the Unix epoch, None for no archivable time.

    None leaves a message constructor's Timestamp field unset, as `set_timestamp` does.
    """
    if not TIME_MIN_NS <= ns < TIME_MAX_NS:
        return None
    sec, nsec = divmod(int(ns), NS)
    return Timestamp(seconds=sec, nanos=nsec)


def set_timestamp(stamp: Timestamp, t_ns: int) -> None:
    """Set a message's Timestamp to `t_ns`, or leave it unset when `t_ns` is no archivable time.

    Every builder of an archive message sets its time here (or by `timestamp`),
    the fast (block, columnar) paths and their per-message references alike,
    so both agree on a time outside 1970-2200 (a corrupt RTC century, a
    400-digit field that no Timestamp holds): the field stays absent, and the
    record-time checks refuse the message by its log time. The test is
    `formats.units.archivable_ns` written inline: it runs once per message.
    """
    if TIME_MIN_NS <= t_ns < TIME_MAX_NS:
        stamp.seconds, stamp.nanos = divmod(int(t_ns), NS)


def to_ns(ts: Timestamp) -> int:
    """Integer nanoseconds since the Unix epoch of a protobuf Timestamp."""
    return ts.seconds * NS + ts.nanos


_NAN9 = (float("nan"),) * 9
# bound once: the builders below run per message
_FIX_KEYS, _FIX_PACK = LOCATION_FIX.keys, LOCATION_FIX.struct.pack
_INS_KEYS, _INS_PACK = INS_STATE.keys, INS_STATE.struct.pack
_GNSS_KEYS, _GNSS_PACK = GNSS_STATUS.keys, GNSS_STATUS.struct.pack
_VEL_KEYS, _VEL_PACK = GNSS_VELOCITY.keys, GNSS_VELOCITY.struct.pack


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
        # One parse of packed wire bytes (`formats.wire`): upb sets a repeated double ~0.1 us per element
        # through extend() or a constructor keyword, and a nested Timestamp keyword costs
        # a copy; this way the fix costs about half (bench/bench_nmea.py).
        k0, k1, k2, k3, k4 = _FIX_KEYS
        fix = LocationFix.FromString(_FIX_PACK(
            k0, latitude, k1, longitude, k2, altitude, k3, *covariance_enu_m2, k4, covariance_type))
    else:
        # proto3 enums are open: a type outside the named four (read from someone's bag) is kept as it came
        kind = LocationFix.PositionCovarianceType.ValueType(covariance_type)
        fix = LocationFix(latitude=latitude, longitude=longitude, altitude=altitude,
                          position_covariance=covariance_enu_m2, position_covariance_type=kind)
    fix.frame_id = frame_id
    set_timestamp(fix.timestamp, t_ns)
    return fix


def location_fix_tail(t_ns: int, frame_id: str) -> bytes:
    """The wire bytes of a LocationFix's timestamp and frame_id: what follows its numeric fields when serialized
    (fields in number order), shared by the fixes of one time and frame (`location_fix_bytes`)."""
    fix = LocationFix(frame_id=frame_id)
    set_timestamp(fix.timestamp, t_ns)
    return fix.SerializeToString()


def location_fix_bytes(
    tail: bytes, t_ns: int, frame_id: str, latitude: float, longitude: float, altitude: float,
    covariance_enu_m2: tuple[float, ...], covariance_type: int,
) -> bytes:
    """`location_fix(...).SerializeToString()`, with `tail` = `location_fix_tail(t_ns, frame_id)`, without the
    message: the numeric fields packed (`formats.wire`) then the tail. A zero scalar, which serializing omits,
    or a covariance or type the run cannot pack goes through the message (tests/test_wire.py compares both)."""
    if (latitude == 0.0 or longitude == 0.0 or altitude == 0.0 or len(covariance_enu_m2) != 9
            or not 0 < covariance_type < 128):
        return location_fix(t_ns, frame_id, latitude, longitude, altitude, covariance_enu_m2,
                            covariance_type).SerializeToString()
    k0, k1, k2, k3, k4 = _FIX_KEYS
    return _FIX_PACK(k0, latitude, k1, longitude, k2, altitude, k3, *covariance_enu_m2, k4, covariance_type) + tail


def ins_state(
    t_ns: int, frame_id: str, source_format: str, status: str,
    latitude: float, longitude: float, depth_m: float, roll_deg: float, pitch_deg: float, heading_deg: float,
    velocity_north_mps: float, velocity_east_mps: float, velocity_down_mps: float,
    heading_std_deg: float, position_std_north_m: float, position_std_east_m: float,
    roll_std_deg: float, pitch_std_deg: float, altitude_m: float,
) -> InsState:
    """An auvreplay.InsState from every field (NaN where absent), built from packed wire bytes."""
    # one parse of packed doubles costs a third of fifteen keyword arguments (see location_fix)
    t = _INS_KEYS
    msg = InsState.FromString(_INS_PACK(
        t[0], latitude, t[1], longitude, t[2], depth_m, t[3], roll_deg, t[4], pitch_deg, t[5], heading_deg,
        t[6], velocity_north_mps, t[7], velocity_east_mps, t[8], velocity_down_mps, t[9], heading_std_deg,
        t[10], position_std_north_m, t[11], position_std_east_m, t[12], roll_std_deg, t[13], pitch_std_deg,
        t[14], altitude_m))
    msg.frame_id = frame_id
    msg.status = status
    msg.source_format = source_format
    set_timestamp(msg.timestamp, t_ns)
    return msg


def gnss_status(
    t_ns: int, frame_id: str, fix_quality: int, satellites: int, hdop: float, source_format: str,
    speed_mps: float, course_deg: float, heading_deg: float,
) -> GnssStatus:
    """An auvreplay.GnssStatus, its doubles parsed from packed wire bytes (as `ins_state`)."""
    k0, k1, k2, k3 = _GNSS_KEYS
    msg = GnssStatus.FromString(_GNSS_PACK(k0, hdop, k1, speed_mps, k2, course_deg, k3, heading_deg))
    msg.frame_id = frame_id
    msg.fix_quality = fix_quality
    msg.satellites = satellites
    msg.source_format = source_format
    set_timestamp(msg.timestamp, t_ns)
    return msg


def gnss_velocity(
    t_ns: int, frame_id: str, north_mps: float, east_mps: float, up_mps: float, speed_mps: float, course_deg: float,
    speed_std_mps: float, source_format: str,
) -> GnssVelocity:
    """An auvreplay.GnssVelocity from every field (NaN where absent), its doubles parsed from packed wire bytes."""
    k0, k1, k2, k3, k4, k5 = _VEL_KEYS
    msg = GnssVelocity.FromString(_VEL_PACK(k0, north_mps, k1, east_mps, k2, up_mps, k3, speed_mps, k4, course_deg,
                                            k5, speed_std_mps))
    msg.frame_id = frame_id
    msg.source_format = source_format
    set_timestamp(msg.timestamp, t_ns)
    return msg


# bound once: `detection_bytes` runs per detecting method at every range epoch
_DET_SCORE_KEYS, _DET_SCORE_PACK = DETECTION_SCORES.keys, DETECTION_SCORES.struct.pack
_DET_EXTRA_KEYS, _DET_EXTRA_PACK = DETECTION_EXTRA.keys, DETECTION_EXTRA.struct.pack
_DET_FLAGGED = varint(Detection.DESCRIPTOR.fields_by_name["flagged"].number << 3) + b"\x01"
_DET_CAPPED = varint(Detection.DESCRIPTOR.fields_by_name["isolation_capped"].number << 3) + b"\x01"
_DET_LABEL = varint(Detection.DESCRIPTOR.fields_by_name["label"].number << 3)
DETECTION_EXTRA_NAMES = DETECTION_EXTRA.names
"""The Detection fields `detection_bytes` takes as `extra`, in their order (field-number order)."""


@lru_cache(maxsize=256)
def _detection_strings(leader: str, method: str) -> bytes:
    return Detection(leader=leader, method=method).SerializeToString()


@lru_cache(maxsize=64)
def _detection_follower(follower: str) -> bytes:
    return Detection(follower=follower).SerializeToString()


def detection_stamp(t_ns: int) -> bytes:
    """The wire bytes of a Detection's timestamp (none when `t_ns` is no archivable time), for `detection_bytes`."""
    return Detection(timestamp=timestamp(t_ns)).SerializeToString()


def detection(t_ns: int, follower: str, leader: str, method: str, flagged: bool, scores: tuple[float, ...],
              label: int, capped: bool, extra: tuple[float, ...]) -> Any:
    """An auvreplay.Detection: `scores` are score, threshold and the features f1, f2, f3 (DETECTION_SCORES'
    fields), `extra` the fields of DETECTION_EXTRA_NAMES."""
    return Detection(timestamp=timestamp(t_ns), follower=follower, leader=leader, method=method, flagged=flagged,
                     label=label, isolation_capped=capped, **dict(zip(DETECTION_SCORES.names, scores)),
                     **dict(zip(DETECTION_EXTRA_NAMES, extra)))


def detection_bytes(stamp: bytes, t_ns: int, follower: str, leader: str, method: str, flagged: bool,
                    scores: tuple[float, ...], label: int, capped: bool, extra: tuple[float, ...]) -> bytes:
    """`detection(...).SerializeToString()`, with `stamp` = `detection_stamp(t_ns)`, without the message: fields
    in number order, strings and the time from cached bytes, the doubles packed (`formats.wire`). A zero double
    (serializing omits it), a label outside int32 or counts not those of the runs go through the message
    (tests/test_wire.py compares both)."""
    if (0.0 in scores or 0.0 in extra or len(scores) != 5 or len(extra) != len(DETECTION_EXTRA_NAMES)
            or not -(1 << 31) <= label < (1 << 31)):
        return detection(t_ns, follower, leader, method, flagged, scores, label, capped, extra).SerializeToString()
    k0, k1, k2, k3, k4 = _DET_SCORE_KEYS
    e, x = _DET_EXTRA_KEYS, extra     # every field from 13 on, however many the schema holds
    return b"".join((
        stamp, _detection_strings(leader, method), _DET_FLAGGED if flagged else b"",
        _DET_SCORE_PACK(k0, scores[0], k1, scores[1], k2, scores[2], k3, scores[3], k4, scores[4]),
        _DET_LABEL + varint(label & 0xFFFFFFFFFFFFFFFF) if label else b"",    # a negative int32: ten bytes
        _detection_follower(follower), _DET_CAPPED if capped else b"",
        _DET_EXTRA_PACK(*[v for pair in zip(e, x) for v in pair])))
