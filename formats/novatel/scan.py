"""NovAtel logs as plain tuples for converters on the hot path: what `novatel.decode` yields, without records.

The common line -- ``#NAMEA,...;...*crc`` at the start of a line, CRC good,
every field as the reference reads it -- is parsed here straight into the
values; any line this path does not take on trust (a short or binary
header, a prefix, a bad CRC, a field that does not convert) goes through
`novatel.parse_ascii` itself, and files holding binary logs through
`novatel.decode`, so rejects are exactly the reference's
(tests/test_novatel_scan.py checks both on any bytes).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import fields
from typing import Literal

from ..lines import PREFIX_STYLES, strip_prefix
from ..numbers import finite, integer, optional, optional_integer
from ..records import Reject, Where
from ..scanned import values_view
from . import logs as N

NAN = float("nan")

# (log name, source as 'BESTPOSA' / 'INSPVAB', GPS week, seconds of week, values in record field order
# after `header`, byte offset, line or None, host time ns or None); week and seconds are the record's
# time (INSPVA: its own, else the header's: `novatel.record_time_ns`)
Scanned = tuple[str, str, int, float, tuple, int, int | None, int | None]


# `BEST_POS._make(item[4])` names a scanned BESTPOS's values as the record does
BEST_POS, BEST_VEL, INS_PVA, INS_PVAX = (values_view(r) for r in (N.BestPos, N.BestVel, N.InsPva, N.InsPvax))


def where_of(item: Scanned) -> Where:
    """Where a scanned log was read."""
    return Where(item[5], item[6], item[7])


KINDS = {"BESTPOS": "BestPos", "BESTVEL": "BestVel", "INSPVA": "InsPva", "INSPVAS": "InsPva", "INSPVAX": "InsPvax"}


_f = optional  # number fields: finite, NaN when empty (formats.numbers)


def _hex(s: str) -> int:
    return integer(s, "field", 16) if s else 0


def _enum(s: str, table: dict[int, str]) -> str:
    return table.get(int(s), s) if s.isdigit() else s


def _bestpos(f: list[str]) -> tuple:
    if len(f) < 15:
        raise IndexError("short")
    opt = f + [""] * (21 - len(f))
    # inline conversions: BESTPOS is the hot log of a GNSS file
    return (
        _enum(f[0], N.SOLUTION_STATUS), _enum(f[1], N.POSITION_TYPE), _f(f[2]),
        _f(f[3]), _f(f[4]), _f(f[5]), f[6],
        _f(f[7]), _f(f[8]), _f(f[9]), f[10].strip('"'),
        _f(f[11]), _f(f[12]), optional_integer(f[13]),
        optional_integer(f[14]), optional_integer(opt[15]), optional_integer(opt[16]),
        _hex(opt[18]), _hex(opt[19]), _hex(opt[20]),
    )


def _bestvel(f: list[str]) -> tuple:
    if len(f) < 7:
        raise IndexError("short")
    return (_enum(f[0], N.SOLUTION_STATUS), _enum(f[1], N.POSITION_TYPE), _f(f[2]), _f(f[3]), _f(f[4]), _f(f[5]),
            _f(f[6]))


def _inspva(f: list[str]) -> tuple:
    if len(f) < 12:
        raise IndexError("short")
    return (integer(f[0], "week"), finite(f[1], "seconds"), *map(_f, f[2:11]), _enum(f[11], N.INS_STATUS))


def _inspvax(f: list[str]) -> tuple:
    if len(f) < 21:
        raise IndexError("short")
    opt = f + [""] * (23 - len(f))
    return (_enum(f[0], N.INS_STATUS), _enum(f[1], N.POSITION_TYPE), *_numbers(f[2:21]),
            _hex(opt[21]), optional_integer(opt[22]))


def _numbers(texts: list[str]) -> tuple[float, ...] | map[float]:
    """`_f` of each text: with every one given and their sum finite, one float() each and no call per field."""
    try:
        values = tuple(map(float, texts))
    except ValueError:  # an empty field (NaN) or no number: the number rule, field by field
        return map(_f, texts)
    total = sum(values)
    return values if total - total == 0.0 else map(_f, texts)  # NaN or an infinity among them: named there


VALUES: dict[str, Callable[[list[str]], tuple]] = {
    "BESTPOS": _bestpos, "BESTVEL": _bestvel, "INSPVA": _inspva, "INSPVAS": _inspva, "INSPVAX": _inspvax,
}
_SLOW: Literal[False] = False  # "let the reference parse this line"


def _fast_line(text: str, where: tuple[int, int | None]) -> Scanned | None | Literal[False]:
    """A long-header ASCII log at the start of `text`; None for other logs; _SLOW for anything unusual."""
    star = text.rfind("*")
    semi = text.find(";", 0, star) if star > 0 else -1
    if semi < 0 or not text[1:2].isupper():
        return _SLOW
    given = text[star + 1 : star + 9]
    try:
        if len(given) != 8 or int(given, 16) != N.crc32(text[1:star].encode("latin-1")):
            return _SLOW
        h = text[1:semi].split(",")
        if len(h) != 10:
            return _SLOW
        # every header field converted as `novatel._ascii_header` does: a field it rejects, we leave to it
        week, seconds = integer(h[5], "week"), finite(h[6], "seconds")
        int(h[2]), h[3] and finite(h[3]), h[7] and int(h[7], 16), h[8] and int(h[8], 16), h[9] and int(h[9])
        name = h[0][:-1] if h[0][-1:] == "A" else h[0]
        parser = VALUES.get(name)
        if parser is None:
            return None
        values = parser(text[semi + 1 : star].split(","))
    except (ValueError, IndexError, OverflowError):
        return _SLOW
    if name == "INSPVA" or name == "INSPVAS":
        week, seconds = values[0], values[1]
    return name, name + "A", week, seconds, values, where[0], where[1], None


def from_record(rec: N.NovatelRecord) -> Scanned:
    """The scanned tuple of a decoded record."""
    h, w = rec.header, rec.where
    values = tuple(getattr(rec, f.name) for f in fields(rec)[2:])
    week, seconds = (rec.week, rec.seconds) if isinstance(rec, N.InsPva) else (h.week, h.seconds)
    source = h.message + ("B" if h.encoding.startswith("binary") else "A")
    return h.message, source, week, seconds, values, w.offset, w.line, w.host_time_ns


def scan(data: bytes, prefix: str = "auto", start: tuple[int, int] = (0, 1)) -> Iterator[Scanned | Reject]:
    """What `novatel.decode` yields, as `Scanned` tuples instead of records; from `start` (the byte offset and
    1-based number of a line) on, in a file without binary logs."""
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    if N._next_sync(data, 0) >= 0:  # binary logs in the file: ASCII lines are located by offset only
        for rec in N.decode(data, prefix):
            yield rec if isinstance(rec, Reject) else from_record(rec)
        return
    offset = start[0]
    for number, raw in enumerate(data[offset:].decode("latin-1").split("\n"), start=start[1]):
        line_start = offset
        offset += len(raw) + 1
        fast = _fast_line(raw.rstrip("\r"), (line_start, number)) if raw[:1] == "#" else _SLOW
        item = _slow_line(raw, line_start, number, prefix) if fast is False else fast
        if item is not None:
            yield item


def _slow_line(raw: str, line_start: int, number: int, prefix: str) -> Scanned | Reject | None:
    """One line the way `novatel._text_records` reads it."""
    line = raw.rstrip("\r")
    if not line.strip():
        return None
    host = None
    if prefix != "none" and line[0] not in "#%$":
        line, host = strip_prefix(line, prefix)
    result = N.parse_ascii(line, Where(line_start, number, host))
    if result is None or isinstance(result, Reject):
        return result
    return from_record(result)
