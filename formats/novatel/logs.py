"""NovAtel OEM logs: BESTPOS, BESTVEL and SPAN INSPVA / INSPVAS / INSPVAX, ASCII and binary.

Layouts follow the NovAtel OEM6/OEM7 firmware reference manuals:

- ASCII long header ``#NAMEA,port,sequence,idle%,time status,week,seconds,
  receiver status,reserved,sw version;body*crc32`` and short header
  ``%NAMEA,week,seconds;body*crc32``;
- binary long header (sync ``AA 44 12``, 28 bytes) and short header
  (``AA 44 13``, 12 bytes), little-endian body, then a 4-byte CRC;
- the CRC-32 is NovAtel's: reflected polynomial 0xEDB88320, initial value 0,
  no final XOR, over everything between the sync character and ``*``
  (ASCII) or over header and body (binary). That equals
  ``zlib.crc32(data, 0xFFFFFFFF) ^ 0xFFFFFFFF``, which runs in C.

Other NovAtel logs with a valid CRC, NMEA sentences, abbreviated-ASCII lines
(``<...``) and command prompts (``[COM1]``) in the same file are skipped
silently; anything else is a `Reject`. A binary log with a bad CRC is a
`Reject` and the scan resumes one byte after its sync.

Angles are degrees; heights are metres (BESTPOS: above mean sea level, with
the undulation to add for the ellipsoid; INSPVA: ellipsoidal height).
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

from ..gpstime import gps_to_unix_ns, unix_ns_to_gps
from ..lines import PREFIX_STYLES, strip_prefix
from ..numbers import finite, integer, optional, optional_integer
from ..records import Reject, Where

NAN = float("nan")

SOLUTION_STATUS = {
    0: "SOL_COMPUTED", 1: "INSUFFICIENT_OBS", 2: "NO_CONVERGENCE", 3: "SINGULARITY",
    4: "COV_TRACE", 5: "TEST_DIST", 6: "COLD_START", 7: "V_H_LIMIT", 8: "VARIANCE",
    9: "RESIDUALS", 13: "INTEGRITY_WARNING", 18: "PENDING", 19: "INVALID_FIX",
    20: "UNAUTHORIZED", 22: "INVALID_RATE",
}
POSITION_TYPE = {
    0: "NONE", 1: "FIXEDPOS", 2: "FIXEDHEIGHT", 8: "DOPPLER_VELOCITY", 16: "SINGLE",
    17: "PSRDIFF", 18: "WAAS", 19: "PROPAGATED", 32: "L1_FLOAT", 33: "IONOFREE_FLOAT",
    34: "NARROW_FLOAT", 48: "L1_INT", 49: "WIDE_INT", 50: "NARROW_INT", 51: "RTK_DIRECT_INS",
    52: "INS_SBAS", 53: "INS_PSRSP", 54: "INS_PSRDIFF", 55: "INS_RTKFLOAT", 56: "INS_RTKFIXED",
    68: "PPP_CONVERGING", 69: "PPP", 70: "OPERATIONAL", 71: "WARNING", 72: "OUT_OF_BOUNDS",
    73: "INS_PPP_CONVERGING", 74: "INS_PPP", 77: "PPP_BASIC_CONVERGING", 78: "PPP_BASIC",
    79: "INS_PPP_BASIC_CONVERGING", 80: "INS_PPP_BASIC",
}
INS_STATUS = {
    0: "INS_INACTIVE", 1: "INS_ALIGNING", 2: "INS_HIGH_VARIANCE", 3: "INS_SOLUTION_GOOD",
    6: "INS_SOLUTION_FREE", 7: "INS_ALIGNMENT_COMPLETE", 8: "DETERMINING_ORIENTATION",
    9: "WAITING_INITIALPOS", 10: "WAITING_AZIMUTH", 11: "INITIALIZING_BIASES", 12: "MOTION_DETECT",
}
TIME_STATUS = {
    20: "UNKNOWN", 60: "APPROXIMATE", 80: "COARSEADJUSTING", 100: "COARSE", 120: "COARSESTEERING",
    130: "FREEWHEELING", 140: "FINEADJUSTING", 160: "FINE", 170: "FINEBACKUPSTEERING",
    180: "FINESTEERING", 200: "SATTIME",
}
DATUM = {61: "WGS84", 63: "USER"}
PORTS = {0x20: "COM1", 0x40: "COM2", 0x60: "COM3"}
_PORT_IDS = {v: k for k, v in PORTS.items()}
MESSAGE_IDS = {42: "BESTPOS", 99: "BESTVEL", 507: "INSPVA", 508: "INSPVAS", 1465: "INSPVAX"}
_IDS = {name: i for i, name in MESSAGE_IDS.items()}

SYNC_LONG = b"\xaa\x44\x12"
SYNC_SHORT = b"\xaa\x44\x13"
_HDR_LONG = struct.Struct("<3sBHBBHHBBHIIHH")  # 28 bytes
_HDR_SHORT = struct.Struct("<3sBHHI")  # 12 bytes
_BODY = {
    "BESTPOS": struct.Struct("<IIdddfIfff4sffBBBBBBBB"),  # 72
    "BESTVEL": struct.Struct("<IIffdddf"),  # 44
    "INSPVA": struct.Struct("<Id9dI"),  # 88
    "INSPVAX": struct.Struct("<IIdddfddddddfffffffffIH"),  # 126
}
_BODY["INSPVAS"] = _BODY["INSPVA"]


def crc32(data: bytes) -> int:
    """NovAtel's CRC-32 (reflected 0xEDB88320, initial 0, no final XOR)."""
    return zlib.crc32(data, 0xFFFFFFFF) ^ 0xFFFFFFFF


