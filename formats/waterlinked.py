"""Water Linked DVL (A50/A125) serial reports and TCP JSON: decode and encode.

From Water Linked's "DVL protocol" (protocol 2.x). Serial packets start with
``w``, direction ``r``, a command letter, comma-separated options, ``*`` and a
CRC-8 over everything before the ``*`` (polynomial 0x07, init 0, no
reflection, no final xor; two lower-case hex digits):

    wrz,vx,vy,vz,valid(y/n),altitude,fom,cov(9 numbers ;-separated),
        time_of_validity(us),time_of_transmission(us),time(ms since last),status
    wru,id,velocity,distance,rssi,nsd          one per transducer
    wrp,time_stamp,x,y,z,pos_std,roll,pitch,yaw,status    dead reckoning
    wrx,time(ms),vx,vy,vz,fom,altitude,valid,status       (deprecated velocity)
    wrt,d1,d2,d3,d4                                       (deprecated distances)

TCP JSON (port 16171, one object per line): ``"type": "velocity"`` with vx,
vy, vz, fom, covariance (3x3), altitude, transducers (id, velocity,
distance, rssi, nsd, beam_valid), velocity_valid, status, time_of_validity,
time_of_transmission (Unix us); ``"type": "position_local"`` with ts, x, y, z,
std, roll, pitch, yaw, status.

Axes are the DVL's mounted frame (x forward, y right, z down). An altitude
or distance of -1 means invalid (NaN here).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from .lines import iter_lines
from .log_blocks import LogText
from .numbers import integer, optional
from .records import Reject, Where
from .units import TIME_MAX_NS, TIME_MIN_NS


def _crc8_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_TABLE = _crc8_table()


def crc8(data: bytes) -> int:
    """CRC-8 (poly 0x07, init 0, no reflection, xorout 0; check value of b'123456789' is 0xF4)."""
    crc = 0
    for b in data:
        crc = _TABLE[crc ^ b]
    return crc


@dataclass(frozen=True, slots=True)
class VelocityReport:
    """wrz / wrx / JSON "velocity": velocity in the DVL frame, altitude, figure of merit."""

    where: Where
    source: str  # "wrz", "wrx" or "json"
    velocity_mps: tuple[float, float, float]
    valid: bool
    altitude_m: float
    figure_of_merit: float
    covariance: tuple[float, ...]  # 9, row-major; empty when absent
    time_of_validity_us: int | None
    time_of_transmission_us: int | None
    since_last_ms: float
    status: int
    transducers: tuple[TransducerReport, ...] = ()


@dataclass(frozen=True, slots=True)
class TransducerReport:
    """wru (or one entry of JSON "transducers"): one beam's velocity and slant distance."""

    where: Where
    id: int
    velocity_mps: float
    distance_m: float
    rssi_dbm: float
    nsd_dbm: float
    beam_valid: bool


@dataclass(frozen=True, slots=True)
class PositionReport:
    """wrp / JSON "position_local": dead-reckoned position (m, NED from the last reset)."""

    where: Where
    time_s: float
    x_m: float
    y_m: float
    z_m: float
    std_m: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float
    status: int


@dataclass(frozen=True, slots=True)
class LegacyDistances:
    """wrt (deprecated): the four transducer distances (m; NaN when invalid)."""

    where: Where
    distance_m: tuple[float, float, float, float]


WaterLinkedRecord = VelocityReport | TransducerReport | PositionReport | LegacyDistances
_FIELDS = {"wrz": 11, "wru": 5, "wrp": 9, "wrx": 8, "wrt": 4}


def _f(text: str) -> float:
    return optional(str(text).strip())  # a JSON 1e400 or NaN comes as a float: str() gives 'inf', 'nan'


def _pos(v: float) -> float:
    # -1 (or any negative) marks an invalid altitude / distance
    return v if v >= 0 else math.nan


def _int(text: str) -> int | None:
    text = str(text).strip()
    return integer(text) if text.lstrip("-").isdigit() else None


def _serial(kind: str, p: list[str], where: Where) -> WaterLinkedRecord:
    if kind == "wrz":
        cov = tuple(_f(c) for c in p[6].split(";")) if p[6].strip() else ()
        return VelocityReport(where, "wrz", (_f(p[0]), _f(p[1]), _f(p[2])), p[3].strip() == "y",
                              _pos(_f(p[4])), _f(p[5]), cov, _int(p[7]), _int(p[8]), _f(p[9]),
                              _int(p[10]) or 0)
    if kind == "wru":
        return TransducerReport(where, int(p[0]), _f(p[1]), _pos(_f(p[2])), _f(p[3]), _f(p[4]),
                                _f(p[2]) >= 0)
    if kind == "wrp":
        return PositionReport(where, _f(p[0]), _f(p[1]), _f(p[2]), _f(p[3]), _f(p[4]), _f(p[5]), _f(p[6]), _f(p[7]),
                              _int(p[8]) or 0)
    if kind == "wrx":
        return VelocityReport(where, "wrx", (_f(p[1]), _f(p[2]), _f(p[3])), p[6].strip() == "y",
                              _pos(_f(p[5])), _f(p[4]), (), None, None, _f(p[0]), _int(p[7]) or 0)
    d1, d2, d3, d4 = (_pos(_f(x)) for x in p[:4])
    return LegacyDistances(where, (d1, d2, d3, d4))


