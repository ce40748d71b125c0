"""Clock alignment: time of day plus a date to UTC ns, midnight rollover, clock offsets."""

from __future__ import annotations

import calendar
import math
from datetime import UTC, date
from functools import lru_cache

from formats.gpstime import gps_to_unix_ns
from formats.units import DAY_NS, NS


@lru_cache(maxsize=64)
def date_to_ns(d: date) -> int:
    """UTC midnight of a date in ns since the Unix epoch (cached: NMEA logs restate it every epoch)."""
    return calendar.timegm(d.timetuple()) * NS


class DayClock:
    """Turns NMEA-style times of day into absolute UTC ns.

    The date comes from the last date-bearing record (RMC, ZDA, ...) or else
    the manifest's trial date. When the time of day drops by more than half a
    day without a new date, the clock rolls over to the next day; a small drop
    is an out-of-order record and is kept on the same day.
    """

    def __init__(self, trial_date: date | None, offset_ns: int = 0):
        self.day_ns: int | None = date_to_ns(trial_date) if trial_date else None
        self.offset_ns = offset_ns
        self._last_tod_ns: int | None = None

    def set_date(self, d: date, tod_s: float | None = None) -> None:
        """A record carried a full date (its time of day, if given, anchors the rollover)."""
        self.day_ns = date_to_ns(d)
        if tod_s is not None and math.isfinite(tod_s):
            self._last_tod_ns = round(tod_s * NS)

    def resolve(self, tod_s: float) -> int | None:
        """Absolute UTC ns (clock offset applied) for a time of day, or None without a date."""
        if self.day_ns is None or not math.isfinite(tod_s):
            return None
        tod_ns = round(tod_s * NS)
        if self._last_tod_ns is not None and tod_ns < self._last_tod_ns - DAY_NS // 2:
            self.day_ns += DAY_NS
        elif self._last_tod_ns is not None and tod_ns > self._last_tod_ns + DAY_NS // 2:
            self.day_ns -= DAY_NS  # a late record from before midnight
        self._last_tod_ns = tod_ns
        return self.day_ns + tod_ns + self.offset_ns


def gps_time_ns(week: int, seconds_of_week: float, offset_ns: int = 0) -> int:
    """UTC ns for GPS week/seconds with the log's clock offset applied."""
    return gps_to_unix_ns(week, seconds_of_week) + offset_ns


def iso_utc(ns: int | None) -> str | None:
    """ISO 8601 UTC text ('...Z') for ns since the Unix epoch; None stays None."""
    if ns is None:
        return None
    from datetime import datetime

    sec, frac = divmod(int(ns), NS)
    text = datetime.fromtimestamp(sec, tz=UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{text}Z" if frac == 0 else f"{text}.{frac:09d}".rstrip("0") + "Z"