@dataclass(frozen=True, slots=True)
class Header:
    """A log header; `message` is the log name without its format letter (e.g. 'BESTPOS')."""

    message: str
    encoding: str  # "ascii", "ascii-short", "binary", "binary-short"
    week: int
    seconds: float  # GPS seconds of week
    port: str = ""
    sequence: int = 0
    idle_percent: float = NAN
    time_status: str = ""
    receiver_status: int = 0
    reserved: int = 0
    sw_version: int = 0


@dataclass(frozen=True, slots=True)
class BestPos:
    """BESTPOS: best position with 1-sigma errors (m); height above MSL, undulation to the ellipsoid."""

    where: Where
    header: Header
    solution_status: str
    position_type: str
    latitude: float
    longitude: float
    height_msl_m: float
    undulation_m: float
    datum: str
    lat_std_m: float
    lon_std_m: float
    height_std_m: float
    station_id: str
    diff_age_s: float
    solution_age_s: float
    satellites_tracked: int
    satellites_used: int
    satellites_l1: int = -1
    satellites_multi: int = -1
    extended_status: int = 0
    galileo_beidou_mask: int = 0
    gps_glonass_mask: int = 0


@dataclass(frozen=True, slots=True)
class BestVel:
    """BESTVEL: horizontal speed (m/s), track over ground (degrees true), vertical speed (up)."""

    where: Where
    header: Header
    solution_status: str
    velocity_type: str
    latency_s: float
    age_s: float
    horizontal_speed_mps: float
    track_deg: float
    vertical_speed_mps: float


@dataclass(frozen=True, slots=True)
class InsPva:
    """INSPVA / INSPVAS: SPAN position (ellipsoidal height), NEU velocity and attitude.

    Roll is right-handed about the forward axis (right side down positive),
    pitch right-handed about the right axis (nose up positive), azimuth is
    the heading, clockwise from true north.
    """

    where: Where
    header: Header
    week: int
    seconds: float
    latitude: float
    longitude: float
    height_m: float
    north_mps: float
    east_mps: float
    up_mps: float
    roll_deg: float
    pitch_deg: float
    azimuth_deg: float
    status: str


