"""iXblue / Exail PHINS "standard" ASCII output: $HEHDT, the $PIXSE family and $PHTRO.

Layouts from the PHINS interface library ("PHINS standard" protocol):

    $HEHDT,x.xxx,T                       true heading, degrees
    $PIXSE,ATITUD,r.rrr,p.ppp            roll (positive port up), pitch (positive bow down)
    $PIXSE,POSITI,lat,lon,alt            degrees (+N), degrees 0..360 (+E), altitude m (+up)
    $PIXSE,SPEED_,e,n,u                  east, north, up speed, m/s
    $PIXSE,UTMWGS,C,nn,east,north,alt    UTM latitude zone letter, longitude zone, metres
    $PIXSE,HEAVE_,surge,sway,heave       metres
    $PIXSE,TIME__,hhmmss.ssssss          UTC time of day of the burst
    $PIXSE,STDHRP,h,r,p                  1-sigma heading, roll, pitch, degrees
    $PIXSE,STDPOS,lat,lon,alt            1-sigma latitude, longitude, altitude, metres
    $PIXSE,STDSPD,e,n,u                  1-sigma speeds, m/s (same axis order as SPEED_)
    $PIXSE,ALGSTS,lsb,msb                algorithm status, hex words
    $PIXSE,STATUS,lsb,msb                system status, hex words
    $PIXSE,HT_STS,word                   high-level status, hex
    $PHTRO,p.pp,M|P,r.rr,B|T             pitch (M bow up, P bow down), roll (B port down, T port up)

PHINS writes one burst of these per output epoch. Decoded angles keep the
vendor's sign conventions, spelled out in the field names; POSITI's 0..360
longitude is returned in [-180, 180). Heading sentences from any talker
($HEHDT, $INHDT, $HETHS...) are accepted. Other $PIXSE sentences (DEPIN_,
LOGDVL...) and other sentence types are skipped silently; lines without a
sentence and bad checksums are Rejects.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from .lines import PREFIX_STYLES
from .log_blocks import Block, LogText, blocks_in
from .nmea.fields import parse_tod
from .nmea.framing import HEX, build, prefix_xor
from .nmea.sentences import iter_frames
from .numbers import integer, optional, optional_integer
from .records import Reject, Where


@dataclass(frozen=True, slots=True)
class Heading:
    """$--HDT or $--THS: true heading in degrees (THS adds a mode letter, 'V' = invalid)."""

    where: Where
    talker: str
    heading_deg: float
    mode: str = ""


@dataclass(frozen=True, slots=True)
class Atitud:
    """Roll and pitch in PHINS conventions."""

    where: Where
    roll_port_up_deg: float
    pitch_bow_down_deg: float


@dataclass(frozen=True, slots=True)
class Positi:
    """Position: latitude, longitude in [-180, 180), altitude (m, positive up)."""

    where: Where
    latitude: float
    longitude: float
    altitude_m: float


@dataclass(frozen=True, slots=True)
class Speed:
    """Velocity in the local geographic frame, m/s."""

    where: Where
    east_mps: float
    north_mps: float
    up_mps: float


@dataclass(frozen=True, slots=True)
class Utmwgs:
    """Position in UTM (WGS84)."""

    where: Where
    lat_zone: str
    lon_zone: int
    east_m: float
    north_m: float
    altitude_m: float


@dataclass(frozen=True, slots=True)
class Heave:
    """Surge, sway and heave, metres."""

    where: Where
    surge_m: float
    sway_m: float
    heave_m: float


@dataclass(frozen=True, slots=True)
class Time:
    """UTC time of day of the burst (seconds)."""

    where: Where
    time_s: float


@dataclass(frozen=True, slots=True)
class StdHrp:
    """1-sigma heading, roll and pitch, degrees."""

    where: Where
    heading_std_deg: float
    roll_std_deg: float
    pitch_std_deg: float


@dataclass(frozen=True, slots=True)
class StdPos:
    """1-sigma latitude (north), longitude (east) and altitude errors, metres."""

    where: Where
    lat_std_m: float
    lon_std_m: float
    altitude_std_m: float


@dataclass(frozen=True, slots=True)
class StdSpd:
    """1-sigma speed errors, m/s (SPEED_'s axis order)."""

    where: Where
    east_std_mps: float
    north_std_mps: float
    up_std_mps: float


@dataclass(frozen=True, slots=True)
class StatusWords:
    """ALGSTS, STATUS or HT_STS status words (msb is 0 for the one-word HT_STS)."""

    where: Where
    kind: str
    lsb: int
    msb: int


@dataclass(frozen=True, slots=True)
class Phtro:
    """$PHTRO attitude with its direction letters turned into signs."""

    where: Where
    pitch_bow_up_deg: float
    roll_port_up_deg: float


PhinsRecord = (Heading | Atitud | Positi | Speed | Utmwgs | Heave | Time | StdHrp | StdPos | StdSpd | StatusWords
               | Phtro)


_f = optional  # every number field: finite, NaN when empty (formats.numbers)


def _three(f: list[str], n: int = 3) -> tuple[float, ...]:
    if len(f) < n:
        raise IndexError(f"{len(f)} fields, {n} needed")
    if n == 3:  # the common case unrolled: no generator per sentence
        a, b, c = f[0], f[1], f[2]
        if a and b and c:  # three given: plain float(), and one look at their sum for a NaN or an infinity
            x, y, z = float(a), float(b), float(c)
            total = x + y + z
            if total - total == 0.0:
                return x, y, z
        return _f(a), _f(b), _f(c)  # the number rule names the field (an overflowing sum passes it)
    if n == 2:  # ATITUD, once a burst: no generator either
        return _f(f[0]), _f(f[1])
    return tuple(_f(x) for x in f[:n])


def wrap_longitude(lon: float) -> float:
    """Longitude in [-180, 180) from any range (PHINS writes 0..360)."""
    if not math.isfinite(lon) or -180.0 <= lon < 180.0:
        return lon  # untouched, so that the common case keeps every digit
    if 180.0 <= lon < 540.0:
        return lon - 360.0  # exact for 0..360 input (Sterbenz), unlike the modulo below
    return (lon + 180.0) % 360.0 - 180.0


# ---------------------------------------------------------------- per sentence
# Each parser turns the fields after the sentence name into the record's values
# in field order (everything after `where`): `scan()` hands these tuples to
# converters that need no record objects, `decode()` wraps them.


def _words(kind: str) -> Callable[[list[str]], tuple]:
    def parse(f: list[str]) -> tuple:
        if not f or not f[0]:
            raise IndexError("no status word")
        return kind, integer(f[0], "status word", 16), integer(f[1], "status word", 16) if len(f) > 1 and f[1] else 0

    return parse


def _positi(f: list[str]) -> tuple:
    lat, lon, alt = _three(f)
    if abs(lat) > 90.0 or not -360.0 <= lon <= 360.0:
        raise ValueError(f"position {lat}, {lon} out of range")
    return lat, wrap_longitude(lon), alt


def _utmwgs(f: list[str]) -> tuple:
    if len(f) < 5:
        raise IndexError(f"{len(f)} fields, 5 needed")
    return f[0], optional_integer(f[1], "zone"), _f(f[2]), _f(f[3]), _f(f[4])


def _time(f: list[str]) -> tuple:
    if not f:
        raise IndexError("no time field")
    return (parse_tod(f[0]),)


# $PIXSE sentence name -> (epoch key, values parser); the key is the record's
# class name, or the status word's kind (each occurs once per burst)
PIXSE: dict[str, tuple[str, Callable[[list[str]], tuple]]] = {
    "ATITUD": ("Atitud", lambda f: _three(f, 2)),
    "POSITI": ("Positi", _positi),
    "SPEED_": ("Speed", _three),
    "UTMWGS": ("Utmwgs", _utmwgs),
    "HEAVE_": ("Heave", _three),
    "TIME__": ("Time", _time),
    "STDHRP": ("StdHrp", _three),
    "STDPOS": ("StdPos", _three),
    "STDSPD": ("StdSpd", _three),
    "ALGSTS": ("ALGSTS", _words("ALGSTS")),
    "STATUS": ("STATUS", _words("STATUS")),
    "HT_STS": ("HT_STS", _words("HT_STS")),
}
RECORDS: dict[str, type] = {
    "Heading": Heading, "Atitud": Atitud, "Positi": Positi, "Speed": Speed, "Utmwgs": Utmwgs, "Heave": Heave,
    "Time": Time, "StdHrp": StdHrp, "StdPos": StdPos, "StdSpd": StdSpd, "ALGSTS": StatusWords,
    "STATUS": StatusWords, "HT_STS": StatusWords, "Phtro": Phtro,
}


def _phtro(f: list[str]) -> tuple:
    if len(f) < 4:
        raise IndexError(f"{len(f)} fields, 4 needed")
    if f[1] not in ("M", "P", "") or f[3] not in ("B", "T", ""):
        raise ValueError(f"direction letters {f[1]!r}, {f[3]!r}")
    pitch, roll = _f(f[0]), _f(f[2])
    return -pitch if f[1] == "P" else pitch, -roll if f[3] == "B" else roll


def _values(address: str, fields: list[str]) -> tuple[str, tuple] | None:
    """(epoch key, record values) of a framed sentence; None for sentences of other decoders; raises when bad."""
    if address == "PIXSE":
        entry = PIXSE.get(fields[1]) if len(fields) > 1 else None
        return (entry[0], entry[1](fields[2:])) if entry else None
    if address == "PHTRO":
        return "Phtro", _phtro(fields[1:])
    if address[0] != "P" and address.endswith(("HDT", "THS")):
        mode = fields[2] if address.endswith("THS") and len(fields) > 2 else ""
        if len(fields) < 2:
            raise IndexError("no heading field")
        return "Heading", (address[:-3], _f(fields[1]), mode)
    return None


def _bad(address: str, fields: list[str], where: Where, exc: Exception) -> Reject:
    return Reject(where, f"bad {address} {fields[1] if len(fields) > 1 else ''} sentence: {exc}".replace("  ", " "))


def _parse(address: str, fields: list[str], where: Where) -> PhinsRecord | Reject | None:
    try:
        found = _values(address, fields)
    except (ValueError, IndexError, OverflowError) as exc:
        return _bad(address, fields, where, exc)
    return None if found is None else RECORDS[found[0]](where, *found[1])


def decode(data: LogText, prefix: str = "auto") -> Iterator[PhinsRecord | Reject]:
    """Stream every PHINS record (or Reject) in a log, in file order."""
    for item in iter_frames(data, prefix):
        if isinstance(item, Reject):
            yield item
            continue
        address, fields, where = item
        result = _parse(address, fields, where)
        if result is not None:
            yield result


# (epoch key, values in record field order after `where`, byte offset, line, host time ns or None)
Scanned = tuple[str, tuple, int, int, int | None]


def scan(data: LogText, prefix: str = "auto") -> Iterator[Scanned | Reject]:
    """What `decode` yields, as plain tuples instead of records (for converters on the hot path).

    The common line (``$ADDRS,...*HH``, nothing before it, one '$') is framed
    here with the checksum from a prefix XOR of the whole buffer; everything
    else goes through `iter_frames`' general path.
    """
    check_prefix(prefix)
    for block in blocks_in(data):
        yield from scan_block(block, prefix)


def check_prefix(prefix: str) -> None:
    """ValueError for a host-timestamp prefix style that is none of PREFIX_STYLES."""
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")


def scan_block(block: Block, prefix: str) -> Iterator[Scanned | Reject]:
    """`scan` of one block of a log (positions the log's; the prefix style already checked)."""
    data, base = block.data, block.offset
    pxor = prefix_xor(data)
    hexes, values = HEX, _values
    offset = base
    for number, raw in enumerate(data.decode("latin-1").split("\n"), start=block.lines + 1):
        line_start = offset
        offset += len(raw) + 1
        star = raw.find("*")
        given = hexes.get(raw[star + 1 : star + 3]) if star > 0 else None
        if given is None or raw[0] != "$" or raw.count("$") != 1:
            if raw.isspace() or not raw:
                continue  # blank: a flood of them must cost no framing (iter_frames skips them too)
            yield from _scan_general(raw, line_start, number, prefix)
            continue
        at = line_start - base  # in the block, where `pxor` is
        computed = pxor[at + star - 1] ^ pxor[at]
        if given != computed:
            yield Reject(Where(line_start, number),
                         f"bad checksum {raw[star + 1 : star + 3]!r}, computed {computed:02X}", bad_checksum=True)
            continue
        fields = raw[1:star].split(",")
        address = fields[0]
        if len(address) < 3 or not (address.isascii() and address.isalnum()) or not address.isupper():
            yield Reject(Where(line_start, number), f"malformed sentence address {address[:12]!r}")
            continue
        try:
            found = values(address, fields)
        except (ValueError, IndexError, OverflowError) as exc:
            yield _bad(address, fields, Where(line_start, number), exc)
            continue
        if found is not None:
            yield found[0], found[1], line_start, number, None


def _scan_general(raw: str, line_start: int, number: int, prefix: str) -> Iterator[Scanned | Reject]:
    """A line off the fast path: prefixes, noise, missing checksums, glued sentences, garbage."""
    for item in iter_frames(raw.encode("latin-1"), prefix):
        if isinstance(item, Reject):
            where = Where(line_start, number, item.where.host_time_ns)
            yield Reject(where, item.reason, item.bad_checksum)
            continue
        address, fields, w = item
        where = Where(line_start, number, w.host_time_ns)
        try:
            found = _values(address, fields)
        except (ValueError, IndexError, OverflowError) as exc:
            yield _bad(address, fields, where, exc)
            continue
        if found is not None:
            yield found[0], found[1], line_start, number, where.host_time_ns


# ---------------------------------------------------------------- encoders


def _n(x: float, spec: str) -> str:
    return format(x, spec) if math.isfinite(x) else ""


def _hms(utc_ns: int) -> str:
    us = (utc_ns + 500) // 1000 % 86_400_000_000
    h, rem = divmod(us, 3_600_000_000)
    m, rem = divmod(rem, 60_000_000)
    return f"{h:02d}{m:02d}{rem // 1_000_000:02d}.{rem % 1_000_000:06d}"


def encode_hehdt(heading_deg: float) -> str:
    """$HEHDT line (true heading, 3 decimals)."""
    return build("HEHDT", [_n(heading_deg % 360.0, ".3f"), "T"])


def encode_atitud(roll_port_up_deg: float, pitch_bow_down_deg: float) -> str:
    """$PIXSE,ATITUD line in PHINS sign conventions."""
    return build("PIXSE", ["ATITUD", _n(roll_port_up_deg, ".3f"), _n(pitch_bow_down_deg, ".3f")])


def encode_positi(latitude: float, longitude: float, altitude_m: float) -> str:
    """$PIXSE,POSITI line; longitude written 0..360 as PHINS does."""
    lon = _n(longitude % 360.0, ".8f")
    if lon == "360.00000000":
        lon = "0.00000000"
    return build("PIXSE", ["POSITI", _n(latitude, ".8f"), lon, _n(altitude_m, ".3f")])


def encode_speed(east_mps: float, north_mps: float, up_mps: float) -> str:
    """$PIXSE,SPEED_ line (east, north, up)."""
    return build("PIXSE", ["SPEED_", *(_n(v, ".3f") for v in (east_mps, north_mps, up_mps))])


def encode_heave(surge_m: float, sway_m: float, heave_m: float) -> str:
    """$PIXSE,HEAVE_ line."""
    return build("PIXSE", ["HEAVE_", *(_n(v, ".3f") for v in (surge_m, sway_m, heave_m))])


def encode_time(utc_ns: int) -> str:
    """$PIXSE,TIME__ line (time of day, microseconds)."""
    return build("PIXSE", ["TIME__", _hms(utc_ns)])


def encode_stdhrp(heading_std_deg: float, roll_std_deg: float, pitch_std_deg: float) -> str:
    """$PIXSE,STDHRP line."""
    return build("PIXSE", ["STDHRP", *(_n(v, ".3f") for v in (heading_std_deg, roll_std_deg, pitch_std_deg))])


def encode_stdpos(lat_std_m: float, lon_std_m: float, altitude_std_m: float) -> str:
    """$PIXSE,STDPOS line."""
    return build("PIXSE", ["STDPOS", *(_n(v, ".2f") for v in (lat_std_m, lon_std_m, altitude_std_m))])


def encode_stdspd(east_std_mps: float, north_std_mps: float, up_std_mps: float) -> str:
    """$PIXSE,STDSPD line."""
    return build("PIXSE", ["STDSPD", *(_n(v, ".3f") for v in (east_std_mps, north_std_mps, up_std_mps))])


def encode_status(kind: str, lsb: int, msb: int = 0) -> str:
    """$PIXSE,ALGSTS / STATUS (two words) or HT_STS (one word) line."""
    words = [f"{lsb:08X}"] if kind == "HT_STS" else [f"{lsb:08X}", f"{msb:08X}"]
    return build("PIXSE", [kind, *words])


def encode_phtro(pitch_bow_up_deg: float, roll_port_up_deg: float) -> str:
    """$PHTRO line: magnitudes with M/P (bow up/down) and T/B (port up/down) letters."""
    pitch, roll = _n(abs(pitch_bow_up_deg), ".2f"), _n(abs(roll_port_up_deg), ".2f")
    # the letter follows the written magnitude: no "P" for a pitch that rounds to 0.00
    return build("PHTRO", [
        pitch, "P" if pitch_bow_up_deg < 0 and pitch.strip("0.") else "M",
        roll, "B" if roll_port_up_deg < 0 and roll.strip("0.") else "T",
    ])


def encode_epoch(
    utc_ns: int, latitude: float, longitude: float, depth_m: float, heading_deg: float,
    roll_deg: float, pitch_deg: float, velocity_north_mps: float, velocity_east_mps: float,
    velocity_down_mps: float = 0.0, *, heading_std_deg: float = 0.01, roll_std_deg: float = 0.01,
    pitch_std_deg: float = 0.01, position_std_north_m: float = 1.0, position_std_east_m: float = 1.0,
    depth_std_m: float = 0.1, algsts: tuple[int, int] = (0x00000045, 0), status: tuple[int, int] = (0, 0),
) -> str:
    """One PHINS standard burst (12 lines, CRLF) from InsState-style values.

    `roll_deg` is positive starboard down (= PHINS port up), `pitch_deg`
    positive bow up (PHINS writes it negated); depth is positive down.
    """
    return "".join((
        encode_hehdt(heading_deg),
        encode_atitud(roll_deg, -pitch_deg + 0.0),
        encode_positi(latitude, longitude, -depth_m + 0.0),
        encode_speed(velocity_east_mps, velocity_north_mps, -velocity_down_mps + 0.0),
        encode_heave(0.0, 0.0, 0.0),
        encode_time(utc_ns),
        encode_stdhrp(heading_std_deg, roll_std_deg, pitch_std_deg),
        encode_stdpos(position_std_north_m, position_std_east_m, depth_std_m),
        encode_stdspd(0.05, 0.05, 0.05),
        encode_status("ALGSTS", *algsts),
        encode_status("STATUS", *status),
        encode_status("HT_STS", 0),
    ))
