"""NMEA sentences of a clean log as numpy columns (the whole-log fast path of `sentences.scan`).

`decode_columns` gives, for a log whose every line is a clean sentence (see
`formats.nmea.clean`) of types GGA (14 fields), GST (8), RMC (12),
VTG (9, with unit letters), GLL (7), ZDA (6), HDT (2) and THS (2), from
any talker, with sentences of other families among them, the values
`sentences.scan` would give, as one array per field. It returns None for any other
log, or when one value is anything the per-line parsers might reject: the
caller then takes the per-line path, which decides every kind of damage.
Sentences of other families are dropped, as `scan` does; a malformed address
is a Reject there, so it makes the log unclean here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .clean import CleanLines, clean_lines, field_table, select
from .counts import BLANK, IGNORED, USED, SentenceCounts, skipped_outcome
from .fields import (
    NAN,
    angle_column,
    number_column,
    parse_ddmmyy,
    parse_zda_date,
    tod_column,
)
from .sentences import VALUES

KINDS = ("GGA", "GST", "RMC", "VTG", "GLL", "ZDA", "HDT", "THS")  # kind codes 0..7
_WIDTH = {"GGA": 15, "GST": 9, "RMC": 13, "VTG": 10, "GLL": 8, "ZDA": 7, "HDT": 3, "THS": 3}  # with the address
_TIME = {"GGA": 0, "GST": 0, "RMC": 0, "GLL": 4, "ZDA": 0}  # field of the time of day; the others have none
# The column parsers below read field k of a sentence as f[k], the numbering of `sentences`' per-line
# parsers (fields after the address), so the two readings of a sentence line up field by field.


@dataclass(frozen=True, slots=True)
class NmeaColumns:
    """Sentences of a clean log in file order: kind code, time of day, position in the log; values per kind."""

    kind: np.ndarray  # index into KINDS
    tod: np.ndarray  # seconds of the UTC day; NaN for the types without a time (VTG, HDT, THS)
    offsets: np.ndarray
    numbers: np.ndarray
    rows: dict[str, np.ndarray]  # kind -> its sentences' positions in file order
    values: dict[str, dict[str, np.ndarray | list]]  # kind -> field name -> one value per sentence
    lines: Lines  # every line of the log, by address, for `count_sentences`


@dataclass(frozen=True, slots=True)
class Lines:
    """A clean log's sentence lines by address: the distinct addresses, each line's, its line number."""

    addresses: list[str]
    used: list[bool]  # per address: a type of ours (KINDS), else skipped
    code: np.ndarray  # per sentence line: index into `addresses`
    numbers: np.ndarray  # per sentence line: its 1-based line number
    count: int  # lines of the log, blank ones too


def _address_ok(key: bytes) -> bool:
    address = key[:5].decode("latin-1")
    return address.isascii() and address.isalnum() and address.isupper()


def _gga(f: list[list[str]]) -> dict | None:
    cols = {
        "lat": angle_column(f[1], f[2], "S", 90.0), "lon": angle_column(f[3], f[4], "W", 180.0),
        "quality": number_column(int, f[5], -1), "satellites": number_column(int, f[6], -1),
        "hdop": number_column(float, f[7], NAN), "alt": number_column(float, f[8], NAN),
        "sep": number_column(float, f[10], NAN), "age": number_column(float, f[12], NAN),
    }
    return None if any(v is None for v in cols.values()) else cols


def _gst(f: list[list[str]]) -> dict | None:
    cols = {name: number_column(float, f[k], NAN) for k, name in enumerate(
        ("rms", "major", "minor", "orient", "lat_std", "lon_std", "alt_std"), start=1)}
    return None if any(v is None for v in cols.values()) else cols


def _rmc(f: list[list[str]]) -> dict | None:
    try:
        dates = list(map(parse_ddmmyy, f[8]))
    except (ValueError, IndexError, OverflowError):
        return None
    cols = {
        "valid": np.array([s == "A" for s in f[1]], dtype=bool),
        "lat": angle_column(f[2], f[3], "S", 90.0), "lon": angle_column(f[4], f[5], "W", 180.0),
        "speed": number_column(float, f[6], NAN), "course": number_column(float, f[7], NAN),
        "date": dates, "variation": number_column(float, f[9], NAN),
    }
    return None if any(v is None for v in cols.values()) else cols


def _vtg(f: list[list[str]]) -> dict | None:
    # `sentences._vtg` reads the unit-letter layout unless both letters are odd: only that layout here
    if not all((t in ("T", "") and m in ("M", "")) or t == "T" or m == "M" for t, m in set(zip(f[1], f[3]))):
        return None
    cols: dict = {name: number_column(float, f[k], NAN) for k, name in
                  ((0, "course"), (2, "course_magnetic"), (4, "speed"), (6, "kmh"))}
    cols["mode"] = f[8]
    return None if any(v is None for v in cols.values()) else cols


def _gll(f: list[list[str]]) -> dict | None:
    cols = {
        "lat": angle_column(f[0], f[1], "S", 90.0), "lon": angle_column(f[2], f[3], "W", 180.0),
        "valid": np.array([s == "A" for s in f[5]], dtype=bool),
    }
    return None if any(v is None for v in cols.values()) else cols


def _zda(f: list[list[str]]) -> dict | None:
    try:  # one date() per distinct (day, month, year): a log holds one or two
        table = {k: parse_zda_date(k[2], k[1], k[0]) if k[0] and k[1] and k[2] else None
                 for k in set(zip(f[1], f[2], f[3]))}
    except (ValueError, OverflowError):
        return None
    cols = {"date": list(map(table.__getitem__, zip(f[1], f[2], f[3]))),
            "zone_hours": number_column(int, f[4], -1), "zone_minutes": number_column(int, f[5], -1)}
    return None if any(v is None for v in cols.values()) else cols


def _hdt(f: list[list[str]]) -> dict | None:
    heading = number_column(float, f[0], NAN)
    return None if heading is None else {"heading": heading}


def _ths(f: list[list[str]]) -> dict | None:
    heading = number_column(float, f[0], NAN)
    return None if heading is None else {"heading": heading, "mode": f[1]}


_PARSE = {"GGA": _gga, "GST": _gst, "RMC": _rmc, "VTG": _vtg, "GLL": _gll, "ZDA": _zda, "HDT": _hdt, "THS": _ths}


def _kinds(clean: CleanLines) -> tuple[np.ndarray, np.ndarray, Lines] | None:
    """(kept line positions, kind code of each, every line by address) or None when a line needs the per-line
    path."""
    keys, inverse = np.unique(clean.heads(6), return_inverse=True)
    code_of = np.full(len(keys), -1, dtype=np.int64)
    for j, key in enumerate(keys.tolist()):
        kind = key[2:5].decode("latin-1")
        if len(key) < 6 or key[5:6] != b"," or not _address_ok(key):
            return None  # an address of another length, or malformed: the per-line path decides
        if key[:1] == b"P" or kind not in VALUES:
            code_of[j] = -2  # another family's sentence: skipped, as `scan` does
        elif kind in KINDS:
            code_of[j] = KINDS.index(kind)
        else:
            return None  # a sentence type of ours this fast path does not handle
    inverse = inverse.ravel()
    codes = code_of[inverse]
    kept = np.flatnonzero(codes >= 0)
    lines = Lines([key[:5].decode("latin-1") for key in keys.tolist()], (code_of >= 0).tolist(), inverse,
                  clean.numbers, clean.count)
    return kept, codes[kept], lines


def decode_columns(data: bytes) -> NmeaColumns | None:
    """Sentence values of a clean log as columns, or None when the per-line path must decode it."""
    clean = clean_lines(data)
    if clean is None:
        return None
    found = _kinds(clean)
    if found is None:
        return None
    kept, kind, lines = found
    tod = np.full(len(kept), NAN)
    rows, values = {}, {}
    for code, name in enumerate(KINDS):
        pos = np.flatnonzero(kind == code)
        idx = kept[pos]
        table = field_table(select(clean.lines, idx), _WIDTH[name] + 1)
        if table is None:
            return None
        at = _TIME.get(name)
        fields = table[1:]  # without the address column
        times = tod_column(fields[at]) if at is not None else None
        cols = _PARSE[name](fields)
        if (at is not None and times is None) or cols is None:
            return None
        if times is not None:
            tod[pos] = times
        rows[name], values[name] = pos, cols
    return NmeaColumns(kind, tod, clean.offsets[kept], clean.numbers[kept], rows, values, lines)


def head(cols: NmeaColumns, k: int) -> NmeaColumns:
    """The first `k` sentences of `cols` (a block's columns without the epoch that may go on in the next block)."""
    rows, values = {}, {}
    for name, pos in cols.rows.items():
        n = int(np.searchsorted(pos, k))
        rows[name] = pos[:n]
        values[name] = {field: column[:n] for field, column in cols.values[name].items()}
    return NmeaColumns(cols.kind[:k], cols.tod[:k], cols.offsets[:k], cols.numbers[:k], rows, values, cols.lines)


def count_sentences(cols: NmeaColumns, counts: SentenceCounts, upto: int | None = None) -> None:
    """Count the lines of a clean log's columns before line `upto` (1-based; None: all of them) into `counts`."""
    lines = cols.lines
    n = len(lines.code) if upto is None else int(np.searchsorted(lines.numbers, upto))
    before = lines.count if upto is None else upto - 1
    per = np.bincount(lines.code[:n], minlength=len(lines.addresses)).tolist()
    for outcome, take in ((USED, True), (None, False)):
        table = {a: k for a, k, used in zip(lines.addresses, per, lines.used) if k and used == take}
        if outcome is not None:
            counts.merge(outcome, table)
        else:
            for a, k in table.items():
                counts.add(skipped_outcome(a), a, k)
    counts.add(IGNORED, BLANK, before - n)