@dataclass(frozen=True, slots=True)
class InsPvax:
    """INSPVAX: INSPVA plus undulation, position type and 1-sigma errors of every state."""

    where: Where
    header: Header
    status: str
    position_type: str
    latitude: float
    longitude: float
    height_m: float
    undulation_m: float
    north_mps: float
    east_mps: float
    up_mps: float
    roll_deg: float
    pitch_deg: float
    azimuth_deg: float
    lat_std_m: float
    lon_std_m: float
    height_std_m: float
    north_std_mps: float
    east_std_mps: float
    up_std_mps: float
    roll_std_deg: float
    pitch_std_deg: float
    azimuth_std_deg: float
    extended_status: int
    time_since_update_s: int


NovatelRecord = BestPos | BestVel | InsPva | InsPvax


def record_time_ns(rec: NovatelRecord) -> int | None:
    """UTC ns of a record's measurement (INSPVA: its own week/seconds; else the header's); None if unknown."""
    week, seconds = (rec.week, rec.seconds) if isinstance(rec, InsPva) else (rec.header.week, rec.header.seconds)
    if week <= 0 or not math.isfinite(seconds):
        return None
    return gps_to_unix_ns(week, seconds)


# ---------------------------------------------------------------- ASCII bodies


_float = optional  # number fields: finite, NaN or -1 when empty (formats.numbers)
_int = optional_integer


def _hex(s: str) -> int:
    return integer(s, "field", 16) if s else 0


def _enum(s: str, table: dict[int, str]) -> str:
    return table.get(int(s), s) if s.isdigit() else s


def _need(f: list[str], n: int, name: str) -> None:
    if len(f) < n:
        raise IndexError(f"truncated {name}: {len(f)} fields, {n} needed")


def _bestpos_ascii(f: list[str], w: Where, h: Header) -> BestPos:
    _need(f, 15, "BESTPOS")
    opt = f + [""] * (21 - len(f))
    return BestPos(
        w, h, _enum(f[0], SOLUTION_STATUS), _enum(f[1], POSITION_TYPE), _float(f[2]), _float(f[3]),
        _float(f[4]), _float(f[5]), f[6], _float(f[7]), _float(f[8]), _float(f[9]), f[10].strip('"'),
        _float(f[11]), _float(f[12]), _int(f[13]), _int(f[14]), _int(opt[15]), _int(opt[16]),
        _hex(opt[18]), _hex(opt[19]), _hex(opt[20]),
    )


def _bestvel_ascii(f: list[str], w: Where, h: Header) -> BestVel:
    _need(f, 7, "BESTVEL")
    return BestVel(
        w, h, _enum(f[0], SOLUTION_STATUS), _enum(f[1], POSITION_TYPE),
        _float(f[2]), _float(f[3]), _float(f[4]), _float(f[5]), _float(f[6]),
    )


def _inspva_ascii(f: list[str], w: Where, h: Header) -> InsPva:
    _need(f, 12, "INSPVA")
    return InsPva(
        w, h, integer(f[0], "week"), finite(f[1], "seconds"), _float(f[2]), _float(f[3]), _float(f[4]),
        _float(f[5]), _float(f[6]), _float(f[7]), _float(f[8]), _float(f[9]), _float(f[10]), _enum(f[11], INS_STATUS),
    )


def _inspvax_ascii(f: list[str], w: Where, h: Header) -> InsPvax:
    _need(f, 21, "INSPVAX")
    opt = f + [""] * (23 - len(f))
    return InsPvax(
        w, h, _enum(f[0], INS_STATUS), _enum(f[1], POSITION_TYPE),
        _float(f[2]), _float(f[3]), _float(f[4]), _float(f[5]), _float(f[6]), _float(f[7]), _float(f[8]),
        _float(f[9]), _float(f[10]), _float(f[11]), _float(f[12]), _float(f[13]), _float(f[14]), _float(f[15]),
        _float(f[16]), _float(f[17]), _float(f[18]), _float(f[19]), _float(f[20]),
        _hex(opt[21]), _int(opt[22]),
    )


