"""nav_msgs/Odometry, sensor_msgs/NavSatFix and tf2_msgs/TFMessage read straight from their serialized bytes.

As `formats.ros_imu` does for the Imu: building rosbags' message objects
(a dataclass per header, time, pose, vector...) costs more than everything
else a bag message does in a recording, and these types' layouts are fixed
but for their text fields. So a message is walked here field by field, with
the checks rosbags' deserializers make (every length inside the message, a
CDR string's terminating NUL, UTF-8 text, nothing left over but CDR's up to 3
bytes of padding): a message read here is one rosbags decodes, and gives the
same values. TFMessage is only checked (it is archived as itself, never
converted); Odometry and NavSatFix give their stamp, frames and numbers.

Only a bag whose definition of the type is the standard one is read this way
(`STANDARD`, rosbags' MD5 of the definition text by ROS version), and only
little-endian CDR (rosbags reads a big-endian message); any other is decoded by
rosbags.
"""

from __future__ import annotations

import struct

ODOMETRY, NAVSATFIX, TF = "nav_msgs/msg/Odometry", "sensor_msgs/msg/NavSatFix", "tf2_msgs/msg/TFMessage"
# rosbags' MD5 of each definition (Typestore.generate_msgdef), by ROS version: the layouts read here
STANDARD = {
    ODOMETRY: {1: "cd5e73d190d741a2f92e81eda573aca7", 2: "7d13133659beedef5fbafd61a6288fbe"},
    NAVSATFIX: {1: "2d3a8cd499b9b4a0249fb98fd05cfa48", 2: "67a809d0baed1f0d41ca4f460a28e15b"},
    TF: {1: "94810edda583a504dfda3829e70d7eec", 2: "70ffc0bc3c839d1cfd586f7c7916d88b"},
}
# Odometry's doubles, in order: pose position (3), orientation x y z w (4), pose covariance (36), twist linear (3),
# angular (3), twist covariance (36)
ODOMETRY_DOUBLES = 85
POSE_COV, LINEAR = slice(7, 43), slice(43, 46)   # after position (0-2) and orientation (3-6)
_U32 = struct.Struct("<I")
_ROS1_STAMP = struct.Struct("<IiI")   # seq, secs, nsecs (rosbags reads secs as int32, as ROS 2's)
_CDR_STAMP = struct.Struct("<iI")     # sec, nanosec (after the 4-byte encapsulation)
_ODOMETRY = struct.Struct(f"<{ODOMETRY_DOUBLES}d")
_FIX_ROS1 = struct.Struct("<bH12dB")  # status, service, latitude, longitude, altitude, covariance (9), its type
_I8 = struct.Struct("<b")
_FIX_DOUBLES = struct.Struct("<12d")
_TRANSFORM = 56                      # translation (3) and rotation (4) doubles
NS = 1_000_000_000
_ERRORS = (struct.error, IndexError, UnicodeDecodeError, ValueError)

Odometry = tuple[int, str, str, tuple[float, ...]]                 # stamp ns, frame_id, child_frame_id, doubles
NavSatFix = tuple[int, str, int, tuple[float, ...], int]           # stamp ns, frame_id, status, doubles, cov type


def _text(data: bytes, pos: int, ros1: bool) -> tuple[str, int]:
    """A string field at `pos` (CDR: aligned to 4 first) and the position after it; ValueError when it does not
    fit, lacks its NUL (CDR) or is not UTF-8."""
    if ros1:
        (n,) = _U32.unpack_from(data, pos)
        end = pos + 4 + n
        if end > len(data):
            raise ValueError("string past the end")
        return data[pos + 4:end].decode(), end
    pos = (pos + 3) & ~3   # the payload starts at byte 4: aligned to 4 in it is aligned to 4 here
    (n,) = _U32.unpack_from(data, pos)
    end = pos + 4 + n
    if n < 1 or end > len(data) or data[end - 1] != 0:
        raise ValueError("string without its NUL")
    return data[pos + 4:end - 1].decode(), end


def _header(data: bytes, ros1: bool) -> tuple[int, str, int]:
    """(stamp ns, frame_id, position after it) of a std_msgs/Header that opens a message."""
    if ros1:
        _, sec, nsec = _ROS1_STAMP.unpack_from(data, 0)
        frame, pos = _text(data, 12, True)
        return sec * NS + nsec, frame, pos
    if data[0] != 0 or data[1] != 1:   # encapsulation CDR_LE (0x0001) only: rosbags reads the others
        raise ValueError("not little-endian CDR")
    sec, nsec = _CDR_STAMP.unpack_from(data, 4)
    frame, pos = _text(data, 12, False)
    return sec * NS + nsec, frame, pos


