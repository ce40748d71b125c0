"""Nortek DVL bottom-track NMEA sentences ($PNORBT family): decode and encode.

As documented for the DVL1000 / Nucleus / Signature telemetry (data formats
DF350-DF359; the field order below is the one in Nortek's examples, also
followed by pynmea2's `nor` module). Each format exists with and without
``TAG=`` prefixes on its fields; tags are stripped and fields read by position.

    $PNORBT              (Signature DF300/301) per beam, as 0/1 plus water velocity
    $PNORBT0 / $PNORBT1  one sentence per beam: beam, date MMDDYY, time
                         hhmmss.ssss, dt1, dt2, beam velocity (m/s), FOM,
                         vertical distance (m), status
    $PNORBT3 / $PNORBT4  dt1, dt2, speed over ground (m/s), direction (°),
                         FOM, vertical distance (m)          -- no time
    $PNORBT6 / $PNORBT7  ping time (Unix s), dt1, dt2, vx, vy, vz (m/s), FOM,
                         vertical distance beam 1-4 (m)
    $PNORBT8 / $PNORBT9  as 6/7, then battery (V), sound speed (m/s),
                         pressure (dbar), temperature (°C), status (hex)

Invalid values: velocity -32.768, distance 0.0, FOM 10.0 -> NaN here.
The NMEA XOR checksum is verified when present.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

from .lines import iter_lines
from .log_blocks import LogText
from .nmea.framing import build, frame
from .numbers import optional
from .records import Reject, Where
from .units import NS

BAD_VELOCITY = -32.768
BAD_FOM = 10.0
_FIELDS = {"": 10, "0": 9, "1": 9, "3": 6, "4": 6, "6": 11, "7": 11, "8": 16, "9": 16}


@dataclass(frozen=True, slots=True)
class BeamReport:
    """$PNORBT0/1: one beam's velocity and vertical distance."""

    where: Where
    sentence: str
    beam: int
    time_ns: int | None
    dt1_s: float
    dt2_s: float
    velocity_mps: float
    figure_of_merit: float
    distance_m: float
    status: str


@dataclass(frozen=True, slots=True)
class SpeedReport:
    """$PNORBT3/4: speed over ground and direction; carries no time."""

    where: Where
    sentence: str
    dt1_s: float
    dt2_s: float
    speed_mps: float
    direction_deg: float
    figure_of_merit: float
    distance_m: float


@dataclass(frozen=True, slots=True)
class VelocityReport:
    """$PNORBT6/7/8/9: XYZ velocity with the ping time; 8/9 add sensors and status."""

    where: Where
    sentence: str
    time_ns: int | None
    dt1_s: float
    dt2_s: float
    velocity_mps: tuple[float, float, float]
    figure_of_merit: float
    distance_m: tuple[float, float, float, float]
    battery_v: float = math.nan
    sound_speed_mps: float = math.nan
    pressure_dbar: float = math.nan
    temperature_c: float = math.nan
    status: str = ""


NortekRecord = BeamReport | SpeedReport | VelocityReport


def _f(text: str) -> float:
    return optional(text.strip())


def _vel(text: str) -> float:
    v = _f(text)
    return math.nan if math.isclose(v, BAD_VELOCITY) else v


def _dist(text: str) -> float:
    v = _f(text)
    return v if v > 0 else math.nan


def _fom(text: str) -> float:
    v = _f(text)
    return math.nan if v == BAD_FOM else v


def unix_to_ns(text: str) -> int | None:
    """Exact ns from a decimal Unix time string ('1452244916.7508'); None if not one."""
    whole, _, frac = text.strip().partition(".")
    if not whole.isdigit() or (frac and not frac.isdigit()):
        return None
    return int(whole) * NS + int((frac + "000000000")[:9])


def _date_time_ns(date: str, tod: str) -> int | None:
    date, tod = date.strip(), tod.strip()
    whole, _, frac = tod.partition(".")
    if len(date) != 6 or not date.isdigit() or len(whole) != 6 or not whole.isdigit():
        return None
    if frac and not frac.isdigit():
        return None
    try:
        dt = datetime(2000 + int(date[4:6]), int(date[0:2]), int(date[2:4]), int(whole[0:2]),
                      int(whole[2:4]), int(whole[4:6]), tzinfo=UTC)
    except ValueError:
        return None
    return int(dt.timestamp()) * NS + int((frac + "000000000")[:9])


