"""Clock alignment: time of day plus a date to UTC ns, midnight rollover, clock offsets, time bases.

A log's time base (its manifest entry's `time_base`, docs/time-bases.md) says what its clock counts:
"utc" (the default) is UTC, corrected by `clock_offset_s`; "sim" (a bag recorded in simulated time) and
"boot" (a dataflash log's time since boot) count seconds from a zero that the entry's `start` places in
UTC. Either way the log's times become UTC by one offset (`log_offset_ns`), which every converter adds
as it always has; the recording then checks that the offset put the log's first time in 1980-2100
(`offset_problem`).
"""

from __future__ import annotations

import calendar
import math
from datetime import UTC, date, datetime
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
    sec, frac = divmod(int(ns), NS)
    text = datetime.fromtimestamp(sec, tz=UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{text}Z" if frac == 0 else f"{text}.{frac:09d}".rstrip("0") + "Z"


TIME_BASES = ("utc", "sim", "boot")
RELATIVE_BASES = ("sim", "boot")  # clocks counting from a zero that `start` places in UTC
# where a log's times may land once its clock offset or start is applied: 1980-01-01 .. 2100-01-01 UTC
OFFSET_TIMES_NS = (315_532_800 * NS, 4_102_444_800 * NS)
# the largest clock offset (~133 years): beyond it no clock counting from 0, nor a UTC clock before 2100, lands
# in 1980-2100; and times stay within int64 ns where they are handled as arrays
MAX_OFFSET_S = 4.2e9


def log_offset_ns(time_base: str, start_ns: int | None, clock_offset_s: float) -> int:
    """The ns added to every time of a log: its `start` under a sim/boot time base, else its clock offset."""
    if time_base in RELATIVE_BASES and start_ns is not None:
        return start_ns
    return round(clock_offset_s * NS)


def parse_utc(value: object) -> int | None:
    """UTC ns of an ISO 8601 instant with a zone (text, or a TOML datetime); None when it is not one."""
    if isinstance(value, str):
        try:
            value = datetime.fromisoformat(value.strip())
        except ValueError:
            return None
    if not isinstance(value, datetime) or value.tzinfo is None or value.utcoffset() is None:
        return None
    delta = value - datetime(1970, 1, 1, tzinfo=UTC)
    return (delta.days * 86400 + delta.seconds) * NS + delta.microseconds * 1000


def in_offset_window(t_ns: int) -> bool:
    """Whether a time shifted by a log's offset or start is in 1980-2100 (OFFSET_TIMES_NS)."""
    return OFFSET_TIMES_NS[0] <= t_ns < OFFSET_TIMES_NS[1]


def shift_text(time_base: str, offset_ns: int) -> str:
    """How the manifest moves a log's times, as its keys read ("clock_offset_s = 1.6e+09"); "" when not at all."""
    if time_base in RELATIVE_BASES:
        return f"time_base = {time_base!r} with start = {iso_utc(offset_ns)}"
    return f"clock_offset_s = {offset_ns / NS:g}" if offset_ns else ""


def offset_problem(t_ns: int, time_base: str, offset_ns: int) -> str | None:
    """None when `t_ns` (a log's first time, its offset or start applied) is in 1980-2100, or the manifest does
    not move the log's times; else the one-line reason naming the key and the date it gives."""
    if in_offset_window(t_ns) or not (what := shift_text(time_base, offset_ns)):
        return None
    return f"{what} puts the log's first time at {date_text(t_ns)}, outside 1980-01-01 .. 2100-01-01 UTC"


def date_text(t_ns: float) -> str:
    """ISO UTC text of any ns since the epoch: datetime's years 1..9999, beyond them the year alone."""
    if -62_135_596_800 * NS <= t_ns < 253_402_300_800 * NS:
        return str(iso_utc(int(t_ns)))
    return f"the year {t_ns / NS / 86400 / 365.2425 + 1970:.6g}"
