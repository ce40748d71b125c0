"""User-defined line format: a Python regex with named groups (manifest format "regex").

For modems without a public log format, such as the Teledyne Benthos ATM-88x
used in the source lake trial, the user describes a range line with a
regular expression. Recognised named groups:

- ``time``: the measurement time, read with ``time_format``:
  ``tod`` ("HH:MM:SS(.f)" or "HHMMSS(.f)", date from an optional ``date``
  group "YYYY-MM-DD" or the trial date), ``iso8601``, or ``unix`` (seconds).
  Without a ``time`` group the host-timestamp prefix gives the time.
- ``source`` / ``destination``: the vehicle heard and the vehicle that
  measured, as modem addresses (digits) or vehicle names.
- ``travel_time_s`` (multiplied by ``travel_time_scale``, e.g. 0.5 for a
  round-trip time, 0.0005 for a round trip written in milliseconds) and/or
  ``range_m``; at least one of the two is required.
- USBL lines may also use ``target``, ``bearing_deg``, ``elevation_deg``,
  ``east_m``, ``north_m``, ``up_m``, ``phase_x_rad``, ``phase_y_rad``.

Any other named group is kept as text in `RegexRecord.groups`. A line is
matched after its host-timestamp prefix is removed, and when that fails, whole
(so a pattern may read a leading timestamp that looks like a host prefix).

Example, an ATM-88x-style range line as a topside logger might write it::

    12:00:05.200 Range 1 to 2 : 500.1 m (Round-trip 666.8 ms)

    pattern = '(?P<time>\\d{2}:\\d{2}:\\d{2}(?:\\.\\d+)?) Range (?P<destination>\\d+) to
               (?P<source>\\d+) : [\\d.]+ m \\(Round-trip (?P<travel_time_s>[\\d.]+) ms\\)'
    time_format = "tod"
    travel_time_scale = 0.0005      # milliseconds -> seconds, round trip -> one way

(`EXAMPLE_PATTERN` below is that pattern, tested in tests/test_regex_lines.py.)
Lines that do not match are Rejects ("no match"); a pattern that does not
compile raises `FormatError`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import UTC, date, datetime
from typing import Any

# user patterns run on the `regex` engine for its per-match time limit: a pattern from a shared manifest
# that backtracks without end ((a|aa)+$) is refused with a message instead of hanging `record`
import regex

from .lines import PREFIX_STYLES, iter_lines, strip_prefix
from .log_blocks import LogText
from .numbers import finite
from .records import FormatError, Reject, Where
from .units import NS, archivable_ns

TIME_FORMATS = ("tod", "iso8601", "unix")
NUMERIC_GROUPS = (
    "travel_time_s", "range_m", "bearing_deg", "elevation_deg",
    "east_m", "north_m", "up_m", "phase_x_rad", "phase_y_rad",
)
EXAMPLE_PATTERN = (
    r"(?P<time>\d{2}:\d{2}:\d{2}(?:\.\d+)?) Range (?P<destination>\d+) to (?P<source>\d+)"
    r" : [\d.]+ m \(Round-trip (?P<travel_time_s>[\d.]+) ms\)"
)
EXAMPLE_SCALE = 0.0005

_TOD = re.compile(r"(\d{2}):?(\d{2}):?(\d{2}(?:\.\d+)?)")
_ISO = re.compile(r"(\d{4}-\d{2}-\d{2})[T ](\d{2}:\d{2}:\d{2})(?:[.,](\d+))?\s*(Z|[+-]\d{2}:?\d{2})?")


@dataclass(frozen=True, slots=True)
class RegexRecord:
    """One matched line: its time (absolute or time of day), endpoints and numeric groups.

    `time_ns` is UTC ns without the clock offset (iso8601/unix), `tod_s`
    seconds since midnight (tod); both None when the line has no time group.
    `values` holds every recognised numeric group (travel time already scaled).
    """

    where: Where
    time_ns: int | None
    tod_s: float | None
    date: date | None
    source: str
    destination: str
    values: Mapping[str, float] = field(default_factory=dict)
    groups: Mapping[str, str] = field(default_factory=dict)

    @property
    def travel_time_s(self) -> float:
        """One-way travel time in seconds (NaN when the line has none)."""
        return self.values.get("travel_time_s", math.nan)

    @property
    def range_m(self) -> float:
        """Range in metres as written on the line (NaN when absent)."""
        return self.values.get("range_m", math.nan)


MATCH_TIMEOUT_S = 0.05   # per line; a sane pattern takes microseconds
MAX_LINE_CHARS = 65_536  # longer lines are not records of any modem log


def compile_pattern(pattern: object, require_range: bool = True) -> Any:
    """Compile a user pattern (a `regex` Pattern); FormatError with a clear message when it is unusable."""
    if not isinstance(pattern, str) or not pattern:
        raise FormatError("regex format: the manifest option 'pattern' must be a non-empty string")
    try:
        compiled = regex.compile(pattern)
    except (regex.error, OverflowError, RecursionError) as exc:
        raise FormatError(f"regex format: pattern does not compile: {exc}") from None
    names = set(compiled.groupindex)
    if require_range and not names & {"travel_time_s", "range_m"}:
        raise FormatError("regex format: pattern needs a named group 'travel_time_s' or 'range_m'")
    return compiled


def parse_iso8601_ns(text: str) -> int:
    """UTC ns of an ISO 8601 time ('2016-10-12T08:00:01.25Z'; no zone means UTC)."""
    m = _ISO.fullmatch(text.strip())
    if not m:
        raise ValueError(f"not an ISO 8601 time: {text!r}")
    dt = datetime.fromisoformat(f"{m.group(1)}T{m.group(2)}")
    zone = m.group(4)
    tz = UTC if zone in (None, "Z") else datetime.fromisoformat("2000-01-01T00:00:00" + zone).tzinfo
    frac = m.group(3) or ""
    return int(dt.replace(tzinfo=tz).timestamp()) * NS + int((frac + "0" * 9)[:9])


def parse_tod_s(text: str) -> float:
    """Seconds since midnight of 'HH:MM:SS(.f)' or 'HHMMSS(.f)'."""
    m = _TOD.fullmatch(text.strip())
    if not m:
        raise ValueError(f"not a time of day: {text!r}")
    h, mi, s = int(m.group(1)), int(m.group(2)), float(m.group(3))
    if h > 23 or mi > 59 or s >= 61:
        raise ValueError(f"time of day out of range: {text!r}")
    return h * 3600 + mi * 60 + s


def _unix_ns(text: str) -> int:
    whole, _, frac = text.strip().partition(".")
    if not whole.lstrip("-").isdigit() or (frac and not frac.isdigit()):
        raise ValueError(f"not Unix seconds: {text!r}")
    sign = -1 if whole.startswith("-") else 1
    return int(whole) * NS + sign * int((frac + "0" * 9)[:9]) if frac else int(whole) * NS


def _finite(name: str, text: str) -> float:
    return finite(text, f"group {name}")


def _times(g: Mapping[str, str], time_format: str) -> tuple[int | None, float | None, date | None]:
    stamp = g.get("time")
    day = date.fromisoformat(g["date"]) if g.get("date") else None
    if not stamp:
        return None, None, day
    if time_format == "tod":
        return None, parse_tod_s(stamp), day
    t = parse_iso8601_ns(stamp) if time_format == "iso8601" else _unix_ns(stamp)
    if not archivable_ns(t):
        raise ValueError(f"time outside 1970-2200: {stamp!r}")
    return t, None, day


def _record(m: Any, where: Where, time_format: str, scale: float) -> RegexRecord | Reject:
    g = {k: v for k, v in m.groupdict().items() if v is not None}
    try:
        time_ns, tod_s, day = _times(g, time_format)
        values = {k: _finite(k, g[k]) for k in NUMERIC_GROUPS if g.get(k, "").strip()}
    except (ValueError, OverflowError) as exc:
        return Reject(where, f"bad field: {exc}")
    if "travel_time_s" in values:
        values["travel_time_s"] *= scale
    if any(values.get(k, 0.0) < 0 for k in ("travel_time_s", "range_m")):
        return Reject(where, "negative travel time or range")
    source = g.get("source", g.get("target", "")).strip()
    return RegexRecord(where, time_ns, tod_s, day, source, g.get("destination", "").strip(), values, g)


def decode(
    data: LogText,
    pattern: Any,
    time_format: str = "tod",
    prefix: str = "auto",
    travel_time_scale: float = 1.0,
) -> Iterator[RegexRecord | Reject]:
    """Match every line against the user pattern; non-matching lines are Rejects ('no match').

    A pattern that takes over MATCH_TIMEOUT_S on one line is a FormatError
    naming the line (it would take as long on every other).
    """
    compiled = compile_pattern(pattern) if isinstance(pattern, str) else pattern
    if prefix not in PREFIX_STYLES:
        raise FormatError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    if time_format not in TIME_FORMATS:
        raise FormatError(f"regex format: time_format must be one of {TIME_FORMATS}, not {time_format!r}")
    scale = float(travel_time_scale)
    if not math.isfinite(scale) or scale <= 0:
        raise FormatError(f"regex format: travel_time_scale must be a positive number, not {travel_time_scale!r}")
    for raw in iter_lines(data, "none"):
        rest, host_ns = strip_prefix(raw.text, prefix)
        where = Where(raw.where.offset, raw.where.line, host_ns)
        if len(raw.text) > MAX_LINE_CHARS:
            yield Reject(where, f"line of {len(raw.text)} characters, over {MAX_LINE_CHARS}")
            continue
        # a pattern may itself read the leading timestamp that looks like a host prefix
        try:
            m = compiled.search(rest, timeout=MATCH_TIMEOUT_S) or (
                compiled.search(raw.text, timeout=MATCH_TIMEOUT_S) if host_ns is not None else None)
        except TimeoutError:
            raise FormatError(f"regex format: the pattern takes over {MATCH_TIMEOUT_S} s on line {where.line} "
                              "(nested repetition such as (a|aa)+ backtracks without end): simplify it") from None
        if m is None:
            yield Reject(where, "no match")
            continue
        yield _record(m, where, time_format, scale)