_ASCII: dict[str, Callable[[list[str], Where, Header], NovatelRecord]] = {
    "BESTPOS": _bestpos_ascii, "BESTVEL": _bestvel_ascii, "INSPVA": _inspva_ascii,
    "INSPVAS": _inspva_ascii, "INSPVAX": _inspvax_ascii,
}


def _ascii_header(text: str, short: bool) -> Header:
    h = text.split(",")
    name = h[0][:-1] if h[0].endswith("A") else h[0]
    if short:
        _need(h, 3, "short header")
        return Header(name, "ascii-short", integer(h[1], "week"), finite(h[2], "seconds"))
    _need(h, 10, "header")
    return Header(
        name, "ascii", integer(h[5], "week"), finite(h[6], "seconds"), h[1], int(h[2]), _float(h[3]), h[4],
        _hex(h[7]), _hex(h[8]), int(h[9]) if h[9] else 0,
    )


def _log_start(text: str) -> int:
    for i, ch in enumerate(text):
        if ch in "#%" and text[i + 1 : i + 2].isupper():
            return i
    return -1


def parse_ascii(text: str, where: Where) -> NovatelRecord | Reject | None:
    """One ASCII line: a record, a Reject, or None for lines that belong elsewhere."""
    start = _log_start(text)
    if start < 0:
        stripped = text.lstrip()
        if "$" in text or stripped[:1] in ("<", "["):
            return None  # NMEA, abbreviated ASCII, or a port prompt
        return Reject(where, "no NovAtel log in line")
    star = text.rfind("*")
    end = star if star > start else len(text.rstrip())
    if star > start:
        given = text[star + 1 : star + 9]
        computed = crc32(text[start + 1 : star].encode("latin-1"))
        try:
            ok = len(given) == 8 and int(given, 16) == computed
        except ValueError:
            ok = False
        if not ok:
            return Reject(where, f"bad CRC {given!r}, computed {computed:08x}", bad_checksum=True)
    semi = text.find(";", start, end)
    if semi < 0:
        return Reject(where, "truncated NovAtel log: no ';' after the header")
    try:
        header = _ascii_header(text[start + 1 : semi], text[start] == "%")
        parser = _ASCII.get(header.message)
        if parser is None:
            return None
        return parser(text[semi + 1 : end].split(","), where, header)
    except (ValueError, IndexError, OverflowError) as exc:
        return Reject(where, f"bad NovAtel log: {exc}")


# ---------------------------------------------------------------- binary bodies


def _binary_record(name: str, values: tuple, w: Where, h: Header) -> NovatelRecord:
    if name == "BESTPOS":
        v = list(values)
        v[0], v[1] = SOLUTION_STATUS.get(v[0], str(v[0])), POSITION_TYPE.get(v[1], str(v[1]))
        v[6] = DATUM.get(v[6], str(v[6]))
        v[10] = v[10].rstrip(b"\0").decode("latin-1")
        del v[17]  # reserved byte
        return BestPos(w, h, *v)
    if name == "BESTVEL":
        status, velocity_type, latency, age, speed, track, vertical, _ = values  # the last is a reserved float
        return BestVel(
            w, h, SOLUTION_STATUS.get(status, str(status)), POSITION_TYPE.get(velocity_type, str(velocity_type)),
            latency, age, speed, track, vertical,
        )
    if name in ("INSPVA", "INSPVAS"):
        week, seconds, lat, lon, height, north, east, up, roll, pitch, azimuth, ins_status = values
        return InsPva(w, h, week, seconds, lat, lon, height, north, east, up, roll, pitch, azimuth,
                      INS_STATUS.get(ins_status, str(ins_status)))
    return InsPvax(
        w, h, INS_STATUS.get(values[0], str(values[0])), POSITION_TYPE.get(values[1], str(values[1])),
        *values[2:],
    )


