"""GNSS velocity over ground on ``/<vehicle>/gps/velocity`` (auvreplay.GnssVelocity), from any receiver.

A receiver gives either components (north/east/up, as NovAtel BESTVEL's vertical speed or MAVLink
GPS_INPUT) or speed and course (NMEA VTG/RMC, GPS_RAW_INT): the other form is derived, so a reader always
finds both. Missing values are NaN. `components` is the one rule from speed and course to north and east;
`components_column` applies it to a column (the NMEA columnar path), value for value the same floats.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from formats import schemas as S

from .base import LogContext

SUFFIX = "gps/velocity"
NAN = math.nan
# why an epoch whose motion sentence (VTG, RMC) gives no velocity archives none (counted as ignored)
NO_VELOCITY = "nmea: VTG/RMC without a valid speed and course (empty, or not valid): no velocity"


def components(speed: float, course: float) -> tuple[float, float]:
    """(north, east) in m/s of a speed (m/s) along a course (degrees true); both finite."""
    c = math.radians(course)
    return speed * math.cos(c), speed * math.sin(c)


def components_column(speed: np.ndarray, course: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """`components` of every (speed, course) pair: math's cos and sin per value, products in numpy.

    numpy's own cos and sin may differ from libm's in the last bit; these are exactly `components`' floats.
    """
    c = list(map(math.radians, course))
    cos = np.fromiter(map(math.cos, c), dtype=np.float64, count=len(c))
    sin = np.fromiter(map(math.sin, c), dtype=np.float64, count=len(c))
    return speed * cos, speed * sin


def gnss_velocity(ctx: LogContext, t_ns: int, source: str, *, north: float = NAN, east: float = NAN,
                  up: float = NAN, speed: float = NAN, course: float = NAN,
                  speed_std: float = NAN) -> S.GnssVelocity:
    """A GnssVelocity stamped `t_ns` (ns, UTC); speed/course from north/east when not given, and back."""
    if math.isnan(speed) and not (math.isnan(north) or math.isnan(east)):
        speed, course = math.hypot(north, east), math.degrees(math.atan2(east, north)) % 360.0
    elif math.isnan(north) and math.isfinite(speed) and math.isfinite(course):
        north, east = components(speed, course)
    return S.gnss_velocity(t_ns, ctx.vehicle, north, east, up, speed, course, speed_std, source)


def has_velocity(speed: float, north: float) -> bool:
    """Whether an epoch gave a velocity at all (speed, or a north component)."""
    return math.isfinite(speed) or math.isfinite(north)
