"""Teledyne RDI PD6 (and PD13) ASCII DVL output: decode lines, group ensembles, encode.

Lines (Pathfinder DVL Guide, "Pathfinder Output Data Format (PD6)"), no checksum:

    :SA,±PP.PP,±RR.RR,HHH.HH                   pitch, roll, heading (°)
    :TS,YYMMDDHHmmsshh,SS.S,±TT.T,DDDD.D,CCCC.C,BBB
                                               time, salinity, temperature, depth,
                                               speed of sound, BIT
    :RA,PPP.PP,R1,R2,R3,R4                     (PD13) pressure kPa, ranges in dm
    :WI / :BI,±X,±Y,±Z,±E,S                    instrument velocity (mm/s), A good / V bad
    :WS / :BS,±T,±L,±N,S                       ship: transverse (to starboard),
                                               longitudinal (forward), normal (up)
    :WE / :BE,±E,±N,±U,S                       earth: east, north, up
    :WD / :BD,±E,±N,±U,range,time              distance made good (m), range to
                                               bottom (m), time since last good (s)

PD6 reports the vessel moving over a still bottom (no negation, unlike PD0);
-32768 is a bad velocity. Real outputs pad fields with spaces (" +24"), which
are ignored. An ensemble runs from :SA or :TS to the next :SA or :TS.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

from .lines import iter_lines
from .log_blocks import LogText
from .numbers import optional
from .records import Reject, Where
from .units import NS

BAD = -32768
VELOCITY_TAGS = ("WI", "BI", "WS", "BS", "WE", "BE")


@dataclass(frozen=True, slots=True)
class Attitude:
    """:SA line."""

    where: Where
    pitch_deg: float
    roll_deg: float
    heading_deg: float


@dataclass(frozen=True, slots=True)
class TimeScale:
    """:TS line: the ensemble time (UTC ns, None if the stamp is invalid) and environment."""

    where: Where
    time_ns: int | None
    salinity_ppt: float
    temperature_c: float
    depth_m: float
    sound_speed_mps: float
    bit: int


@dataclass(frozen=True, slots=True)
class Velocity:
    """:WI/:BI/:WS/:BS/:WE/:BE line: velocities in m/s (NaN bad), status 'A' good / 'V' bad."""

    where: Where
    tag: str
    values_mps: tuple[float, ...]  # 4 for WI/BI (x, y, z, error), 3 otherwise
    status: str

    @property
    def good(self) -> bool:
        """Status A and every component valid."""
        return self.status == "A" and all(math.isfinite(v) for v in self.values_mps[:3])


@dataclass(frozen=True, slots=True)
class Distance:
    """:WD/:BD line: distance made good east/north/up (m), range (m), time since good (s)."""

    where: Where
    tag: str
    east_m: float
    north_m: float
    up_m: float
    range_m: float
    time_since_good_s: float


@dataclass(frozen=True, slots=True)
class Ranges:
    """:RA line (PD13): pressure (kPa) and per-beam ranges to bottom (m; NaN when 0)."""

    where: Where
    pressure_kpa: float
    range_m: tuple[float, ...]


Pd6Line = Attitude | TimeScale | Velocity | Distance | Ranges


@dataclass(frozen=True, slots=True)
class Pd6Ensemble:
    """The lines of one output cycle, grouped; missing parts are None."""

    where: Where
    attitude: Attitude | None = None
    timescale: TimeScale | None = None
    ranges: Ranges | None = None
    velocities: dict[str, Velocity] = field(default_factory=dict)
    distances: dict[str, Distance] = field(default_factory=dict)

    @property
    def time_ns(self) -> int | None:
        """The :TS time, else the host time of the first line, else None."""
        if self.timescale is not None and self.timescale.time_ns is not None:
            return self.timescale.time_ns
        return self.where.host_time_ns


def _num(text: str) -> float:
    return optional(text.strip())


def _ts_time(stamp: str) -> int | None:
    s = stamp.strip()
    if len(s) != 14 or not s.isdigit():
        return None
    try:
        dt = datetime(2000 + int(s[0:2]), int(s[2:4]), int(s[4:6]), int(s[6:8]), int(s[8:10]),
                      int(s[10:12]), tzinfo=UTC)
    except ValueError:
        return None
    return int(dt.timestamp()) * NS + int(s[12:14]) * 10_000_000


def _mps(text: str) -> float:
    v = _num(text)
    return math.nan if v == BAD or not math.isfinite(v) else v / 1000


def parse_line(text: str, where: Where) -> Pd6Line | Reject | None:
    """One PD6 line (prefix already removed); None when it is not a PD6 line at all."""
    i = text.find(":")
    if i < 0 or len(text) < i + 3:
        return None
    tag, parts = text[i + 1 : i + 3], text[i + 1 :].rstrip().split(",")[1:]
    need = {"SA": 3, "TS": 6, "RA": 5, "WD": 5, "BD": 5}.get(tag, 5 if tag in ("WI", "BI") else 4)
    if tag not in ("SA", "TS", "RA", "WD", "BD") + VELOCITY_TAGS:
        return None
    if len(parts) < need:
        return Reject(where, f":{tag} has {len(parts)} fields, needs {need}")
    try:
        if tag == "SA":
            return Attitude(where, _num(parts[0]), _num(parts[1]), _num(parts[2]))
        if tag == "TS":
            bit = parts[5].strip()
            return TimeScale(where, _ts_time(parts[0]), _num(parts[1]), _num(parts[2]),
                             _num(parts[3]), _num(parts[4]), int(bit) if bit.isdigit() else -1)
        if tag == "RA":
            rng = tuple(_num(p) / 10 if _num(p) > 0 else math.nan for p in parts[1:5])
            return Ranges(where, _num(parts[0]), rng)
        if tag in ("WD", "BD"):
            return Distance(where, tag, *(_num(p) for p in parts[:5]))
        return Velocity(where, tag, tuple(_mps(p) for p in parts[: need - 1]),
                        parts[need - 1].strip())
    except ValueError as exc:
        return Reject(where, f":{tag} field not a number: {exc}")


def decode(data: LogText, prefix: str = "auto") -> Iterator[Pd6Line | Reject]:
    """Yield every PD6/PD13 line record; non-PD6 text lines are rejected as noise."""
    for line in iter_lines(data, prefix):
        rec = parse_line(line.text, line.where)
        if rec is None:
            yield Reject(line.where, "not a PD6 line")
        else:
            yield rec


def ensembles(data: LogText, prefix: str = "auto") -> Iterator[Pd6Ensemble | Reject]:
    """Group decoded lines into ensembles (a new :SA or :TS, or a repeated tag, starts one)."""
    cur: dict | None = None
    for rec in decode(data, prefix):
        if isinstance(rec, Reject):
            yield rec
            continue
        starts = isinstance(rec, (Attitude, TimeScale))
        if cur is not None and (starts and _has_data(cur) or _repeats(cur, rec)):
            yield _build(cur)
            cur = None
        if cur is None:
            cur = {"where": rec.where, "velocities": {}, "distances": {}}
        _add(cur, rec)
    if cur is not None:
        yield _build(cur)


def _has_data(cur: dict) -> bool:
    return bool(cur["velocities"] or cur["distances"] or "ranges" in cur)


def _repeats(cur: dict, rec: Pd6Line) -> bool:
    if isinstance(rec, Attitude):
        return "attitude" in cur
    if isinstance(rec, TimeScale):
        return "timescale" in cur
    if isinstance(rec, Velocity):
        return rec.tag in cur["velocities"]
    if isinstance(rec, Distance):
        return rec.tag in cur["distances"]
    return "ranges" in cur


def _add(cur: dict, rec: Pd6Line) -> None:
    if isinstance(rec, Attitude):
        cur["attitude"] = rec
    elif isinstance(rec, TimeScale):
        cur["timescale"] = rec
    elif isinstance(rec, Ranges):
        cur["ranges"] = rec
    elif isinstance(rec, Velocity):
        cur["velocities"][rec.tag] = rec
    else:
        cur["distances"][rec.tag] = rec


def _build(cur: dict) -> Pd6Ensemble:
    return Pd6Ensemble(**cur)


def vehicle_velocity(ens: Pd6Ensemble, frame: str | None = None
                     ) -> tuple[str, float, float, float, float, bool] | None:
    """(frame, x, y, z, error, good) from bottom-track lines, or None without any.

    Preference BS (BODY_FRD: longitudinal, transverse, -normal), then BE
    (EARTH_NED: north, east, -up), then BI (INSTRUMENT: x, y, z, error);
    `frame` ('BODY_FRD', 'EARTH_NED', 'INSTRUMENT') picks one explicitly.
    """
    order = {"BODY_FRD": "BS", "EARTH_NED": "BE", "INSTRUMENT": "BI"}
    tags = [order[frame]] if frame in order else ["BS", "BE", "BI"]
    err = ens.velocities["BI"].values_mps[3] if "BI" in ens.velocities else math.nan
    for tag in tags:
        v = ens.velocities.get(tag)
        if v is None:
            continue
        a, b, c = v.values_mps[:3]
        if tag == "BI":
            return ("INSTRUMENT", a, b, c, v.values_mps[3], v.good)
        name = "BODY_FRD" if tag == "BS" else "EARTH_NED"
        return (name, b, a, -c, err, v.good)
    return None


# --- encoding (simulation and tests) -----------------------------------------------------


def _mm(v: float) -> str:
    return f"{BAD:+d}" if not math.isfinite(v) else f"{max(-32767, min(32767, round(v * 1000))):+d}"


def encode_sa(pitch_deg: float, roll_deg: float, heading_deg: float) -> str:
    """:SA line with CRLF."""
    return f":SA,{pitch_deg:+06.2f},{roll_deg:+06.2f},{heading_deg % 360:06.2f}\r\n"


def encode_ts(time_ns: int, *, salinity_ppt: float = 0.0, temperature_c: float = 10.0,
              depth_m: float = 0.0, sound_speed_mps: float = 1500.0, bit: int = 0) -> str:
    """:TS line with CRLF (time truncated to 0.01 s; years 2000-2099)."""
    sec, rem = divmod(int(time_ns), NS)
    dt = datetime.fromtimestamp(sec, tz=UTC)
    stamp = dt.strftime("%y%m%d%H%M%S") + f"{rem // 10_000_000:02d}"
    return (f":TS,{stamp},{salinity_ppt:04.1f},{temperature_c:+05.1f},{depth_m:06.1f},"
            f"{sound_speed_mps:06.1f},{bit:03d}\r\n")


def encode_velocity(tag: str, values_mps: Sequence[float], good: bool | None = None) -> str:
    """:WI/:BI (4 values) or :WS/:BS/:WE/:BE (3 values) line with CRLF."""
    if good is None:
        good = all(math.isfinite(v) for v in values_mps[:3])
    return f":{tag}," + ",".join(_mm(v) for v in values_mps) + f",{'A' if good else 'V'}\r\n"


def encode_distance(tag: str, east_m: float, north_m: float, up_m: float, range_m: float,
                    time_since_good_s: float) -> str:
    """:WD/:BD line with CRLF."""
    return (f":{tag},{east_m:+012.2f},{north_m:+012.2f},{up_m:+012.2f},{range_m:07.2f},"
            f"{time_since_good_s:06.2f}\r\n")


def encode_ensemble(time_ns: int, forward_mps: float, starboard_mps: float, down_mps: float,
                    altitude_m: float, *, heading_deg: float = 0.0, pitch_deg: float = 0.0,
                    roll_deg: float = 0.0, temperature_c: float = 10.0, depth_m: float = 0.0,
                    sound_speed_mps: float = 1500.0) -> str:
    """A PD6 cycle (:SA :TS :BI :BS :BE :BD) for a vehicle velocity in body FRD axes.

    BI and BS carry the same values (a DVL mounted aligned with the body);
    BE rotates by the heading (pitch and roll ignored); NaN altitude writes 0.
    """
    h = math.radians(heading_deg)
    north = forward_mps * math.cos(h) - starboard_mps * math.sin(h)
    east = forward_mps * math.sin(h) + starboard_mps * math.cos(h)
    rng = altitude_m if math.isfinite(altitude_m) else 0.0
    return "".join([
        encode_sa(pitch_deg, roll_deg, heading_deg),
        encode_ts(time_ns, temperature_c=temperature_c, depth_m=depth_m,
                  sound_speed_mps=sound_speed_mps),
        encode_velocity("BI", (starboard_mps, forward_mps, -down_mps, 0.0)),
        encode_velocity("BS", (starboard_mps, forward_mps, -down_mps)),
        encode_velocity("BE", (east, north, -down_mps)),
        encode_distance("BD", 0.0, 0.0, 0.0, rng, 0.0),
    ])
