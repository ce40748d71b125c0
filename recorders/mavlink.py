"""ArduSub / ArduPilot MAVLink logs (`format = "mavlink"`: `.tlog`, dataflash `.BIN`) into sensor topics.

MAVLink (tlog) messages:

- ``GPS_RAW_INT``, ``GPS_INPUT`` (a Water Linked UGPS or other external fix) -> ``/<v>/gps``,
  ``/<v>/gps/status`` (fix type 0/1 -> status only) and ``/<v>/gps/velocity``; ``GLOBAL_POSITION_INT``
  (the EKF's fused position) also when the log has neither, so that the vehicle has one fix source, never
  two interleaved.
- ``GLOBAL_POSITION_INT`` with the latest ``ATTITUDE`` -> ``/<v>/ins`` (depth = -relative altitude, velocity
  NED); a log without GLOBAL_POSITION_INT gives attitude-only states from ATTITUDE.
- ``VISION_SPEED_ESTIMATE`` -> ``/<v>/dvl`` EARTH_NED; ``VISION_POSITION_DELTA`` (the DVL's path into ArduSub)
  -> ``/<v>/dvl`` BODY_FRD, position delta / time delta, valid when its confidence is above 0;
  ``DISTANCE_SENSOR`` facing down (orientation 25) -> ``/<v>/dvl`` altitude only (velocity NaN, not valid).

Dataflash records are mapped the same way by name: ``GPS`` -> fixes, ``ATT`` with ``POS`` -> INS state,
``VISV`` -> EARTH_NED velocity, ``VISO`` -> BODY_FRD velocity, ``RFND`` -> altitude.

Times are the log's own plus the clock offset: a tlog's receive time; for dataflash, each record's
microseconds since boot (TimeUS) put on UTC by the first GPS record with a GPS week (`formats.gpstime`'s
leap-second table: pymavlink's own dataflash clock assumes today's 18 s); a dataflash log without one
has no UTC time, and its records are rejected saying so. BAD_DATA runs are rejected
and counted; every other message is archived, merged (ATTITUDE into the next INS state) or ignored by type.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from formats import gpstime
from formats import mavlink as mv
from formats import schemas as S
from formats.records import FormatError, Reject, Where

from . import dvl
from .base import Converter, Ignored, LogContext, Output, output
from .containers import checked_times
from .gnss_velocity import SUFFIX as VELOCITY
from .gnss_velocity import gnss_velocity, has_velocity
from .gps import gnss_status
from .ins import ins_state

NAN = math.nan
FIX_TYPES = ("GPS_RAW_INT", "GPS_INPUT", "GPS")
DOWNWARD = 25  # MAV_SENSOR_ROTATION_PITCH_270
# GPS_FIX_TYPE -> GGA-style quality: 0/1 none, 2/3 fix, 4 DGPS, 5 RTK float, 6 RTK fixed, 7 static, 8 PPP
FIX_QUALITY = {0: 0, 1: 0, 2: 1, 3: 1, 4: 2, 5: 5, 6: 4, 7: 7, 8: 5}


def _f(fields: dict, key: str, scale: float = 1.0) -> float:
    value = fields.get(key)
    try:
        f = float(value) * scale  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return NAN
    return f if math.isfinite(f) else NAN


def _fix(ctx: LogContext, m: mv.MavMessage, t: int, where: Where) -> Iterator[Output]:
    f = m.fields
    north = east = up = NAN
    if m.type == "GPS_RAW_INT":
        lat, lon, alt = _f(f, "lat", 1e-7), _f(f, "lon", 1e-7), _f(f, "alt", 1e-3)
        hdop = _f(f, "eph", 0.01) if f.get("eph") != 65535 else NAN
        speed = _f(f, "vel", 0.01) if f.get("vel") != 65535 else NAN
        course = _f(f, "cog", 0.01) if f.get("cog") != 65535 else NAN
        fix_type, sats = int(f.get("fix_type", 0) or 0), int(f.get("satellites_visible", 255) or 0)
    elif m.type == "GPS_INPUT":
        lat, lon, alt = _f(f, "lat", 1e-7), _f(f, "lon", 1e-7), _f(f, "alt")
        hdop, fix_type, sats = _f(f, "hdop"), int(f.get("fix_type", 0) or 0), int(f.get("satellites_visible", 255))
        north, east, up = _f(f, "vn"), _f(f, "ve"), -_f(f, "vd")
        speed = course = NAN
    elif m.type == "GPS":  # dataflash
        lat, lon, alt = _f(f, "Lat"), _f(f, "Lng"), _f(f, "Alt")
        hdop, fix_type, sats = _f(f, "HDop"), int(f.get("Status", 0) or 0), int(f.get("NSats", 255) or 0)
        speed, course, up = _f(f, "Spd"), _f(f, "GCrs"), -_f(f, "VZ")  # VZ: down positive (NED)
    else:  # GLOBAL_POSITION_INT: the EKF's position
        lat, lon, alt = _f(f, "lat", 1e-7), _f(f, "lon", 1e-7), _f(f, "alt", 1e-3)
        hdop, fix_type, sats = NAN, 3, -1
        north, east, up = _f(f, "vx", 0.01), _f(f, "vy", 0.01), -_f(f, "vz", 0.01)
        speed = course = NAN
    if math.isnan(speed) and math.isfinite(north) and math.isfinite(east):
        speed, course = math.hypot(north, east), math.degrees(math.atan2(east, north)) % 360.0
    quality = FIX_QUALITY.get(fix_type, 1)
    if quality > 0 and math.isfinite(lat) and math.isfinite(lon) and (lat, lon) != (0.0, 0.0):
        yield output(ctx, "gps", S.location_fix(t, ctx.vehicle, lat, lon, alt), t, where)
    sats = sats if 0 <= sats < 255 else -1
    yield output(ctx, "gps/status", gnss_status(t, ctx.vehicle, quality, sats, hdop, "mavlink:" + m.type,
                                                speed, course, NAN), t, where)
    if quality > 0 and has_velocity(speed, north):
        yield output(ctx, VELOCITY, gnss_velocity(ctx, t, "mavlink:" + m.type, north=north, east=east, up=up,
                                                  speed=speed, course=course), t, where)


def _attitude(m: mv.MavMessage) -> tuple[float, float, float]:
    f = m.fields
    if m.type == "ATT":  # dataflash, degrees
        return _f(f, "Roll"), _f(f, "Pitch"), _f(f, "Yaw") % 360.0
    return math.degrees(_f(f, "roll")), math.degrees(_f(f, "pitch")), math.degrees(_f(f, "yaw")) % 360.0


def _ins(ctx: LogContext, m: mv.MavMessage | None, att: mv.MavMessage | None, t: int, where: Where) -> Output:
    roll, pitch, heading = _attitude(att) if att is not None else (NAN, NAN, NAN)
    lat = lon = depth = vn = ve = vd = NAN
    if m is not None:
        f = m.fields
        if m.type == "POS":
            lat, lon, depth = _f(f, "Lat"), _f(f, "Lng"), -_f(f, "RelHomeAlt")
        else:
            lat, lon, depth = _f(f, "lat", 1e-7), _f(f, "lon", 1e-7), -_f(f, "relative_alt", 1e-3)
            vn, ve, vd = _f(f, "vx", 0.01), _f(f, "vy", 0.01), _f(f, "vz", 0.01)
            if not math.isfinite(heading) and f.get("hdg") != 65535:
                heading = _f(f, "hdg", 0.01)
    source = "mavlink:" + "+".join(x.type for x in (m, att) if x is not None)
    state = ins_state(t, ctx, source, latitude=lat, longitude=lon, depth_m=depth, roll_deg=roll, pitch_deg=pitch,
                      heading_deg=heading, velocity_north_mps=vn, velocity_east_mps=ve, velocity_down_mps=vd)
    return output(ctx, "ins", state, t, where)


def _velocity(ctx: LogContext, m: mv.MavMessage, t: int, where: Where) -> Output | Reject | Ignored:
    f, source = m.fields, "mavlink:" + m.type
    if m.type in ("VISION_SPEED_ESTIMATE", "VISV"):
        keys = ("x", "y", "z") if m.type == "VISION_SPEED_ESTIMATE" else ("VX", "VY", "VZ")
        v = tuple(_f(f, k) for k in keys)
        return output(ctx, "dvl", dvl.message(ctx, t, "EARTH_NED", v, source=source), t, where)
    if m.type in ("VISION_POSITION_DELTA", "VISO"):
        if m.type == "VISO":
            dt, delta, conf = _f(f, "dt"), [_f(f, k) for k in ("PosDX", "PosDY", "PosDZ")], _f(f, "conf")
        else:
            dt = _f(f, "time_delta_usec", 1e-6)
            raw = f.get("position_delta") or (NAN, NAN, NAN)
            delta, conf = [float(x) for x in list(raw)[:3]], _f(f, "confidence")
        if not dt > 0:
            return Reject(where, f"{m.type}: time delta {dt!r} s is not positive")
        v = tuple(d / dt for d in delta)
        return output(ctx, "dvl", dvl.message(ctx, t, "BODY_FRD", v, valid=conf > 0 and all(map(math.isfinite, v)),
                                             fom=NAN, source=source), t, where)
    # DISTANCE_SENSOR / RFND: the DVL's (or an echosounder's) altitude
    if m.type == "RFND":
        distance, orientation = _f(f, "Dist"), int(f.get("Orient", DOWNWARD) or 0)
    else:
        distance, orientation = _f(f, "current_distance", 0.01), int(f.get("orientation", -1))
    if orientation != DOWNWARD:
        return Ignored(where, f"{m.type} not facing down (orientation {orientation})")
    return output(ctx, "dvl", dvl.message(ctx, t, "BODY_FRD", (NAN, NAN, NAN), altitude=distance, valid=False,
                                         source=source), t, where)


def _dataflash_boot_ns(messages: list[tuple[mv.MavMessage, Where]]) -> int | None:
    """UTC (ns) of a dataflash log's boot, from its first GPS record with a week; None for a tlog."""
    if not any("TimeUS" in m.fields for m, _ in messages[:50]):
        return None
    for m, _ in messages:
        f = m.fields
        if m.type == "GPS" and int(f.get("GWk", 0) or 0) > 0 and "TimeUS" in f:
            return gpstime.gps_to_unix_ns(int(f["GWk"]), float(f.get("GMS", 0)) / 1000.0) - int(f["TimeUS"]) * 1000
    return 0  # dataflash without GPS time: every record is rejected as untimed


