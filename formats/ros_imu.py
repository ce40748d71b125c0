"""sensor_msgs/Imu read straight from its serialized bytes, ROS 1 or CDR, many messages at once.

An Imu is the busiest topic of most bags (100-400 Hz), and building rosbags'
message object for each costs more than everything else its message does
here. Its layout is fixed but for the frame name: a header (ROS 1: seq,
stamp, frame_id; ROS 2: stamp, frame_id), then 37 float64 (orientation x y z
w and its 3 x 3 covariance, angular velocity and its covariance, linear
acceleration and its covariance) that end the message. So a message is
checked in a few byte reads (`header`: its length must be exactly header +
frame name + padding + 296 bytes), and the doubles of a batch are one numpy
array (`values`).

Only a bag whose Imu definition is the standard one is read this way (`STANDARD`,
rosbags' MD5 of the definition text); any other is decoded by rosbags.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

import numpy as np

MSGTYPE = "sensor_msgs/msg/Imu"
DOUBLES = 37
TAIL = 8 * DOUBLES
# rosbags' MD5 of sensor_msgs/Imu's definition (Typestore.generate_msgdef), by ROS version: the layout read here
STANDARD = {1: "6a62c6daae103f4ff57a132d6f95cec2", 2: "71ec98acab7649fe7360000f098e51b6"}
# columns of `values`
ORIENTATION, ORIENTATION_COV = slice(0, 4), slice(4, 13)
ANGULAR, ANGULAR_COV0 = slice(13, 16), 16
LINEAR, LINEAR_COV0 = slice(25, 28), 28
_STAMP = struct.Struct("<IIII")     # ROS 1: seq, secs, nsecs, frame_id length
_CDR_STAMP = struct.Struct("<iII")  # CDR little-endian, after its 4-byte encapsulation: sec, nanosec, length


def header(data: bytes, ros1: bool) -> tuple[int, bytes] | None:
    """(header stamp ns, frame_id bytes) of one serialized Imu, or None when its bytes are not an Imu's (a length
    that does not add up, or a big-endian CDR message, which rosbags reads instead)."""
    n = len(data)
    if ros1:
        if n < 16 + TAIL:
            return None
        _, sec, nsec, length = _STAMP.unpack_from(data, 0)
        end = 16 + length
        if n != end + TAIL:
            return None
        return sec * 1_000_000_000 + nsec, data[16:end]
    if n < 16 + TAIL or data[1] != 1:   # encapsulation CDR_LE (0x0001)
        return None
    sec, nsec, length = _CDR_STAMP.unpack_from(data, 4)
    end = 16 + length
    aligned = 4 + ((end - 4 + 7) & ~7)  # the doubles align to 8 within the payload that follows the encapsulation
    if length < 1 or n != aligned + TAIL:
        return None
    return sec * 1_000_000_000 + nsec, data[16:end - 1]   # CDR strings end with a NUL, counted in length


def values(messages: Sequence[bytes]) -> np.ndarray:
    """The 37 doubles of each message (checked by `header`), one row each; non-finite values NaN."""
    out = np.frombuffer(b"".join([m[-TAIL:] for m in messages]), "<f8").reshape(len(messages), DOUBLES)
    return np.where(np.isfinite(out), out, np.nan)