def _resync(data: bytes, pos: int) -> int:
    """Where to look after a damaged binary log at `pos`: the next sync or ASCII log line, else the end."""
    sync = _next_sync(data, pos + 1)
    stop = len(data) if sync < 0 else sync
    for i in range(pos + 1, stop):
        if data[i] in b"#%" and data[i + 1 : i + 2].isupper():
            return i
    return stop


def parse_binary(data: bytes, pos: int) -> tuple[NovatelRecord | Reject | None, int]:
    """The binary log at `pos` (a sync) and the offset after it; after a Reject, the next place to look."""
    where = Where(pos)
    short = data[pos + 2] == 0x13
    hdr_len = _HDR_SHORT.size if short else (data[pos + 3] if pos + 3 < len(data) else 28)
    if pos + max(hdr_len, 12) > len(data) or hdr_len < 12:
        return Reject(where, "truncated NovAtel binary header"), _resync(data, pos)
    if short:
        _, length, msg_id, week, ms = _HDR_SHORT.unpack_from(data, pos)
        status, port, seq, idle, rx, reserved, sw = "", "", 0, NAN, 0, 0, 0
    else:
        if hdr_len < _HDR_LONG.size:
            return Reject(where, f"NovAtel binary header length {hdr_len}"), _resync(data, pos)
        (_, _, msg_id, _, port_id, length, seq, idle_raw, ts, week, ms, rx, reserved,
         sw) = _HDR_LONG.unpack_from(data, pos)
        status, port, idle = TIME_STATUS.get(ts, str(ts)), PORTS.get(port_id, str(port_id)), idle_raw / 2.0
    end = pos + hdr_len + length
    if end + 4 > len(data):
        return Reject(where, "truncated NovAtel binary log"), _resync(data, pos)
    given = int.from_bytes(data[end : end + 4], "little")
    computed = crc32(data[pos:end])
    if given != computed:
        return Reject(where, f"bad CRC {given:08x}, computed {computed:08x}", bad_checksum=True), _resync(data, pos)
    name = MESSAGE_IDS.get(msg_id)
    if name is None:
        return None, end + 4
    body = _BODY[name]
    if length < body.size:
        return Reject(where, f"{name} body of {length} bytes, {body.size} needed"), end + 4
    header = Header(name, "binary-short" if short else "binary", week, ms / 1000.0, port, seq, idle, status,
                    rx, reserved, sw)
    return _binary_record(name, body.unpack_from(data, pos + hdr_len), where, header), end + 4


# ---------------------------------------------------------------- streaming


def _text_records(text: str, base: int, numbered: bool, prefix: str) -> Iterator[NovatelRecord | Reject]:
    offset = base
    for number, raw in enumerate(text.split("\n"), start=1):
        line_start = offset
        offset += len(raw) + 1
        line = raw.rstrip("\r")
        if not line.strip():
            continue
        host = None
        if prefix != "none" and line[0] not in "#%$":
            line, host = strip_prefix(line, prefix)
        result = parse_ascii(line, Where(line_start, number if numbered else None, host))
        if result is not None:
            yield result


def _next_sync(data: bytes, pos: int) -> int:
    a, b = data.find(SYNC_LONG, pos), data.find(SYNC_SHORT, pos)
    return a if b < 0 else b if a < 0 else min(a, b)


def decode(data: bytes, prefix: str = "auto") -> Iterator[NovatelRecord | Reject]:
    """Stream every BESTPOS/BESTVEL/INSPVA(S)/INSPVAX log (or Reject) in a file, ASCII or binary.

    In a file holding binary logs, ASCII lines are located by byte offset only.
    """
    if prefix not in PREFIX_STYLES:
        raise ValueError(f"unknown host-timestamp prefix style {prefix!r}; use one of {PREFIX_STYLES}")
    sync = _next_sync(data, 0)
    if sync < 0:
        yield from _text_records(data.decode("latin-1"), 0, True, prefix)
        return
    pos = 0
    while pos < len(data):
        sync = _next_sync(data, pos)
        stop = len(data) if sync < 0 else sync
        if stop > pos:
            yield from _text_records(data[pos:stop].decode("latin-1"), pos, False, prefix)
        if sync < 0:
            return
        result, pos = parse_binary(data, sync)
        if result is not None:
            yield result


