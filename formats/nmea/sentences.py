"""NMEA 0183 GNSS sentences: GGA, RMC, ZDA, VTG, GST, HDT, THS, GLL from any talker.

Decoding follows NMEA 0183 v4.10 field layouts (the same ones gpsd's
"NMEA revealed" and the receiver manuals document). Real logs are messy, so:

- any talker is accepted (GP, GN, GL, GA, GB, IN, HE, unknown ones too);
  proprietary sentences (``$P...``), other standard types ($GPGSV, $GPGSA...)
  and NovAtel ``#``/``%`` logs in the same file are skipped silently: they
  belong to other decoders;
- a line with no sentence at all (binary noise, a half-written line) is a
  `Reject`; a failed checksum is a `Reject` with ``bad_checksum=True``;
  a missing checksum is accepted; hex digits may be lowercase;
- empty fields become NaN (floats) or -1 (counts), never zero;
- a latitude or longitude with fewer than three digits before the point
  ('37.352387': decimal degrees written by some converters) is a `Reject`,
  not 0°37'; a VTG that stops after the knots pair has NaN km/h;
- host-timestamp prefixes are removed with `formats.lines.strip_prefix`.

Checksums are checked against a prefix-XOR of the whole buffer computed once
with numpy, so the per-line cost is two byte lookups instead of a Python loop
(see bench/bench_nmea.py).

Encoders (for the trial simulator and the round-trip tests) take the UTC time
as integer nanoseconds and return a line ending in CRLF; empty fields are
written for NaN values.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass
from datetime import UTC, date, datetime

from ..lines import PREFIX_STYLES, strip_prefix
from ..log_blocks import Block, LogText, blocks_in
from ..records import Reject, Where
from .counts import (
    BAD_CHECKSUM,
    BLANK,
    IGNORED,
    NO_SENTENCE,
    NOVATEL,
    OUTCOMES,
    REJECTED,
    UNKNOWN,
    USED,
    SentenceCounts,
    skipped_outcome,
)
from .fields import (
    NAN,
    parse_ddmmyy,
    parse_float,
    parse_int,
    parse_lat,
    parse_lon,
    parse_tod,
    parse_zda_date,
)
from .framing import HEX, nmea_checksum, prefix_xor

KNOT_MPS = 1852.0 / 3600.0
_DAY_CS = 8_640_000  # centiseconds per day


@dataclass(frozen=True, slots=True)
class Gga:
    """GGA: fix time, position, quality, satellites, HDOP, altitude (MSL) and geoid separation."""

    where: Where
    talker: str
    time_s: float  # seconds of the UTC day; NaN when empty
    latitude: float
    longitude: float
    quality: int  # 0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 DR...; -1 empty
    satellites: int
    hdop: float
    altitude_msl_m: float
    geoid_separation_m: float
    dgps_age_s: float
    dgps_station: str


@dataclass(frozen=True, slots=True)
class Rmc:
    """RMC: time, validity, position, speed and course over ground, date, magnetic variation."""

    where: Where
    talker: str
    time_s: float
    valid: bool  # status 'A'
    latitude: float
    longitude: float
    speed_knots: float
    course_deg: float  # true
    date: date | None
    magnetic_variation_deg: float  # east positive
    mode: str  # NMEA 2.3+ mode indicator ('' before 2.3)


@dataclass(frozen=True, slots=True)
class Zda:
    """ZDA: UTC time and full date, local zone offset."""

    where: Where
    talker: str
    time_s: float
    date: date | None
    zone_hours: int
    zone_minutes: int


@dataclass(frozen=True, slots=True)
class Vtg:
    """VTG: course (true, magnetic) and speed over ground; carries no time of its own."""

    where: Where
    talker: str
    course_true_deg: float
    course_magnetic_deg: float
    speed_knots: float
    speed_kmh: float
    mode: str


@dataclass(frozen=True, slots=True)
class Gst:
    """GST: pseudorange error statistics; 1-sigma errors in metres, ellipse orientation from true north."""

    where: Where
    talker: str
    time_s: float
    rms_m: float
    semi_major_m: float
    semi_minor_m: float
    orientation_deg: float
    lat_std_m: float
    lon_std_m: float
    alt_std_m: float


@dataclass(frozen=True, slots=True)
class Hdt:
    """HDT: true heading in degrees; carries no time of its own."""

    where: Where
    talker: str
    heading_deg: float


@dataclass(frozen=True, slots=True)
class Ths:
    """THS: true heading and mode (A autonomous, E estimated, M manual, S simulator, V invalid)."""

    where: Where
    talker: str
    heading_deg: float
    mode: str


@dataclass(frozen=True, slots=True)
class Gll:
    """GLL: position, time and validity."""

    where: Where
    talker: str
    latitude: float
    longitude: float
    time_s: float
    valid: bool
    mode: str


NmeaRecord = Gga | Rmc | Zda | Vtg | Gst | Hdt | Ths | Gll
TIMED = (Gga, Rmc, Zda, Gst, Gll)


def _need(fields: list[str], n: int, kind: str) -> None:
    if len(fields) < n:
        raise IndexError(f"truncated {kind}: {len(fields)} fields, {n} needed")


def _opt(fields: list[str], i: int) -> str:
    return fields[i] if len(fields) > i else ""


# ---------------------------------------------------------------- per sentence
# Each parser turns the fields after the address into the record's values in
# field order (everything after `where` and `talker`): `scan()` hands these
# tuples to converters that need no record objects, `decode()` wraps them.


def _gga(f: list[str]) -> tuple:
    if len(f) < 9:  # checked inline: a call per sentence is a tenth of its parse
        _need(f, 9, "GGA")
    if len(f) < 14:
        f = f + [""] * (14 - len(f))
    # inline conversions: GGA is the hot sentence of every log
    return (
        parse_tod(f[0]), parse_lat(f[1], f[2]), parse_lon(f[3], f[4]), parse_int(f[5]),
        parse_int(f[6]), parse_float(f[7]), parse_float(f[8]),
        parse_float(f[10]), parse_float(f[12]), f[13],
    )


def _rmc(f: list[str]) -> tuple:
    if len(f) < 9:
        _need(f, 9, "RMC")
    if len(f) < 12:
        f = f + [""] * (12 - len(f))
    var = parse_float(f[9])
    return (
        parse_tod(f[0]), f[1] == "A", parse_lat(f[2], f[3]), parse_lon(f[4], f[5]), parse_float(f[6]),
        parse_float(f[7]), parse_ddmmyy(f[8]), -var if f[10] == "W" else var, f[11],
    )


def _zda(f: list[str]) -> tuple:
    if len(f) < 4:
        _need(f, 4, "ZDA")
    if len(f) < 6:
        f = f + [""] * (6 - len(f))
    day = parse_zda_date(f[3], f[2], f[1]) if f[1] and f[2] and f[3] else None
    return parse_tod(f[0]), day, parse_int(f[4]), parse_int(f[5])


def _vtg(f: list[str]) -> tuple:
    labelled = len(f) >= 7 and f[1] in ("T", "") and f[3] in ("M", "")
    if labelled or (len(f) >= 4 and (f[1] == "T" or f[3] == "M")):
        # some receivers stop after the knots pair ('$GPVTG,,T,,M,0.00,N'): km/h is then NaN
        return parse_float(f[0]), parse_float(_opt(f, 2)), parse_float(_opt(f, 4)), parse_float(_opt(f, 6)), _opt(f, 8)
    # NMEA 1.x layout without unit letters: course true, course magnetic, knots, km/h
    _need(f, 4, "VTG")
    return parse_float(f[0]), parse_float(f[1]), parse_float(f[2]), parse_float(f[3]), ""


def _gst(f: list[str]) -> tuple:
    if len(f) < 8:
        _need(f, 8, "GST")
    return (
        parse_tod(f[0]), parse_float(f[1]), parse_float(f[2]), parse_float(f[3]),
        parse_float(f[4]), parse_float(f[5]), parse_float(f[6]), parse_float(f[7]),
    )


def _hdt(f: list[str]) -> tuple:
    _need(f, 1, "HDT")
    return (parse_float(f[0]),)


def _ths(f: list[str]) -> tuple:
    _need(f, 2, "THS")
    return parse_float(f[0]), f[1]


def _gll(f: list[str]) -> tuple:
    if len(f) < 4:
        _need(f, 4, "GLL")
    if len(f) < 7:
        f = f + [""] * (7 - len(f))
    return parse_lat(f[0], f[1]), parse_lon(f[2], f[3]), parse_tod(f[4]), f[5] == "A", f[6]


VALUES: dict[str, Callable[[list[str]], tuple]] = {
    "GGA": _gga, "RMC": _rmc, "ZDA": _zda, "VTG": _vtg,
    "GST": _gst, "HDT": _hdt, "THS": _ths, "GLL": _gll,
}
RECORDS: dict[str, type] = {
    "GGA": Gga, "RMC": Rmc, "ZDA": Zda, "VTG": Vtg, "GST": Gst, "HDT": Hdt, "THS": Ths, "GLL": Gll,
}
# where the time of day sits in each sentence type's values (absent: the sentence has no time)
TIME_INDEX: dict[str, int] = {"GGA": 0, "RMC": 0, "ZDA": 0, "GST": 0, "GLL": 2}


def _record_parser(kind: str) -> Callable[[list[str], Where, str], NmeaRecord]:
    values, cls = VALUES[kind], RECORDS[kind]
    return lambda f, w, t: cls(w, t, *values(f))


PARSERS = {kind: _record_parser(kind) for kind in VALUES}


# ---------------------------------------------------------------- framing

Frame = tuple[str, list[str], Where]  # address, fields after it, where


def _looks_novatel(text: str) -> bool:
    for ch in "#%":
        i = text.find(ch)
        if i >= 0 and text[i + 1 : i + 2].isupper():
            return True
    return False


def frame_line(text: str, where: Where, checksum: int | None = None) -> Frame | Reject | None:
    """Frame one line's sentence: (address, fields, where), a Reject, or None for a NovAtel log.

    `checksum` is the XOR of the characters between '$' and '*' when the
    caller already knows it (iter_frames() does); otherwise it is computed here.
    """
    start = text.find("$")
    if start < 0:
        return None if _looks_novatel(text) else Reject(where, "no NMEA sentence in line")
    star = text.find("*", start)
    if star >= 0:
        given = text[star + 1 : star + 3]
        body = text[start + 1 : star]
        if len(given) < 2:
            return Reject(where, "truncated checksum")
        if checksum is None:
            checksum = nmea_checksum(body)
        try:
            ok = int(given, 16) == checksum
        except ValueError:
            ok = False
        if not ok:
            return Reject(where, f"bad checksum {given!r}, computed {checksum:02X}", bad_checksum=True)
    else:
        body = text[start + 1 :].rstrip()
    fields = body.split(",")
    address = fields[0]
    if len(address) < 3 or not (address.isascii() and address.isalnum()) or not address.isupper():
        return Reject(where, f"malformed sentence address {address[:12]!r}")
    return address, fields, where


def iter_frames(data: LogText, prefix: str = "auto") -> Iterator[Frame | Reject]:
    """Every NMEA-framed sentence of a log (checksum verified) or a Reject, in file order.

    Shared by the NMEA, PHINS and $PASHR decoders. `fields[0]` is the address.
    """
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    strip = prefix != "none"
    for block in blocks_in(data):
        yield from _block_frames(block, prefix, strip)


def _block_frames(block: Block, prefix: str, strip: bool) -> Iterator[Frame | Reject]:
    """`iter_frames` of one block of a log (positions the log's)."""
    data, base = block.data, block.offset
    pxor = prefix_xor(data)
    offset = base
    for number, raw in enumerate(data.decode("latin-1").split("\n"), start=block.lines + 1):
        line_start = offset
        offset += len(raw) + 1
        text = raw.rstrip("\r")
        if not text or text.isspace():
            continue
        host = None
        skipped = 0
        if strip and text[0] not in "$#%":
            rest, host = strip_prefix(text, prefix)
            skipped = len(text) - len(rest)
            text = rest
        where = Where(line_start, number, host)
        if text.count("$") > 1:
            yield from _glued_frames(text, where)
            continue
        start = text.find("$")
        star = text.find("*", start) if start >= 0 else -1
        checksum = None
        if star > start + 1:
            at = line_start - base + skipped  # in the block, where `pxor` is
            checksum = pxor[at + star - 1] ^ pxor[at + start]
        result = frame_line(text, where, checksum)
        if result is not None:
            yield result


def _glued_frames(text: str, where: Where) -> Iterator[Frame | Reject]:
    """A line holding several '$': every start framed on its own (sentences glued together), and each run of
    consecutive pieces that frame as nothing one Reject, so a flood of '$' is one broken line, not a million.

    A bad checksum stays a reject of its own: it is a whole sentence, counted apart as bad checksum.
    """
    broken: Reject | None = None
    more = 0
    for piece in text.split("$")[1:]:
        result = frame_line("$" + piece, where) if piece else Reject(where, "malformed sentence address ''")
        if isinstance(result, Reject) and not result.bad_checksum:
            if broken is None:
                broken = result
            else:
                more += 1
            continue
        if broken is not None:
            yield _run_of(broken, more)
            broken, more = None, 0
        if result is not None:
            yield result
    if broken is not None:
        yield _run_of(broken, more)


def _run_of(first: Reject, more: int) -> Reject:
    """One Reject for a run of broken pieces of a line: the first one's reason, and how many followed it."""
    return first if not more else Reject(first.where, f"{first.reason} and {more} more broken pieces after it")


def _frame_values(frame: Frame) -> Scanned | Reject | None:
    address, fields, where = frame
    if address[0] == "P":
        return None  # proprietary: another decoder's business
    kind = address[-3:]
    parser = VALUES.get(kind)
    if parser is None:
        return None
    try:
        return kind, address[:-3], parser(fields[1:]), where.offset, where.line, where.host_time_ns
    except (ValueError, IndexError, OverflowError) as exc:
        return Reject(where, f"bad {kind} sentence: {exc}")


def parse_frame(frame: Frame) -> NmeaRecord | Reject | None:
    """The record for a framed sentence; None for proprietary and other sentence types."""
    item = _frame_values(frame)
    if item is None or isinstance(item, Reject):
        return item
    kind, talker, values, _, _, _ = item
    return RECORDS[kind](frame[2], talker, *values)


# (sentence type, talker, values in record field order, byte offset, line, host time ns or None)
Scanned = tuple[str, str, tuple, int, int | None, int | None]


def scan(data: bytes, prefix: str = "auto", base: int = 0, lines: int = 0,
         counts: SentenceCounts | None = None) -> Generator[Scanned | Reject, None, None]:
    """What `decode` yields, as plain tuples instead of records (for converters on the hot path).

    `data` may be a block of a longer log (`formats.log_blocks`) starting at
    byte `base` after `lines` line ends: positions are then the log's.
    Every line is counted into `counts` (`formats.nmea.counts`) when the
    scan ends or is closed; a sentence yielded is counted once the consumer
    asks for the next item, so one it stopped at is left for whoever reads
    on from it.

    The common line (``$TTSSS,...*HH`` with nothing before it) takes a fast
    path: the sentence type is looked up before anything else, so the
    sentences of other families ($GPGSV, $GPGSA...) cost one dict update and
    their checksums are not verified; everything else goes through
    `iter_frames`' general path.
    """
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    pxor = prefix_xor(data)
    parsers, hexes = VALUES, HEX
    prefixes = HostPrefixes(prefix)
    tally: dict[str, dict[str, int]] = {outcome: {} for outcome in OUTCOMES}
    used, skipped, bad, rejected = tally[USED], tally[IGNORED], tally[BAD_CHECKSUM], tally[REJECTED]
    blank = 0
    pieces = data.decode("latin-1").split("\n")
    offset = 0  # in `data`; positions given out are `base` + it
    try:
        for number, raw in enumerate(pieces, start=lines + 1):
            line_start = offset
            offset += len(raw) + 1
            s, host = 0, None  # where the sentence starts in the line, and the line's host time
            if raw[:1] != "$":
                if raw.isspace() or not raw:
                    blank += 1  # a flood of blank lines must cost no framing (iter_frames skips them too)
                    continue
                s, host = prefixes.split(raw)
            star = raw.find("*", s + 6)
            if raw[s : s + 1] != "$" or raw[s + 6 : s + 7] != "," or star < 0 or raw.count("$") != 1:
                yield from _scan_general(raw, base + line_start, number, prefix, tally)
                continue
            kind = raw[s + 3 : s + 6]
            parser = parsers.get(kind)
            address = raw[s + 1 : s + 6]
            if parser is None or raw[s + 1] == "P":
                n = skipped.get(address)
                if n is not None:
                    skipped[address] = n + 1  # a sentence of another family seen before ($GPGSV...)
                elif not (address.isascii() and address.isalnum() and address.isupper()):
                    rejected[NO_SENTENCE] = rejected.get(NO_SENTENCE, 0) + 1
                    yield Reject(Where(base + line_start, number, host), f"malformed sentence address {address!r}")
                else:
                    skipped[address] = 1
                continue
            given = hexes.get(raw[star + 1 : star + 3])
            computed = pxor[line_start + star - 1] ^ pxor[line_start + s]
            if given != computed:
                bad[address] = bad.get(address, 0) + 1
                yield Reject(Where(base + line_start, number, host),
                             f"bad checksum {raw[star + 1 : star + 3]!r}, computed {computed:02X}", bad_checksum=True)
                continue
            try:
                values = parser(raw[s + 7 : star].split(","))
            except (ValueError, IndexError, OverflowError) as exc:
                rejected[address] = rejected.get(address, 0) + 1
                yield Reject(Where(base + line_start, number, host), f"bad {kind} sentence: {exc}")
                continue
            yield kind, raw[s + 1 : s + 3], values, base + line_start, number, host
            used[address] = used.get(address, 0) + 1
        if pieces[-1] == "":
            blank -= 1  # the end of the last line, no line of its own
    finally:
        if counts is not None:
            _count(counts, tally, blank)


def _count(counts: SentenceCounts, tally: dict[str, dict[str, int]], blank: int) -> None:
    """A scan's tally into `counts`: the types skipped split into ignored and unknown, blank lines added."""
    skipped = tally[IGNORED]
    # a key in parentheses is no address (NOVATEL): it stays ignored
    tally[IGNORED] = {a: n for a, n in skipped.items() if a[:1] == "(" or skipped_outcome(a) == IGNORED}
    tally[UNKNOWN] = {a: n for a, n in skipped.items() if a[:1] != "(" and skipped_outcome(a) == UNKNOWN}
    if blank:
        tally[IGNORED][BLANK] = blank
    for outcome, table in tally.items():
        counts.merge(outcome, table)


class HostPrefixes:
    """Splits host-timestamp prefixes off lines, the stamp of the line before parsed once for all lines that
    repeat it (a capture stamps every line of one read alike; a logger stamps a burst alike)."""

    def __init__(self, style: str):
        self.style = style
        self._last: str | None = None
        self._host: int | None = None

    def split(self, raw: str) -> tuple[int, int | None]:
        """(where the text after the prefix starts, the host time in ns), or (0, None) without a prefix.

        A cached stamp is used only when a '$' follows it, where neither prefix pattern can read further,
        so the split is the one `strip_prefix` gives.
        """
        last = self._last
        if last is not None and raw.startswith(last) and raw[len(last) : len(last) + 1] == "$":
            return len(last), self._host
        if self.style == "none":
            return 0, None
        rest, host = strip_prefix(raw, self.style)
        if host is None:
            return 0, None
        s = len(raw) - len(rest)
        if rest[:1] == "$":
            self._last, self._host = raw[:s], host
        return s, host


def _scan_general(raw: str, line_start: int, number: int, prefix: str,
                  tally: dict[str, dict[str, int]] | None = None) -> Iterator[Scanned | Reject]:
    """A line off the fast path: prefixes, noise, missing checksums, glued sentences, garbage; counted in `tally`."""
    if tally is None:
        tally = {outcome: {} for outcome in OUTCOMES}
    found = False
    for item in iter_frames(raw.encode("latin-1"), prefix):
        found = True
        if isinstance(item, Reject):
            where = item.where
            address = _address_of(raw) if item.bad_checksum else NO_SENTENCE
            outcome = BAD_CHECKSUM if item.bad_checksum else REJECTED
            tally[outcome][address] = tally[outcome].get(address, 0) + 1
            yield Reject(Where(line_start, number, where.host_time_ns), item.reason, item.bad_checksum)
            continue
        address, fields, where = item
        result = _frame_values((address, fields, Where(line_start, number, where.host_time_ns)))
        outcome = IGNORED if result is None else REJECTED if isinstance(result, Reject) else USED
        key = address[:16]  # an address is any run of capitals and digits: a key of bounded size
        tally[outcome][key] = tally[outcome].get(key, 0) + 1
        if result is not None:
            yield result
    if not found:  # a NovAtel log among the sentences: another decoder's
        tally[IGNORED][NOVATEL] = tally[IGNORED].get(NOVATEL, 0) + 1


def _address_of(text: str) -> str:
    """The address of a framed sentence in a line with a bad checksum (after its '$', up to ',' or '*'), or
    NO_SENTENCE when that is no address."""
    start = text.find("$")
    end = min((i for i in (text.find(",", start), text.find("*", start)) if i >= 0), default=len(text))
    address = text[start + 1 : end]
    ok = len(address) >= 3 and address.isascii() and address.isalnum() and address.isupper()
    return address[:16] if ok else NO_SENTENCE


def decode(data: LogText, prefix: str = "auto") -> Iterator[NmeaRecord | Reject]:
    """Stream every GNSS sentence record (or Reject) in a log, whole or in blocks, in file order (see `scan`)."""
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    records = RECORDS
    for block in blocks_in(data):
        for item in scan(block.data, prefix, block.offset, block.lines):
            if isinstance(item, Reject):
                yield item
            else:
                kind, talker, values, offset, line, host = item
                yield records[kind](Where(offset, line, host), talker, *values)


# ---------------------------------------------------------------- encoders


def _num(x: float, fmt: str) -> str:
    return "" if x is None or not math.isfinite(x) else format(x, fmt)


def _hhmmss(utc_ns: int) -> str:
    cs = (utc_ns + 5_000_000) // 10_000_000 % _DAY_CS
    h, rem = divmod(cs, 360_000)
    m, rem = divmod(rem, 6_000)
    return f"{h:02d}{m:02d}{rem // 100:02d}.{rem % 100:02d}"


def _utc_date(utc_ns: int) -> date:
    cs = (utc_ns + 5_000_000) // 10_000_000
    return datetime.fromtimestamp(cs // 100, tz=UTC).date()


def _ddmm(value: float, deg_digits: int, hemis: str, decimals: int) -> tuple[str, str]:
    if value is None or not math.isfinite(value):
        return "", ""
    scale = 10**decimals
    units = round(abs(value) * 60.0 * scale)
    deg, rem = divmod(units, 60 * scale)
    text = f"{deg:0{deg_digits}d}{rem // scale:02d}.{rem % scale:0{decimals}d}"
    return text, hemis[1] if value < 0 and units else hemis[0]  # no "S" for a value that rounds to 0


def _body(address: str, fields: list[str]) -> str:
    payload = ",".join([address, *fields])
    return f"${payload}*{nmea_checksum(payload):02X}\r\n"


def encode_gga(
    utc_ns: int, latitude: float, longitude: float, *, quality: int = 1, satellites: int = 8,
    hdop: float = 1.0, altitude_msl_m: float = 0.0, geoid_separation_m: float = 0.0,
    dgps_age_s: float = NAN, dgps_station: str = "", talker: str = "GP", decimals: int = 5,
) -> str:
    """$--GGA line; lat/lon with `decimals` decimals of minutes, altitude and separation in m."""
    lat, ns = _ddmm(latitude, 2, "NS", decimals)
    lon, ew = _ddmm(longitude, 3, "EW", decimals)
    fields = [
        _hhmmss(utc_ns), lat, ns, lon, ew, "" if quality < 0 else str(quality),
        "" if satellites < 0 else f"{satellites:02d}", _num(hdop, ".1f"),
        _num(altitude_msl_m, ".2f"), "M", _num(geoid_separation_m, ".2f"), "M",
        _num(dgps_age_s, ".1f"), dgps_station,
    ]
    return _body(talker + "GGA", fields)


def encode_rmc(
    utc_ns: int, latitude: float, longitude: float, *, speed_knots: float = 0.0,
    course_deg: float = NAN, valid: bool = True, magnetic_variation_deg: float = NAN,
    mode: str = "A", talker: str = "GP", decimals: int = 5,
) -> str:
    """$--RMC line with the date of `utc_ns`; speed in knots, course true degrees."""
    lat, ns = _ddmm(latitude, 2, "NS", decimals)
    lon, ew = _ddmm(longitude, 3, "EW", decimals)
    d = _utc_date(utc_ns)
    var = _num(abs(magnetic_variation_deg), ".1f") if math.isfinite(magnetic_variation_deg) else ""
    var_dir = ("W" if magnetic_variation_deg < 0 else "E") if var else ""
    fields = [
        _hhmmss(utc_ns), "A" if valid else "V", lat, ns, lon, ew, _num(speed_knots, ".2f"),
        _num(course_deg, ".2f"), f"{d.day:02d}{d.month:02d}{d.year % 100:02d}", var, var_dir, mode,
    ]
    return _body(talker + "RMC", fields)


def encode_zda(utc_ns: int, *, talker: str = "GP") -> str:
    """$--ZDA line (UTC time and date, zone 00:00)."""
    d = _utc_date(utc_ns)
    return _body(talker + "ZDA", [_hhmmss(utc_ns), f"{d.day:02d}", f"{d.month:02d}", f"{d.year:04d}", "00", "00"])


def encode_gst(
    utc_ns: int, *, lat_std_m: float, lon_std_m: float, alt_std_m: float = NAN,
    rms_m: float = NAN, semi_major_m: float = NAN, semi_minor_m: float = NAN,
    orientation_deg: float = NAN, talker: str = "GP",
) -> str:
    """$--GST line: 1-sigma errors in metres (latitude, longitude, altitude) and the error ellipse."""
    values = (rms_m, semi_major_m, semi_minor_m, orientation_deg, lat_std_m, lon_std_m, alt_std_m)
    return _body(talker + "GST", [_hhmmss(utc_ns), *(_num(v, ".3f") for v in values)])


def encode_vtg(
    course_true_deg: float, speed_knots: float, *, course_magnetic_deg: float = NAN,
    mode: str = "A", talker: str = "GP",
) -> str:
    """$--VTG line (NMEA 2.3+ layout with unit letters and mode)."""
    kmh = speed_knots * 1.852 if math.isfinite(speed_knots) else NAN
    fields = [
        _num(course_true_deg, ".2f"), "T", _num(course_magnetic_deg, ".2f"), "M",
        _num(speed_knots, ".2f"), "N", _num(kmh, ".2f"), "K", mode,
    ]
    return _body(talker + "VTG", fields)


def encode_hdt(heading_deg: float, *, talker: str = "GP") -> str:
    """$--HDT line: true heading in degrees (3 decimals)."""
    return _body(talker + "HDT", [_num(heading_deg, ".3f"), "T"])


def encode_ths(heading_deg: float, mode: str = "A", *, talker: str = "GP") -> str:
    """$--THS line: true heading and mode indicator."""
    return _body(talker + "THS", [_num(heading_deg, ".3f"), mode])


def encode_gll(
    utc_ns: int, latitude: float, longitude: float, *, valid: bool = True, mode: str = "A",
    talker: str = "GP", decimals: int = 5,
) -> str:
    """$--GLL line: position, time, status and mode."""
    lat, ns = _ddmm(latitude, 2, "NS", decimals)
    lon, ew = _ddmm(longitude, 3, "EW", decimals)
    return _body(talker + "GLL", [lat, ns, lon, ew, _hhmmss(utc_ns), "A" if valid else "V", mode])
