"""Splitting text logs into lines as real loggers write them.

Handles CRLF or LF endings, bytes that are not text (decoded as latin-1 so
nothing is lost), and optional host-timestamp prefixes that data loggers put
before each record: ISO 8601 (``2016-10-12T08:00:01.250Z``, optionally in
brackets) or Unix seconds (``1476259201.250``).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime

from .log_blocks import LogText, blocks_in
from .records import Where
from .units import NS

PREFIX_STYLES = ("auto", "none", "iso8601", "unix")

_ISO = re.compile(
    r"\[?(\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}:\d{2}(?:[.,]\d+)?)(Z|[+-]\d{2}:?\d{2})?\]?[ \t,;|]*"
)
_UNIX = re.compile(r"\[?(\d{9,10}(?:\.\d+)?)\]?[ \t,;|]+")


@dataclass(frozen=True, slots=True)
class Line:
    """One line's text (prefix and line ending removed) and where it came from."""

    text: str
    where: Where


def _iso_to_ns(stamp: str, zone: str | None) -> int:
    stamp = stamp.replace(",", ".").replace(" ", "T")
    whole, _, frac = stamp.partition(".")
    dt = datetime.fromisoformat(whole)
    if zone and zone != "Z":
        dt = dt.replace(tzinfo=datetime.fromisoformat("2000-01-01T00:00:00" + zone).tzinfo)
    else:
        dt = dt.replace(tzinfo=UTC)
    frac_ns = int((frac + "000000000")[:9]) if frac else 0
    return int(dt.timestamp()) * NS + frac_ns


def _unix_to_ns(stamp: str) -> int:
    whole, _, frac = stamp.partition(".")
    return int(whole) * NS + (int((frac + "000000000")[:9]) if frac else 0)


def strip_prefix(text: str, style: str = "auto") -> tuple[str, int | None]:
    """Remove a host-timestamp prefix; returns the rest and the host time in ns (or None)."""
    if style == "none":
        return text, None
    if style in ("auto", "iso8601"):
        m = _ISO.match(text)
        if m:
            try:
                return text[m.end() :], _iso_to_ns(m.group(1), m.group(2))
            except ValueError:
                pass
    if style in ("auto", "unix"):
        m = _UNIX.match(text)
        if m:
            return text[m.end() :], _unix_to_ns(m.group(1))
    return text, None


def iter_lines(data: LogText, prefix: str = "auto") -> Iterator[Line]:
    """Yield every non-empty line with its byte offset, line number and host time in the log (whole or in blocks)."""
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    for block in blocks_in(data):
        offset = block.offset
        for number, raw in enumerate(block.data.split(b"\n"), start=block.lines + 1):
            start = offset
            offset += len(raw) + 1
            text = raw.decode("latin-1").rstrip("\r")
            if not text.strip():
                continue
            rest, host_ns = strip_prefix(text, prefix)
            yield Line(rest, Where(start, number, host_ns))