# ---------------------------------------------------------------- encoders


def _code(name: str, table: dict[int, str]) -> int:
    for k, v in table.items():
        if v == name:
            return k
    return int(name)


def _fmt(x: float, spec: str) -> str:
    return format(x, spec) if math.isfinite(x) else ""


def _ascii_body(rec: NovatelRecord) -> list[str]:
    if isinstance(rec, BestPos):
        return [
            rec.solution_status, rec.position_type, _fmt(rec.latitude, ".11f"), _fmt(rec.longitude, ".11f"),
            _fmt(rec.height_msl_m, ".4f"), _fmt(rec.undulation_m, ".4f"), rec.datum,
            *(_fmt(x, ".4f") for x in (rec.lat_std_m, rec.lon_std_m, rec.height_std_m)),
            f'"{rec.station_id}"', _fmt(rec.diff_age_s, ".3f"), _fmt(rec.solution_age_s, ".3f"),
            *(str(n) for n in (rec.satellites_tracked, rec.satellites_used, rec.satellites_l1, rec.satellites_multi)),
            "00", f"{rec.extended_status:02x}", f"{rec.galileo_beidou_mask:02x}", f"{rec.gps_glonass_mask:02x}",
        ]
    if isinstance(rec, BestVel):
        return [
            rec.solution_status, rec.velocity_type, _fmt(rec.latency_s, ".3f"), _fmt(rec.age_s, ".3f"),
            _fmt(rec.horizontal_speed_mps, ".4f"), _fmt(rec.track_deg, ".6f"), _fmt(rec.vertical_speed_mps, ".4f"),
            "0.0",
        ]
    if isinstance(rec, InsPva):
        return [
            str(rec.week), f"{rec.seconds:.9f}", _fmt(rec.latitude, ".11f"), _fmt(rec.longitude, ".11f"),
            _fmt(rec.height_m, ".4f"),
            *(_fmt(x, ".4f") for x in (rec.north_mps, rec.east_mps, rec.up_mps)),
            *(_fmt(x, ".9f") for x in (rec.roll_deg, rec.pitch_deg, rec.azimuth_deg)), rec.status,
        ]
    return [
        rec.status, rec.position_type, _fmt(rec.latitude, ".11f"), _fmt(rec.longitude, ".11f"),
        _fmt(rec.height_m, ".4f"), _fmt(rec.undulation_m, ".4f"),
        *(_fmt(x, ".4f") for x in (rec.north_mps, rec.east_mps, rec.up_mps)),
        *(_fmt(x, ".9f") for x in (rec.roll_deg, rec.pitch_deg, rec.azimuth_deg)),
        *(_fmt(x, ".4f") for x in (
            rec.lat_std_m, rec.lon_std_m, rec.height_std_m, rec.north_std_mps, rec.east_std_mps,
            rec.up_std_mps, rec.roll_std_deg, rec.pitch_std_deg, rec.azimuth_std_deg,
        )),
        f"{rec.extended_status:08x}", str(rec.time_since_update_s),
    ]


def encode_ascii(rec: NovatelRecord, short: bool = False) -> str:
    """One ASCII log line (long '#' or short '%' header, valid CRC, CRLF) for a record."""
    h = rec.header
    name = h.message + ("S" if short and h.message == "INSPVA" else "")
    if short:
        head = f"%{name}A,{h.week},{h.seconds:.3f}"
    else:
        head = (
            f"#{name}A,{h.port or 'COM1'},{h.sequence},{_fmt(h.idle_percent, '.1f') or '0.0'},"
            f"{h.time_status or 'FINESTEERING'},{h.week},{h.seconds:.3f},{h.receiver_status:08x},"
            f"{h.reserved:04x},{h.sw_version}"
        )
    payload = head[1:] + ";" + ",".join(_ascii_body(rec))
    return f"{head[0]}{payload}*{crc32(payload.encode('latin-1')):08x}\r\n"