def _on_utc(m: mv.MavMessage, boot_ns: int) -> mv.MavMessage:
    us = m.fields.get("TimeUS")
    if not boot_ns or not isinstance(us, int):
        return mv.MavMessage(m.type, 0, m.index, m.fields, m.problem)
    return mv.MavMessage(m.type, boot_ns + us * 1000, m.index, m.fields, m.problem)


VELOCITY_TYPES = ("VISION_SPEED_ESTIMATE", "VISION_POSITION_DELTA", "DISTANCE_SENSOR", "VISV", "VISO", "RFND")


def convert_mavlink(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    """ArduSub/ArduPilot .tlog and dataflash .BIN (pymavlink): GPS, EKF position + attitude, vision/DVL, range."""
    return checked_times(_convert_mavlink(data, ctx))


def _convert_mavlink(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    if not ctx.files:
        raise FormatError("a MAVLink log is read from its file: no file given")
    messages: list[tuple[mv.MavMessage, Where]] = []
    start, number = 0, 0
    for path in ctx.files:
        size = path.stat().st_size
        for m in mv.read_mavlink(path):
            number += 1
            messages.append((m, Where(start + min(m.index, max(size - 1, 0)), None, m.time_ns or None, number)))
        start += size
    boot_ns = _dataflash_boot_ns(messages)
    if boot_ns is not None:
        messages = [(_on_utc(m, boot_ns), w) for m, w in messages]
    types = {m.type for m, _ in messages}
    ekf_as_fix = not types & {"GPS_RAW_INT", "GPS_INPUT", "GPS"}
    ekf_types = {"GLOBAL_POSITION_INT", "POS"}
    has_ekf = bool(types & ekf_types)
    attitude: mv.MavMessage | None = None
    for m, where in messages:
        t = m.time_ns + ctx.clock_offset_ns
        if m.problem:
            yield Reject(where, m.problem)
        elif m.time_ns <= 0:
            yield Reject(where, f"{m.type} without a time" if boot_ns is None else
                         f"{m.type}: no UTC time (the dataflash log has no GPS record with a GPS week)")
        elif m.type in FIX_TYPES:
            yield from _fix(ctx, m, t, where)
        elif m.type in ekf_types:
            yield _ins(ctx, m, attitude, t, where)
            if ekf_as_fix and m.type == "GLOBAL_POSITION_INT":
                yield from _fix(ctx, m, t, where)
        elif m.type in ("ATTITUDE", "ATT"):
            attitude = m
            if has_ekf:
                yield Ignored(where, f"{m.type} merged into the next INS state")
            else:
                yield _ins(ctx, None, m, t, where)
        elif m.type in VELOCITY_TYPES:
            yield _velocity(ctx, m, t, where)
        else:
            yield Ignored(where, f"MAVLink {m.type} is not mapped")


MANIFEST_EXAMPLE = """[[vehicles.logs]]
format = "mavlink"                 # ArduSub/ArduPilot telemetry .tlog or dataflash .BIN
path = "bluerov/2016-10-12 02-00-00.tlog"
"""

CONVERTERS: dict[str, Converter] = {"mavlink": convert_mavlink}
# the formats whose logs are (or may be) binary: read as bytes, never cut into lines (`recorders.registry`)
BINARY_FORMATS = frozenset({"mavlink"})  # tlog or dataflash
