"""GPS time (week, seconds of week) to UTC nanoseconds, with the leap-second table."""

from __future__ import annotations

import bisect
import calendar

import numpy as np

from .units import NS

GPS_EPOCH_UNIX_S = 315964800  # 1980-01-06T00:00:00Z

# UTC instants (Unix seconds) from which GPS - UTC equals the given count.
_LEAPS: tuple[tuple[int, int], ...] = tuple(
    (calendar.timegm((y, m, 1, 0, 0, 0)), n)
    for (y, m, n) in (
        (1981, 7, 1), (1982, 7, 2), (1983, 7, 3), (1985, 7, 4), (1988, 1, 5),
        (1990, 1, 6), (1991, 1, 7), (1992, 7, 8), (1993, 7, 9), (1994, 7, 10),
        (1996, 1, 11), (1997, 7, 12), (1999, 1, 13), (2006, 1, 14), (2009, 1, 15),
        (2012, 7, 16), (2015, 7, 17), (2017, 1, 18),
    )
)
_LEAP_STARTS = [u for u, _ in _LEAPS]


def leap_seconds_at_utc(unix_s: float) -> int:
    """GPS - UTC in seconds at a UTC instant."""
    i = bisect.bisect_right(_LEAP_STARTS, unix_s)
    return 0 if i == 0 else _LEAPS[i - 1][1]


def gps_to_unix_ns(week: int, seconds_of_week: float) -> int:
    """UTC nanoseconds since the Unix epoch for a GPS week and seconds of week."""
    gps_ns = (GPS_EPOCH_UNIX_S + week * 604800) * NS + round(seconds_of_week * NS)
    if 0.0 <= seconds_of_week < 604800.0:  # within its week: the week's one count, when it has one
        known = _WEEK_LEAPS.get(week, -1)  # -1: not worked out yet (a count is never negative)
        if known == -1:
            known = _week_leap(week)
        if known is not None:
            return gps_ns - known * NS
    approx = gps_ns / NS
    leap = leap_seconds_at_utc(approx - leap_seconds_at_utc(approx))
    return gps_ns - leap * NS


# GPS week -> the leap count of every instant of it, or None for a week a leap second falls in; bounded (a log of
# garbage may name any week)
_WEEK_LEAPS: dict[int, int | None] = {}


def _week_leap(week: int) -> int | None:
    """The count `gps_to_unix_ns` works out for every time of `week` (None where it is not one count): with the
    same count at both ends of the week (a margin either side), it is the same inside, both steps being monotone."""
    start = GPS_EPOCH_UNIX_S + week * 604800
    lo, hi = (start - 2) * NS / NS, (start + 604802) * NS / NS
    inner = leap_seconds_at_utc(lo)
    leap = leap_seconds_at_utc(lo - inner)
    same = inner == leap_seconds_at_utc(hi) and leap == leap_seconds_at_utc(hi - inner)
    if len(_WEEK_LEAPS) >= 1024:
        _WEEK_LEAPS.clear()
    _WEEK_LEAPS[week] = leap if same else None
    return _WEEK_LEAPS[week]


def gps_to_unix_ns_column(weeks: np.ndarray, seconds: np.ndarray) -> np.ndarray | None:
    """`gps_to_unix_ns` of every (week, seconds) pair as int64, in numpy where the week has one leap count and the
    seconds lie within it (`round` and numpy's `rint` both round half to even, and every product below 2**53 is
    exact); None where a time is beyond int64."""
    out = np.zeros(len(weeks), dtype=np.int64)
    inside = (seconds >= 0.0) & (seconds < 604800.0)
    for week in np.unique(weeks).tolist():
        leap = _WEEK_LEAPS.get(week, -1)
        if leap == -1:
            leap = _week_leap(week)
        at = np.flatnonzero((weeks == week) & inside) if leap is not None else np.zeros(0, dtype=np.int64)
        base = (GPS_EPOCH_UNIX_S + week * 604800 - (leap or 0)) * NS
        if not -(1 << 62) < base < 1 << 62:
            return None
        out[at] = base + np.rint(seconds[at] * NS).astype(np.int64)
        rest = np.flatnonzero((weeks == week) & ~inside) if leap is not None else np.flatnonzero(weeks == week)
        for i in rest.tolist():
            t = gps_to_unix_ns(week, float(seconds[i]))
            if not -(1 << 63) <= t < 1 << 63:
                return None
            out[i] = t
    return out


def unix_ns_to_gps(unix_ns: int) -> tuple[int, float]:
    """GPS week and seconds of week for UTC nanoseconds (inverse of gps_to_unix_ns)."""
    gps_ns = unix_ns + leap_seconds_at_utc(unix_ns / NS) * NS - GPS_EPOCH_UNIX_S * NS
    week, rem = divmod(gps_ns, 604800 * NS)
    return int(week), rem / NS
