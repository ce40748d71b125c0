"""GNSS velocity over ground on ``/<vehicle>/gps/velocity`` (auvreplay.GnssVelocity), from any receiver.

A receiver gives either components (north/east/up, as NovAtel BESTVEL's vertical speed or MAVLink
GPS_INPUT) or speed and course (NMEA VTG/RMC, GPS_RAW_INT): the other form is derived, so a reader always
finds both. Missing values are NaN.
"""

from __future__ import annotations

import math

from formats import schemas as S

from .base import LogContext

SUFFIX = "gps/velocity"
NAN = math.nan


def gnss_velocity(ctx: LogContext, t_ns: int, source: str, *, north: float = NAN, east: float = NAN,
                  up: float = NAN, speed: float = NAN, course: float = NAN,
                  speed_std: float = NAN) -> S.GnssVelocity:
    """A GnssVelocity stamped `t_ns` (ns, UTC); speed/course from north/east when not given, and back."""
    if math.isnan(speed) and not (math.isnan(north) or math.isnan(east)):
        speed, course = math.hypot(north, east), math.degrees(math.atan2(east, north)) % 360.0
    elif math.isnan(north) and not (math.isnan(speed) or math.isnan(course)):
        north, east = speed * math.cos(math.radians(course)), speed * math.sin(math.radians(course))
    return S.GnssVelocity(timestamp=S.timestamp(t_ns), frame_id=ctx.vehicle, velocity_north_mps=north,
                          velocity_east_mps=east, velocity_up_mps=up, speed_over_ground_mps=speed,
                          course_over_ground_deg=course, speed_std_mps=speed_std, source_format=source)


def has_velocity(speed: float, north: float) -> bool:
    """Whether an epoch gave a velocity at all (speed, or a north component)."""
    return math.isfinite(speed) or math.isfinite(north)