def _untag(fields: Sequence[str]) -> list[str]:
    return [f.split("=", 1)[1] if "=" in f else f for f in fields]


def _build_record(kind: str, p: list[str], where: Where, name: str) -> NortekRecord:
    if kind == "":  # Signature DF300/301: ..., distance, water velocity, status
        return BeamReport(where, name, int(p[0]), _date_time_ns(p[1], p[2]), _f(p[3]), _f(p[4]),
                          _vel(p[5]), _fom(p[6]), _dist(p[7]), p[9].strip())
    if kind in ("0", "1"):
        return BeamReport(where, name, int(p[0]), _date_time_ns(p[1], p[2]), _f(p[3]), _f(p[4]),
                          _vel(p[5]), _fom(p[6]), _dist(p[7]), p[8].strip())
    if kind in ("3", "4"):
        return SpeedReport(where, name, _f(p[0]), _f(p[1]), _vel(p[2]), _f(p[3]), _fom(p[4]),
                           _dist(p[5]))
    extra: tuple = (math.nan, math.nan, math.nan, math.nan, "")
    if kind in ("8", "9"):
        extra = (_f(p[11]), _f(p[12]), _f(p[13]), _f(p[14]), p[15].strip())
    return VelocityReport(where, name, unix_to_ns(p[0]), _f(p[1]), _f(p[2]),
                          (_vel(p[3]), _vel(p[4]), _vel(p[5])), _fom(p[6]),
                          (_dist(p[7]), _dist(p[8]), _dist(p[9]), _dist(p[10])), *extra)


def parse_line(text: str, where: Where) -> NortekRecord | Reject | None:
    """One $PNORBTn sentence; None when the line holds no $PNORBT sentence."""
    s = frame(text, "$")
    if s is None or not s.address.startswith("PNORBT"):
        return None
    if s.has_checksum and not s.checksum_ok:
        return Reject(where, f"{s.address}: bad NMEA checksum", bad_checksum=True)
    kind = s.address[6:]
    if kind not in _FIELDS:
        return Reject(where, f"{s.address}: unsupported bottom-track sentence")
    fields = _untag(s.fields)
    if len(fields) < _FIELDS[kind]:
        return Reject(where, f"{s.address}: {len(fields)} fields, needs {_FIELDS[kind]}")
    try:
        return _build_record(kind, fields, where, s.address)
    except ValueError as exc:
        return Reject(where, f"{s.address}: field not a number: {exc}")


def decode(data: LogText, prefix: str = "auto") -> Iterator[NortekRecord | Reject]:
    """Yield every $PNORBT record; other lines (other sentences, noise) are rejected."""
    for line in iter_lines(data, prefix):
        rec = parse_line(line.text, line.where)
        yield rec if rec is not None else Reject(line.where, "not a $PNORBT sentence")


def encode_pnorbt7(time_ns: int, velocity_mps: Sequence[float], distance_m: Sequence[float],
                   figure_of_merit: float = 0.005, dt1_s: float = 0.0, dt2_s: float = 0.0,
                   tags: bool = False) -> str:
    """A $PNORBT7 sentence (or $PNORBT6 with tags); NaN velocity -> -32.768, NaN distance -> 0."""
    sec, rem = divmod(int(time_ns), NS)
    vals = [f"{sec}.{rem // 100_000:04d}", f"{dt1_s:.4f}", f"{dt2_s:.4f}"]
    vals += [f"{v:.4f}" if math.isfinite(v) else "-32.768" for v in velocity_mps]
    vals.append(f"{figure_of_merit:.4f}" if math.isfinite(figure_of_merit) else "10.0000")
    vals += [f"{d:.2f}" if math.isfinite(d) else "0.00" for d in distance_m]
    if tags:
        names = ("TIME", "DT1", "DT2", "VX", "VY", "VZ", "FOM", "D1", "D2", "D3", "D4")
        return build("PNORBT6", [f"{n}={v}" for n, v in zip(names, vals)])
    return build("PNORBT7", vals)
