"""NovAtel ASCII logs of a clean file as numpy columns (the whole-file fast path of `novatel.scan`).

A file is *clean* when it holds no binary log and every non-empty line is a
long-header ASCII log ``#NAMEA,...;...*xxxxxxxx`` (LF or CRLF, one '#', one
';', one '*' and eight hex digits at the end, CRC right, ten header fields),
each known log with its usual number of fields. The framing, the field counts
and the CRC comparison run once over the buffer with numpy (the CRC itself is
zlib's, one C call a line); the fields of all logs of one name come out of one
join and one split, and each field column is converted at once with Python's
own `float` (a map over the column) or, for status words and counts, the very
per-field rule once per distinct string. `decode_columns` gives what
`scan.scan` would give for such a file, as columns; any other file, or one
holding a value the per-line parsers might refuse or read otherwise, gets
None, and the caller takes the per-line path, which decides every kind of
damage (tests/test_novatel_columns.py holds the two together on damaged files).
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..numbers import HEX_VALUE, finite, integer, optional_integer
from . import logs as N
from .scan import _enum, _hex

NAN = float("nan")
NAMES = ("BESTPOS", "BESTVEL", "INSPVA", "INSPVAS", "INSPVAX")
_CODE = {name: code for code, name in enumerate(NAMES)}
# value fields of a clean log (after ';', before '*'): the ones the manuals list, reserved ones included
_WIDTH = {"BESTPOS": 21, "BESTVEL": 8, "INSPVA": 12, "INSPVAS": 12, "INSPVAX": 23}
_FLOAT = "float"  # a number field: `formats.numbers.optional` (finite, NaN when empty), a column at once


def _strip_quotes(s: str) -> str:
    return s.strip('"')


def _same(s: str) -> str:
    return s


_SS, _PT, _INS = (partial(_enum, table=t) for t in (N.SOLUTION_STATUS, N.POSITION_TYPE, N.INS_STATUS))
# per log name: (body field index, its rule) for each record field after `header`, in the record's order
# (`scan.VALUES`' parsers, field by field)
_SPEC: dict[str, tuple[tuple[int, Callable[[str], object] | str], ...]] = {
    "BESTPOS": ((0, _SS), (1, _PT), *((k, _FLOAT) for k in range(2, 6)), (6, _same),
                *((k, _FLOAT) for k in range(7, 10)), (10, _strip_quotes), (11, _FLOAT), (12, _FLOAT),
                *((k, optional_integer) for k in range(13, 17)), (18, _hex), (19, _hex), (20, _hex)),
    "BESTVEL": ((0, _SS), (1, _PT), *((k, _FLOAT) for k in range(2, 7))),
    "INSPVA": ((0, partial(integer, name="week")), (1, partial(finite, name="seconds")),
               *((k, _FLOAT) for k in range(2, 11)), (11, _INS)),
    "INSPVAX": ((0, _INS), (1, _PT), *((k, _FLOAT) for k in range(2, 21)), (21, _hex), (22, optional_integer)),
}
_SPEC["INSPVAS"] = _SPEC["INSPVA"]


@dataclass(frozen=True, slots=True)
class NovatelColumns:
    """A clean file's known logs in file order: name code, record time, byte offset, line number; values per name.

    `values[name]` holds one column per record field after `header` (the order of `scan`'s value tuples):
    a float64 array for number fields, a list for the others; `rows[name]` the logs of that name.
    """

    code: np.ndarray     # index into NAMES
    week: np.ndarray     # GPS week of the record's time (INSPVA: its own, else the header's)
    seconds: np.ndarray  # GPS seconds of week of the same
    offsets: np.ndarray  # byte offset of each log's line
    numbers: np.ndarray  # 1-based line number of each log
    rows: dict[str, np.ndarray]
    values: dict[str, list[np.ndarray | list]]


def _by_distinct(rule: Callable[[str], object], column: list[str]) -> list:
    """rule() of every string, run once per distinct string (a log repeats its statuses and counts)."""
    table = {s: rule(s) for s in set(column)}
    return list(map(table.__getitem__, column))


def _floats(column: list[str]) -> np.ndarray:
    """`formats.numbers.optional` of every string (float(), NaN when empty); ValueError where it refuses one."""
    try:
        if len(set(column[:64])) <= 8:  # sigmas, undulations: each distinct string converted once
            table = {s: float(s) for s in set(column)}
            values = np.fromiter(map(table.__getitem__, column), dtype=np.float64, count=len(column))
        else:
            values = np.fromiter(map(float, column), dtype=np.float64, count=len(column))
        given = None
    except ValueError:  # an empty field (NaN) or no number at all
        values = np.array([float(s) if s else NAN for s in column], dtype=np.float64)
        given = np.array([bool(s) for s in column])
    bad = ~np.isfinite(values)
    if given is not None:
        bad &= given
    if bad.any():
        raise ValueError("a number field is not finite")
    return values


def _check_headers(heads: list[str]) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Names, weeks and seconds of long headers, each field checked as `scan._fast_line` checks it (ValueError,
    IndexError or OverflowError where it would leave the line to the reference)."""
    flat = ",".join(heads).split(",")
    h = [flat[k::10] for k in range(10)]
    for s in set(h[0]):
        if not s[:1].isupper():
            raise ValueError("no log name")
    for k, rule in ((2, int), (3, finite), (7, partial(int, base=16)), (8, partial(int, base=16)), (9, int)):
        for s in set(h[k]):
            if s or k == 2:
                rule(s)
    weeks = _by_distinct(partial(integer, name="week"), h[5])
    seconds = _floats(h[6]) if "" not in h[6] else np.array([finite(s) for s in h[6]])
    names = [s[:-1] if s[-1:] == "A" else s for s in h[0]]
    return names, np.array(weeks, dtype=np.int64), seconds


def decode_columns(data: bytes, binary_checked: bool = False) -> NovatelColumns | None:
    """A clean file's BESTPOS, BESTVEL, INSPVA(S) and INSPVAX logs as columns, or None when the per-line path
    (`scan.scan`) must read it. Logs of other names with a good CRC are dropped, as `scan` drops them.
    `binary_checked`: the caller knows the data holds no binary log's sync."""
    buf = np.frombuffer(data, dtype=np.uint8)
    if not len(buf) or (not binary_checked and N._next_sync(data, 0) >= 0):
        return None
    nl = np.flatnonzero(buf == 10)
    starts = np.concatenate(([0], nl + 1))
    lens = np.concatenate((nl, [len(buf)])) - starts
    cr = (lens > 0) & (buf[np.minimum(starts + lens - 1, len(buf) - 1)] == 13)
    size = lens - cr
    idx = np.flatnonzero(size > 0)  # empty lines are skipped by the per-line path too
    if not len(idx):
        return None
    s, e = starts[idx], starts[idx] + size[idx]  # each log's '#' and the end of its CRC
    if (size[idx] < 12).any():
        return None
    star = e - 9
    semi = np.flatnonzero(buf == 59)
    for ch, where in ((35, s), (42, star)):
        pos = np.flatnonzero(buf == ch)
        if len(pos) != len(idx) or not np.array_equal(pos, where):
            return None
    if len(semi) != len(idx) or not ((semi > s + 1) & (semi < star)).all():
        return None  # exactly one ';' in each line, after a name
    digits = HEX_VALUE[buf[star[:, None] + np.arange(1, 9)]]
    if (digits < 0).any():
        return None
    given = (digits << (4 * np.arange(7, -1, -1))).sum(axis=1)
    mv = memoryview(data)
    computed = np.fromiter((zlib.crc32(mv[a:b], 0xFFFFFFFF) for a, b in zip((s + 1).tolist(), star.tolist())),
                           dtype=np.int64, count=len(s)) ^ 0xFFFFFFFF
    if not np.array_equal(given, computed):
        return None  # a bad CRC: a Reject, the per-line path's job
    commas = np.flatnonzero(buf == 44)
    at_semi = np.searchsorted(commas, semi)
    if not (at_semi - np.searchsorted(commas, s) == 9).all():
        return None  # not a long header of ten fields
    body_commas = np.searchsorted(commas, star) - at_semi
    text = data.decode("latin-1")
    heads = [text[a:b] for a, b in zip((s + 1).tolist(), semi.tolist())]
    try:
        names, weeks, seconds = _check_headers(heads)
    except (ValueError, IndexError, OverflowError):
        return None
    code_of = {n: _CODE.get(n, -1) for n in set(names)}
    code = np.fromiter(map(code_of.__getitem__, names), dtype=np.int64, count=len(names))
    kept = np.flatnonzero(code >= 0)
    rows: dict[str, np.ndarray] = {}
    values: dict[str, list[np.ndarray | list]] = {}
    week, sow = weeks[kept], seconds[kept]
    for c in np.unique(code[kept]).tolist():
        name = NAMES[c]
        pos = np.flatnonzero(code[kept] == c)
        at = kept[pos]
        if (body_commas[at] != _WIDTH[name] - 1).any():
            return None  # a log with fields missing or extra: the per-line parser decides
        flat = ",".join([text[a:b] for a, b in zip((semi[at] + 1).tolist(), star[at].tolist())]).split(",")
        width = _WIDTH[name]
        try:
            cols = [_floats(flat[k::width]) if rule == _FLOAT else _by_distinct(rule, flat[k::width])  # type: ignore[arg-type]
                    for k, rule in _SPEC[name]]
        except (ValueError, IndexError, OverflowError):
            return None
        if name in ("INSPVA", "INSPVAS"):  # the record's own time
            week[pos] = np.array(cols[0], dtype=np.int64) if max(map(abs, cols[0])) < 1 << 62 else 0
            sow[pos] = cols[1]
        rows[name], values[name] = pos, cols
    return NovatelColumns(code[kept], week, sow, s[kept], idx[kept] + 1, rows, values)