def _binary_values(rec: NovatelRecord) -> tuple:
    if isinstance(rec, BestPos):
        return (
            _code(rec.solution_status, SOLUTION_STATUS), _code(rec.position_type, POSITION_TYPE),
            rec.latitude, rec.longitude, rec.height_msl_m, rec.undulation_m, _code(rec.datum, DATUM),
            rec.lat_std_m, rec.lon_std_m, rec.height_std_m, rec.station_id.encode("latin-1")[:4],
            rec.diff_age_s, rec.solution_age_s, *(max(n, 0) for n in (
                rec.satellites_tracked, rec.satellites_used, rec.satellites_l1, rec.satellites_multi)),
            0, rec.extended_status, rec.galileo_beidou_mask, rec.gps_glonass_mask,
        )
    if isinstance(rec, BestVel):
        return (
            _code(rec.solution_status, SOLUTION_STATUS), _code(rec.velocity_type, POSITION_TYPE),
            rec.latency_s, rec.age_s, rec.horizontal_speed_mps, rec.track_deg, rec.vertical_speed_mps, 0.0,
        )
    if isinstance(rec, InsPva):
        return (
            rec.week, rec.seconds, rec.latitude, rec.longitude, rec.height_m, rec.north_mps, rec.east_mps,
            rec.up_mps, rec.roll_deg, rec.pitch_deg, rec.azimuth_deg, _code(rec.status, INS_STATUS),
        )
    return (
        _code(rec.status, INS_STATUS), _code(rec.position_type, POSITION_TYPE), rec.latitude, rec.longitude,
        rec.height_m, rec.undulation_m, rec.north_mps, rec.east_mps, rec.up_mps, rec.roll_deg, rec.pitch_deg,
        rec.azimuth_deg, rec.lat_std_m, rec.lon_std_m, rec.height_std_m, rec.north_std_mps, rec.east_std_mps,
        rec.up_std_mps, rec.roll_std_deg, rec.pitch_std_deg, rec.azimuth_std_deg, rec.extended_status,
        rec.time_since_update_s,
    )


def encode_binary(rec: NovatelRecord, short: bool = False) -> bytes:
    """One binary log (long or short header, little-endian body, CRC) for a record."""
    h = rec.header
    name = h.message
    if short and name == "INSPVA":
        name = "INSPVAS"
    body = _BODY[name].pack(*_binary_values(rec))
    ms = round(h.seconds * 1000)
    if short:
        head = _HDR_SHORT.pack(SYNC_SHORT, len(body), _IDS[name], h.week, ms)
    else:
        idle = 0 if not math.isfinite(h.idle_percent) else round(h.idle_percent * 2)
        head = _HDR_LONG.pack(
            SYNC_LONG, _HDR_LONG.size, _IDS[name], 0, _PORT_IDS.get(h.port, int(h.port) if h.port.isdigit() else 0x20),
            len(body), h.sequence, idle, _code(h.time_status or "FINESTEERING", TIME_STATUS),
            h.week, ms, h.receiver_status, h.reserved, h.sw_version,
        )
    return head + body + crc32(head + body).to_bytes(4, "little")


def header_at(utc_ns: int, message: str, **kw: object) -> Header:
    """A long ASCII header for a log at UTC ns (GPS week and seconds rounded to the millisecond)."""
    week, sow = unix_ns_to_gps(utc_ns)
    kw.setdefault("port", "COM1")
    kw.setdefault("idle_percent", 50.0)
    kw.setdefault("time_status", "FINESTEERING")
    return Header(message, "ascii", week, round(sow * 1000) / 1000.0, **kw)  # type: ignore[arg-type]  # `kw`: any Header field, by name