def _double_at(pos: int) -> int:
    """A CDR position aligned to 8 within the payload (which starts at byte 4)."""
    return 4 + ((pos - 4 + 7) & ~7)


def _ends(data: bytes, pos: int, ros1: bool) -> bool:
    """Whether the message ends at `pos` (CDR: up to 3 bytes of padding after it, as rosbags allows)."""
    return pos == len(data) if ros1 else 0 <= len(data) - pos <= 3


def odometry(data: bytes, ros1: bool) -> Odometry | None:
    """(stamp ns, frame_id, child_frame_id, the 85 doubles) of a serialized Odometry, or None when its bytes are
    not one."""
    try:
        stamp, frame, pos = _header(data, ros1)
        child, pos = _text(data, pos, ros1)
        if not ros1:
            pos = _double_at(pos)
        values = _ODOMETRY.unpack_from(data, pos)
    except _ERRORS:
        return None
    return (stamp, frame, child, values) if _ends(data, pos + _ODOMETRY.size, ros1) else None


def navsatfix(data: bytes, ros1: bool) -> NavSatFix | None:
    """(stamp ns, frame_id, status, latitude/longitude/altitude and the 9 covariances, covariance type) of a
    serialized NavSatFix, or None when its bytes are not one."""
    try:
        stamp, frame, pos = _header(data, ros1)
        if ros1:
            status, _, *doubles, kind = _FIX_ROS1.unpack_from(data, pos)
            values = tuple(doubles)
            end = pos + _FIX_ROS1.size
        else:
            (status,) = _I8.unpack_from(data, pos)
            pos = ((pos + 2) & ~1) + 2           # the uint16 service, aligned to 2 after the status byte
            pos = _double_at(pos)
            values = _FIX_DOUBLES.unpack_from(data, pos)
            end = pos + _FIX_DOUBLES.size
            kind = data[end]
            end += 1
    except _ERRORS:
        return None
    return (stamp, frame, status, values, kind) if _ends(data, end, ros1) else None


# TFMessages of one transform found whole, by the bytes `_transforms` reads of them (`transforms`); bounded
_ONE_TRANSFORM: set[bytes] = set()
_ONE_TRANSFORM_MAX = 4096


def transforms(data: bytes, ros1: bool) -> int | None:
    """The number of transforms of a serialized TFMessage (each one's stamp, frames and numbers checked to lie
    inside it), or None when its bytes are not one.

    A TFMessage of one transform (the usual /tf message) is read once per frame pair: its check reads nothing
    of the header's seq and stamp (bytes 4-16: ROS 1 seq, secs, nsecs; CDR sec, nanosec after the encapsulation
    and count) nor of the last 56 bytes (a whole message's numbers), so a message alike in every other byte and
    in length is one as well.
    """
    if len(data) > 72:
        key = (b"\x01" if ros1 else b"\x02") + data[:4 if ros1 else 8] + data[16:-56]
        if key in _ONE_TRANSFORM:
            return 1
        count = _transforms(data, ros1)
        if count == 1:
            if len(_ONE_TRANSFORM) >= _ONE_TRANSFORM_MAX:
                _ONE_TRANSFORM.clear()
            _ONE_TRANSFORM.add(key)
        return count
    return _transforms(data, ros1)


def _transforms(data: bytes, ros1: bool) -> int | None:
    try:
        if not ros1 and (data[0] != 0 or data[1] != 1):
            return None
        (count,) = _U32.unpack_from(data, 0 if ros1 else 4)
        pos = 4 if ros1 else 8
        n = len(data)
        if pos + count > n:   # every transform takes a byte at least (rosbags' check of a sequence's count)
            return None
        for _ in range(count):
            if ros1:
                pos += 12       # seq, secs, nsecs
                _, pos = _text(data, pos, True)
                _, pos = _text(data, pos, True)
            else:
                pos = ((pos + 3) & ~3) + 8   # sec, nanosec
                _, pos = _text(data, pos, False)
                _, pos = _text(data, pos, False)
                pos = _double_at(pos)
            pos += _TRANSFORM
            if pos > n:
                return None
    except _ERRORS:
        return None
    return count if _ends(data, pos, ros1) else None
