"""User-defined regex line format: the documented ATM-88x-style example, times, errors."""

from __future__ import annotations

from datetime import date

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import regex_lines as rx
from formats.records import FormatError, Reject


def test_documented_benthos_style_example() -> None:
    data = b"12:00:05.200 Range 1 to 2 : 500.1 m (Round-trip 666.8 ms)\r\n"
    (rec,) = rx.decode(data, rx.EXAMPLE_PATTERN, "tod", travel_time_scale=rx.EXAMPLE_SCALE)
    assert isinstance(rec, rx.RegexRecord)
    assert rec.tod_s == pytest.approx(12 * 3600 + 5.2)
    assert (rec.source, rec.destination) == ("2", "1")
    # 666.8 ms round trip -> 0.3334 s one way
    assert rec.travel_time_s == pytest.approx(0.3334)
    assert rec.time_ns is None and rec.groups["travel_time_s"] == "666.8"


def test_iso_unix_and_date_group() -> None:
    iso = rx.decode(b"2016-10-12T08:00:01.25Z src=3 tt=0.5\n", r"(?P<time>\S+) src=(?P<source>\d+) tt=(?P<travel_time_s>\S+)", "iso8601")
    (rec,) = iso
    assert rec.time_ns == 1476259201_250_000_000 and rec.travel_time_s == 0.5
    (rec,) = rx.decode(b"1476259201.5,3,750.0\n", r"(?P<time>[\d.]+),(?P<source>\d+),(?P<range_m>[\d.]+)", "unix")
    assert rec.time_ns == 1476259201_500_000_000 and rec.range_m == 750.0
    (rec,) = rx.decode(b"2016-10-13 235959.5 1 0.2\n", r"(?P<date>\S+) (?P<time>\S+) (?P<source>\d) (?P<travel_time_s>\S+)")
    assert rec.date == date(2016, 10, 13) and rec.tod_s == pytest.approx(86399.5)
    assert rx.parse_iso8601_ns("2016-10-12T10:00:00+02:00") == 1476259200_000_000_000
    (bad,) = rx.decode(b"99999999999999999999,3,1.0\n", r"(?P<time>\d+),(?P<source>\d+),(?P<range_m>\S+)", "unix")
    assert isinstance(bad, Reject) and "outside 1970-2200" in bad.reason


def test_no_match_bad_values_and_missing_time_group() -> None:
    pattern = r"R (?P<source>\d+) (?P<travel_time_s>\S+)"
    recs = list(rx.decode(b"hello\nR 2 abc\nR 2 -1\nR 2 0.25\n\x00\xff\n", pattern))
    assert [r.reason for r in recs if isinstance(r, Reject)] == [
        "no match", "bad field: could not convert string to float: 'abc'",
        "negative travel time or range", "no match",
    ]
    good = recs[3]
    assert isinstance(good, rx.RegexRecord) and good.tod_s is None and good.travel_time_s == 0.25


@pytest.mark.parametrize(
    ("pattern", "message"),
    [
        ("(?P<source>\\d+", "does not compile"),
        ("(?P<source>\\d+) (?P<x>.*)", "needs a named group 'travel_time_s' or 'range_m'"),
        ("", "non-empty string"),
        (None, "non-empty string"),
    ],
)
def test_pattern_errors_raise_format_error(pattern: object, message: str) -> None:
    with pytest.raises(FormatError, match=message):
        rx.compile_pattern(pattern)


def test_bad_options_raise_format_error() -> None:
    with pytest.raises(FormatError, match="time_format"):
        list(rx.decode(b"", r"(?P<range_m>\d+)", "gps"))
    with pytest.raises(FormatError, match="travel_time_scale"):
        list(rx.decode(b"", r"(?P<range_m>\d+)", "tod", travel_time_scale=-1))


@given(h=st.integers(0, 23), m=st.integers(0, 59), s=st.floats(0, 59.999), tt=st.floats(0, 10))
def test_tod_round_trip(h: int, m: int, s: float, tt: float) -> None:
    line = f"{h:02d}:{m:02d}:{s:06.3f} Range 1 to 2 : 1.0 m (Round-trip {tt * 2000:.4f} ms)"
    (rec,) = rx.decode(line.encode(), rx.EXAMPLE_PATTERN, travel_time_scale=rx.EXAMPLE_SCALE)
    assert isinstance(rec, rx.RegexRecord)
    assert rec.tod_s == pytest.approx(h * 3600 + m * 60 + round(s, 3), abs=1e-6)
    assert rec.travel_time_s == pytest.approx(tt, abs=1e-7)


@settings(max_examples=200)
@given(data=st.binary(max_size=300), fmt=st.sampled_from(rx.TIME_FORMATS))
def test_no_input_makes_the_decoder_raise(data: bytes, fmt: str) -> None:
    pattern = r"(?P<time>\S*) (?P<date>\S*) (?P<source>\S*) (?P<travel_time_s>\S*) (?P<range_m>\S*)"
    for rec in rx.decode(data, pattern, fmt):
        assert isinstance(rec, (Reject, rx.RegexRecord))