def encode_bestposa(
    utc_ns: int, latitude: float, longitude: float, height_msl_m: float, *,
    lat_std_m: float = 1.0, lon_std_m: float = 1.0, height_std_m: float = 2.0,
    undulation_m: float = 0.0, solution_status: str = "SOL_COMPUTED", position_type: str = "SINGLE",
    satellites_tracked: int = 10, satellites_used: int = 9, sequence: int = 0,
) -> str:
    """#BESTPOSA line (long header, valid CRC, CRLF) for a fix at UTC ns."""
    rec = BestPos(
        Where(0), header_at(utc_ns, "BESTPOS", sequence=sequence), solution_status, position_type,
        latitude, longitude, height_msl_m, undulation_m, "WGS84", lat_std_m, lon_std_m, height_std_m,
        "", 0.0, 0.0, satellites_tracked, satellites_used, satellites_used, satellites_used, 0, 0, 0,
    )
    return encode_ascii(rec)


def encode_bestvela(
    utc_ns: int, horizontal_speed_mps: float, track_deg: float, vertical_speed_mps: float = 0.0, *,
    latency_s: float = 0.0, age_s: float = 0.0, solution_status: str = "SOL_COMPUTED",
    velocity_type: str = "DOPPLER_VELOCITY", sequence: int = 0,
) -> str:
    """#BESTVELA line for a velocity at UTC ns."""
    rec = BestVel(
        Where(0), header_at(utc_ns, "BESTVEL", sequence=sequence), solution_status, velocity_type,
        latency_s, age_s, horizontal_speed_mps, track_deg % 360.0, vertical_speed_mps,
    )
    return encode_ascii(rec)


def encode_inspvaa(
    utc_ns: int, latitude: float, longitude: float, height_m: float, north_mps: float, east_mps: float,
    up_mps: float, roll_deg: float, pitch_deg: float, azimuth_deg: float, *,
    status: str = "INS_SOLUTION_GOOD", short: bool = False, sequence: int = 0,
) -> str:
    """#INSPVAA (or %INSPVASA with short=True) line; height ellipsoidal, azimuth = heading."""
    header = header_at(utc_ns, "INSPVA", sequence=sequence)
    rec = InsPva(
        Where(0), header, header.week, header.seconds, latitude, longitude, height_m,
        north_mps, east_mps, up_mps, roll_deg, pitch_deg, azimuth_deg % 360.0, status,
    )
    return encode_ascii(rec, short=short)


def encode_inspvaxa(
    utc_ns: int, latitude: float, longitude: float, height_m: float, north_mps: float, east_mps: float,
    up_mps: float, roll_deg: float, pitch_deg: float, azimuth_deg: float, *,
    lat_std_m: float = 1.0, lon_std_m: float = 1.0, height_std_m: float = 2.0,
    velocity_std_mps: float = 0.05, roll_std_deg: float = 0.05, pitch_std_deg: float = 0.05,
    azimuth_std_deg: float = 0.2, undulation_m: float = 0.0, status: str = "INS_SOLUTION_GOOD",
    position_type: str = "INS_PSRSP", sequence: int = 0,
) -> str:
    """#INSPVAXA line with 1-sigma errors."""
    rec = InsPvax(
        Where(0), header_at(utc_ns, "INSPVAX", sequence=sequence), status, position_type,
        latitude, longitude, height_m, undulation_m, north_mps, east_mps, up_mps, roll_deg, pitch_deg,
        azimuth_deg % 360.0, lat_std_m, lon_std_m, height_std_m, velocity_std_mps, velocity_std_mps,
        velocity_std_mps, roll_std_deg, pitch_std_deg, azimuth_std_deg, 0, 0,
    )
    return encode_ascii(rec)


def with_where(rec: NovatelRecord, where: Where) -> NovatelRecord:
    """The same record at another place (tests compare records whatever their origin)."""
    return replace(rec, where=where)
