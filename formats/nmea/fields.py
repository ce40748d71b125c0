"""NMEA field rules: each written once, as the per-line parser and, beside it, its column form.

The per-line forms (`parse_tod`, `parse_angle`, ...) decide every string,
raising ValueError for a bad one; `sentences` calls them for one sentence.
The column forms (`tod_column`, `angle_column`, `number_column`) take every
string of one field of a clean log (`formats.nmea.clean`) at once for
`formats.nmea.columns`: they convert with Python's own `float` and `int` on
the same strings, or check the strings strictly enough that the vectorised
arithmetic is the per-line rule's exactly, and return None where the
per-line rule must decide (it may reject, or accept something odd).
tests/test_nmea_columns.py checks both forms agree on any log.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import date
from functools import lru_cache

import numpy as np

from ..numbers import optional, optional_integer, texts_finite, texts_integer

NAN = float("nan")


# the number rule of every field: finite, of a size a field holds (formats.numbers); NaN or -1 when empty
parse_float = optional
parse_int = optional_integer


def number_column(convert: Callable[[str], object], column: list[str], empty: object) -> list | None:
    """convert() of every string, `empty` for empty ones (`parse_float`'s and `parse_int`'s rule); None if one fails.

    `convert` is float or int; a string the number rule (`formats.numbers`) might refuse gives None too.
    """
    distinct = set(column)
    if not (texts_finite(distinct) if convert is float else texts_integer(distinct)):
        return None
    return _convert(convert, column, empty, distinct)


def _convert(convert: Callable[[str], object], column: list[str], empty: object, distinct: set[str]) -> list | None:
    """`number_column` for strings already known to be plain numbers (digits and a dot)."""
    try:
        if len(distinct) * 4 < len(column):  # status fields, sigmas, empty ones: convert each string once
            table = {x: convert(x) if x else empty for x in distinct}
            return list(map(table.__getitem__, column))
        if "" not in distinct:
            return list(map(convert, column))
        return [convert(x) if x else empty for x in column]
    except (ValueError, OverflowError):
        return None


# A receiver repeats one epoch's time and position in several sentences (GGA,
# RMC, GLL, GST, ZDA): a small cache turns the repeats into a dict hit (0.05 us
# instead of 0.5). Failures raise again each time: exceptions are not cached.
@lru_cache(maxsize=64)
def parse_tod(s: str) -> float:
    """Seconds of day from hhmmss[.sss]; NaN when empty."""
    if not s:
        return NAN
    if len(s) < 6 or not s[:6].isdigit():
        raise ValueError(f"time {s!r} is not hhmmss.ss")
    v = float(s)  # one float() and arithmetic: much cheaper than three slices and conversions
    h, rest = divmod(v, 10000.0)
    m, sec = divmod(rest, 100.0)
    if not (h <= 23 and m <= 59 and sec < 61.0):  # so written, an overflow to NaN is out of range too
        raise ValueError(f"time {s[:40]!r} out of range")
    return h * 3600.0 + m * 60.0 + sec


def _codes(column: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(n, width) code points of the strings (0 past each end) and their lengths."""
    lengths = np.fromiter(map(len, column), dtype=np.int64, count=len(column))
    arr = np.array(column)
    width = max(arr.dtype.itemsize // 4, 1)
    codes = (arr.view(np.uint32).reshape(len(column), -1) if arr.dtype.itemsize
             else np.zeros((len(column), 1), np.uint32))
    return codes[:, :width], lengths


def tod_column(column: list[str]) -> np.ndarray | None:
    """`parse_tod` of every string (all non-empty), or None where it would not simply succeed."""
    if not column:
        return np.zeros(0)
    codes, lengths = _codes(column)
    if codes.shape[1] < 6 or (lengths < 6).any():
        return None
    head = codes[:, :6]
    if ((head < 48) | (head > 57)).any():
        return None
    values = _convert(float, column, NAN, set(column))  # digits checked above: the number rule holds
    if values is None:
        return None
    v = np.array(values, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # an overflow to inf gives NaN, refused below
        h, rest = np.divmod(v, 10000.0)
        m, sec = np.divmod(rest, 100.0)
    if not ((h <= 23) & (m <= 59) & (sec < 61.0)).all():
        return None
    return h * 3600.0 + m * 60.0 + sec


def parse_angle(s: str, hemi: str, neg: str, limit: float) -> float:
    """Degrees from NMEA (d)ddmm.mmmm plus hemisphere; NaN when empty."""
    if not s:
        return NAN
    if not s.replace(".", "", 1).isdigit():
        raise ValueError(f"angle {s!r} is not (d)ddmm.mmmm")
    dot = s.find(".")
    if (dot if dot >= 0 else len(s)) < 3:
        # some receivers and converters write decimal degrees ('37.352387'); read
        # as ddmm that is 0°37' -- thousands of km off without a sign of error
        raise ValueError(f"angle {s!r} has no degrees before mm.mmmm (decimal degrees?)")
    v = float(s)
    deg = v // 100.0
    minutes = v - deg * 100.0  # exact: both terms are within a factor of two (Sterbenz)
    value = deg + minutes / 60.0
    if not (minutes < 60.0 and value <= limit):  # NaN (400 digits overflow to inf, then NaN) is out of range
        raise ValueError(f"angle {s[:40]!r} out of range")
    if hemi == neg:
        return -value
    if hemi and hemi not in "NE":
        raise ValueError(f"hemisphere {hemi!r}")
    return value


@lru_cache(maxsize=64)
def parse_lat(s: str, hemi: str) -> float:
    """A latitude field and its N/S letter in degrees; NaN when empty."""
    return parse_angle(s, hemi, "S", 90.0)


@lru_cache(maxsize=64)
def parse_lon(s: str, hemi: str) -> float:
    """A longitude field and its E/W letter in degrees; NaN when empty."""
    return parse_angle(s, hemi, "W", 180.0)


def angle_column(column: list[str], hemis: list[str], neg: str, limit: float) -> np.ndarray | None:
    """`parse_angle` of every (d)ddmm.mmmm string and hemisphere letter (empty: NaN), or None."""
    if not column:
        return np.zeros(0)
    codes, lengths = _codes(column)
    digit = (codes >= 48) & (codes <= 57)
    dot = codes == 46
    if not np.array_equal((digit | dot).sum(axis=1), lengths) or (dot.sum(axis=1) > 1).any():
        return None
    has = lengths > 0
    dot_at = np.where(dot.any(axis=1), dot.argmax(axis=1), lengths)
    if (has & (dot_at < 3)).any():
        return None
    values = _convert(float, column, NAN, set(column))  # digits and one dot checked above
    if values is None:
        return None
    v = np.array(values, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # an overflow to inf gives NaN, refused below
        deg = np.floor_divide(v, 100.0)
        minutes = v - deg * 100.0
        value = deg + minutes / 60.0
    if (has & ~((minutes < 60.0) & (value <= limit))).any():
        return None
    south = np.array([h == neg for h in hemis], dtype=bool)
    if not all(h in ("", "N", "E", "NE", neg) for h in set(hemis)):
        return None  # `parse_angle` accepts exactly these letters ('NE' too: it tests `in "NE"`)
    return np.where(south & has, -value, value)


@lru_cache(maxsize=16)  # one date per day of log: a dict hit instead of a date() per RMC
def parse_ddmmyy(s: str) -> date | None:
    """RMC's ddmmyy date; None when empty."""
    if not s:
        return None
    if len(s) != 6 or not s.isdigit():
        raise ValueError(f"date {s!r} is not ddmmyy")
    yy = int(s[4:6])
    # two-digit years: 80..99 -> 1980s/90s (GPS did not exist before 1980)
    return date(2000 + yy if yy < 80 else 1900 + yy, int(s[2:4]), int(s[0:2]))


@lru_cache(maxsize=16)
def parse_zda_date(year: str, month: str, day: str) -> date:
    """ZDA's date from its three fields (all non-empty)."""
    return date(int(year), int(month), int(day))