def parse_serial(text: str, where: Where) -> WaterLinkedRecord | Reject | None:
    """One serial report line (prefix removed); None when it holds no 'wr' report."""
    i = text.find("wr")
    if i < 0:
        return None
    body = text[i:].rstrip("\r\n ")
    star = body.rfind("*")
    if star < 0:
        return Reject(where, f"{body[:3]}: no CRC-8 checksum")
    payload, given = body[:star], body[star + 1 : star + 3]
    try:
        ok = int(given, 16) == crc8(payload.encode("latin-1"))
    except ValueError:
        ok = False
    if not ok:
        return Reject(where, f"{payload[:3]}: bad CRC-8", bad_checksum=True)
    parts = payload.split(",")
    kind = parts[0]
    if kind not in _FIELDS:
        return Reject(where, f"{kind}: not a report")
    if len(parts) - 1 < _FIELDS[kind]:
        return Reject(where, f"{kind}: {len(parts) - 1} fields, needs {_FIELDS[kind]}")
    try:
        return _serial(kind, parts[1:], where)
    except ValueError as exc:
        return Reject(where, f"{kind}: field not a number: {exc}")


def _json_transducer(t: dict[str, Any], where: Where) -> TransducerReport:
    dist = _f(t.get("distance", "nan"))
    return TransducerReport(where, int(t.get("id", -1)), _f(t.get("velocity", "nan")), _pos(dist),
                            _f(t.get("rssi", "nan")), _f(t.get("nsd", "nan")),
                            bool(t.get("beam_valid", dist >= 0)))


# the archivable times (`formats.units`) in microseconds: others are no time of a trial
_US_MIN, _US_MAX = TIME_MIN_NS // 1000, TIME_MAX_NS // 1000


def _us(value: Any) -> int | None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and _US_MIN <= value < _US_MAX
    return int(value) if ok else None


def parse_json(text: str, where: Where) -> WaterLinkedRecord | Reject:
    """One TCP JSON message; velocity and position_local reports, anything else rejected."""
    try:
        obj = json.loads(text)
    except (ValueError, RecursionError) as exc:
        return Reject(where, f"not JSON: {exc}")
    if not isinstance(obj, dict):
        return Reject(where, "JSON message is not an object")
    kind = obj.get("type")
    try:
        if kind == "velocity":
            cov = tuple(_f(x) for row in obj.get("covariance") or () for x in row)
            trans = tuple(_json_transducer(t, where) for t in obj.get("transducers") or ())
            return VelocityReport(
                where, "json", (_f(obj["vx"]), _f(obj["vy"]), _f(obj["vz"])),
                bool(obj.get("velocity_valid", False)), _pos(_f(obj.get("altitude", -1))),
                _f(obj.get("fom", "nan")), cov, _us(obj.get("time_of_validity")),
                _us(obj.get("time_of_transmission")), _f(obj.get("time", "nan")),
                int(obj.get("status", 0)), trans)
        if kind == "position_local":
            return PositionReport(where, _f(obj["ts"]), _f(obj["x"]), _f(obj["y"]), _f(obj["z"]), _f(obj["std"]),
                                  _f(obj.get("roll", "nan")), _f(obj.get("pitch", "nan")), _f(obj.get("yaw", "nan")),
                                  int(obj.get("status", 0)))
    except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as exc:
        return Reject(where, f"JSON {kind} report: bad or missing field {exc}")
    return Reject(where, f"JSON message of type {kind!r} is not a report")


def decode(data: LogText, prefix: str = "auto") -> Iterator[WaterLinkedRecord | Reject]:
    """Yield every report in a serial or TCP-JSON log (both may be mixed, line by line)."""
    for line in iter_lines(data, prefix):
        j = line.text.find("{")
        w = line.text.find("wr")
        if j >= 0 and (w < 0 or j < w):
            yield parse_json(line.text[j:], line.where)
            continue
        rec = parse_serial(line.text, line.where)
        yield rec if rec is not None else Reject(line.where, "not a Water Linked report")


def _sentence(payload: str) -> str:
    return f"{payload}*{crc8(payload.encode('latin-1')):02x}\r\n"


def encode_wrz(velocity_mps: Sequence[float], valid: bool, altitude_m: float,
               figure_of_merit: float, time_of_validity_us: int,
               time_of_transmission_us: int | None = None, since_last_ms: float = 100.0,
               covariance: Sequence[float] = (0.0,) * 9, status: int = 0) -> str:
    """A wrz velocity report with its CRC-8 and CRLF (NaN altitude -> -1)."""
    tot = time_of_validity_us if time_of_transmission_us is None else time_of_transmission_us
    alt = altitude_m if math.isfinite(altitude_m) else -1.0
    cov = ";".join(f"{c:.6g}" for c in covariance)
    vx, vy, vz = (v if math.isfinite(v) else 0.0 for v in velocity_mps)
    return _sentence(f"wrz,{vx:.3f},{vy:.3f},{vz:.3f},{'y' if valid else 'n'},{alt:.2f},"
                     f"{figure_of_merit:.3f},{cov},{time_of_validity_us},{tot},"
                     f"{since_last_ms:.2f},{status}")


def encode_wru(transducer: int, velocity_mps: float, distance_m: float, rssi_dbm: float = -40.0,
               nsd_dbm: float = -95.0) -> str:
    """A wru transducer report with its CRC-8 and CRLF (NaN distance -> -1)."""
    dist = distance_m if math.isfinite(distance_m) else -1.0
    return _sentence(f"wru,{transducer},{velocity_mps:.3f},{dist:.2f},{rssi_dbm:.0f},{nsd_dbm:.0f}")
