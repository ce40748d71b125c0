"""ArduSub / ArduPilot MAVLink logs (`format = "mavlink"`: `.tlog`, dataflash `.BIN`) into sensor topics.

MAVLink (tlog) messages:

- ``GPS_RAW_INT``, ``GPS_INPUT`` (a Water Linked UGPS or other external fix) -> ``/<v>/gps``,
  ``/<v>/gps/status`` (fix type 0/1 -> status only) and ``/<v>/gps/velocity``; ``GLOBAL_POSITION_INT``
  (the EKF's fused position) also when the log has neither, so that the vehicle has one fix source, never
  two interleaved.
- ``GLOBAL_POSITION_INT`` with the latest ``ATTITUDE`` -> ``/<v>/ins`` (depth = -relative altitude, velocity
  NED); a log without GLOBAL_POSITION_INT gives attitude-only states from ATTITUDE.
- ``LOCAL_POSITION_NED`` (the EKF's x/y/z north/east/down of its origin) -> ``/<v>/ins/local``, an InsState with
  latitude/longitude about the origin (flat earth), depth = z, velocity NED. The origin: the latest
  ``GPS_GLOBAL_ORIGIN`` before it, else the log's first (the EKF sets it once per boot; a GCS may ask for it
  late), else the manifest's ``origin = [lat, lon]``; without any it is ignored, saying so.
- ``VISION_SPEED_ESTIMATE`` -> ``/<v>/dvl`` EARTH_NED; ``VISION_POSITION_DELTA`` (the DVL's path into ArduSub)
  -> ``/<v>/dvl`` BODY_FRD, position delta / time delta, valid when its confidence is above 0;
  ``DISTANCE_SENSOR`` facing down (orientation 25) -> ``/<v>/dvl`` altitude only (velocity NaN, not valid).

Dataflash records are mapped the same way by name: ``GPS`` -> fixes, ``ATT`` with ``POS`` -> INS state,
``VISV`` -> EARTH_NED velocity, ``VISO`` -> BODY_FRD velocity, ``RFND`` -> altitude. A log without ``POS``
(an EKF without an origin logs none) takes its INS states from the EKF's own ``XKF1`` (EKF3; ``NKF1``,
EKF2) of core 0: attitude, NED velocity, depth = its down position PD (ArduSub's height reference is the
depth sensor, zeroed at the surface), latitude/longitude from PN/PE about the log's ``ORGN`` EKF origin or
else the manifest's ``origin = [lat, lon]`` (NaN without either); ``ATT`` is then ignored. A log with
neither POS nor XKF1 gives attitude-only states from ``ATT`` with the depth of the latest ``BARO`` of
the depth sensor (``baro_instance``, default the log's highest instance; depth = -Alt).

Times are the log's own plus the clock offset: a tlog's receive time; for dataflash, each record's
microseconds since boot (TimeUS) put on UTC by the first record with a GPS week and time (GPS GWk/GMS;
`formats.gpstime`'s leap-second table: pymavlink's own dataflash clock assumes today's 18 s), or, for a log
without GPS time, by the manifest's `time_base = "boot"` with `start` = the UTC instant of boot
(docs/time-bases.md). A log with neither is refused in one line naming those keys; a log with both is
refused too (its GPS time is never overridden silently: `clock_offset_s` corrects it). BAD_DATA runs are
rejected and counted; every other message is archived, merged (ATTITUDE into the next INS state) or ignored
by type.
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
from .clock import RELATIVE_BASES, iso_utc
from .containers import checked_times, local_to_geodetic, origin_option
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


def _ins(ctx: LogContext, m: mv.MavMessage | None, att: mv.MavMessage | None, t: int, where: Where,
         depth: float = NAN) -> Output:
    roll, pitch, heading = _attitude(att) if att is not None else (NAN, NAN, NAN)
    lat = lon = vn = ve = vd = NAN
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


def _global_origin(m: mv.MavMessage) -> tuple[float, float] | None:
    """(lat, lon) degrees of a GPS_GLOBAL_ORIGIN, or None when it is not a position."""
    lat, lon = _f(m.fields, "latitude", 1e-7), _f(m.fields, "longitude", 1e-7)
    ok = math.isfinite(lat) and math.isfinite(lon) and abs(lat) <= 90 and abs(lon) <= 180 and (lat, lon) != (0, 0)
    return (lat, lon) if ok else None


def _local(ctx: LogContext, m: mv.MavMessage, origin: tuple[float, float] | None, t: int,
           where: Where) -> Output | Ignored:
    """A LOCAL_POSITION_NED as an InsState on /<v>/ins/local, placed on the EKF origin."""
    f = m.fields
    if origin is None:
        return Ignored(where, "LOCAL_POSITION_NED without an origin (no GPS_GLOBAL_ORIGIN in the log, no manifest "
                              "origin)")
    north, east, down = _f(f, "x"), _f(f, "y"), _f(f, "z")
    lat, lon = local_to_geodetic(north, east, origin)
    state = ins_state(t, ctx, "mavlink:LOCAL_POSITION_NED", latitude=lat, longitude=lon, depth_m=down,
                      velocity_north_mps=_f(f, "vx"), velocity_east_mps=_f(f, "vy"), velocity_down_mps=_f(f, "vz"))
    return output(ctx, LOCAL, state, t, where)


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


def _gps_boot_ns(messages: list[tuple[mv.MavMessage, Where]]) -> int | None:
    """UTC (ns) of a dataflash log's boot by its first record carrying GPS week and time (GPS's GWk/GMS)."""
    for m, _ in messages:
        f = m.fields
        if "GWk" in f and "GMS" in f and isinstance(f.get("TimeUS"), int) and int(f["GWk"] or 0) > 0:
            return gpstime.gps_to_unix_ns(int(f["GWk"]), float(f["GMS"]) / 1000.0) - int(f["TimeUS"]) * 1000
    return None


def _dataflash_boot_ns(messages: list[tuple[mv.MavMessage, Where]], ctx: LogContext) -> int | None:
    """UTC (ns, before the clock offset) of a dataflash log's boot; None for a tlog. FormatError when the log has
    no anchor, or two (its own GPS time and a manifest start): one line naming the key that settles it."""
    with ctx.files[0].open("rb") as fh:
        dataflash = mv.is_dataflash(fh.read(2))
    if not dataflash:
        if ctx.time_base in RELATIVE_BASES:
            raise FormatError(f"time_base = {ctx.time_base!r}: a tlog's times are the receiving computer's UTC "
                              "clock; give it no time_base or start (clock_offset_s corrects that clock)")
        return None
    gps = _gps_boot_ns(messages)
    if ctx.time_base in RELATIVE_BASES:
        if gps is not None:  # two anchors that may disagree: the log's own GPS time is not overridden silently
            raise FormatError(f"the dataflash log has its own GPS time (boot at {iso_utc(gps)}): give it no "
                              "time_base or start (clock_offset_s corrects its GPS time)")
        return 0  # TimeUS counts from boot, and the clock offset is the manifest's start
    if gps is None:
        raise FormatError("no UTC time: the dataflash log has no GPS week and time; give the UTC instant of its boot "
                          "in its [[vehicles.logs]] entry: time_base = \"boot\" and start = \"YYYY-MM-DDTHH:MM:SSZ\"")
    return gps


def _on_utc(m: mv.MavMessage, boot_ns: int) -> mv.MavMessage:
    """A dataflash record at boot + TimeUS (time -1: none)."""
    us = m.fields.get("TimeUS")
    return mv.MavMessage(m.type, boot_ns + us * 1000 if isinstance(us, int) else -1, m.index, m.fields, m.problem)


def _ekf_origin(messages: list[tuple[mv.MavMessage, Where]], ctx: LogContext) -> tuple[float, float] | None:
    """The datum of a dataflash EKF's local NED frame: its first ORGN record of the EKF origin (Type 0), else the
    manifest's `origin = [lat, lon]`; None without either (XKF1 states then have no latitude/longitude)."""
    for m, _ in messages:
        f = m.fields
        if m.type == "ORGN" and int(f.get("Type", 0) or 0) == 0:
            lat, lon = _f(f, "Lat"), _f(f, "Lng")
            if math.isfinite(lat) and math.isfinite(lon) and (lat, lon) != (0.0, 0.0):
                return lat, lon
    return origin_option(ctx)


def _baro_instance(messages: list[tuple[mv.MavMessage, Where]], ctx: LogContext) -> int:
    """The BARO instance that measures depth: the manifest's `baro_instance`, else the log's highest (ArduSub
    probes the external water-pressure sensor after the board's own barometers and makes it primary)."""
    chosen = ctx.options.get("baro_instance")
    if isinstance(chosen, int) and not isinstance(chosen, bool):
        return chosen
    return max((int(m.fields.get("I", 0) or 0) for m, _ in messages if m.type == "BARO"), default=0)


def _xkf_ins(ctx: LogContext, m: mv.MavMessage, origin: tuple[float, float] | None, t: int,
             where: Where) -> Output:
    """An INS state from an EKF3/EKF2 XKF1/NKF1 record: attitude, NED velocity, NED position (depth = PD)."""
    f = m.fields
    lat, lon = local_to_geodetic(_f(f, "PN"), _f(f, "PE"), origin)
    state = ins_state(t, ctx, "mavlink:" + m.type, latitude=lat, longitude=lon, depth_m=_f(f, "PD"),
                      roll_deg=_f(f, "Roll"), pitch_deg=_f(f, "Pitch"), heading_deg=_f(f, "Yaw") % 360.0,
                      velocity_north_mps=_f(f, "VN"), velocity_east_mps=_f(f, "VE"), velocity_down_mps=_f(f, "VD"))
    return output(ctx, "ins", state, t, where)


LOCAL = "ins/local"
VELOCITY_TYPES = ("VISION_SPEED_ESTIMATE", "VISION_POSITION_DELTA", "DISTANCE_SENSOR", "VISV", "VISO", "RFND")
XKF_TYPES = ("XKF1", "NKF1")  # EKF3, EKF2: one record per core (C) at the EKF's rate


def convert_mavlink(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    """ArduSub/ArduPilot .tlog and dataflash .BIN (pymavlink): GPS, EKF position + attitude, vision/DVL, range."""
    return checked_times(_convert_mavlink(data, ctx), ctx)


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
    boot_ns = _dataflash_boot_ns(messages, ctx)
    if boot_ns is not None:
        messages = [(_on_utc(m, boot_ns), w) for m, w in messages]
    types = {m.type for m, _ in messages}
    ekf_as_fix = not types & {"GPS_RAW_INT", "GPS_INPUT", "GPS"}
    # the INS state's source: POS (the EKF's latitude/longitude) where the log has it, else XKF1/NKF1
    xkf = "" if "POS" in types else next((x for x in XKF_TYPES if x in types), "")
    ekf_types = {"GLOBAL_POSITION_INT", "POS", xkf} - {""}
    has_ekf = bool(types & ekf_types)
    ekf_origin = _ekf_origin(messages, ctx) if xkf else None
    baro = _baro_instance(messages, ctx)
    attitude: mv.MavMessage | None = None
    depth = NAN  # the latest BARO depth, for attitude-only states
    origins = [o for o in (_global_origin(m) for m, _ in messages if m.type == "GPS_GLOBAL_ORIGIN") if o]
    origin = origins[0] if origins else origin_option(ctx)     # of LOCAL_POSITION_NED (a tlog's EKF)
    for m, where in messages:
        t = m.time_ns + ctx.clock_offset_ns
        if m.problem:
            yield Reject(where, m.problem)
        elif m.time_ns < 0 or (m.time_ns == 0 and boot_ns is None):  # a dataflash record's 0: TimeUS 0 at boot
            yield Reject(where, f"{m.type} without a time")
        elif m.type in FIX_TYPES:
            yield from _fix(ctx, m, t, where)
        elif m.type == xkf:
            core = int(m.fields.get("C", 0) or 0)
            if core:
                yield Ignored(where, f"{m.type} of EKF core {core} (core 0's is archived)")
            else:
                yield _xkf_ins(ctx, m, ekf_origin, t, where)
        elif m.type in ekf_types:
            yield _ins(ctx, m, attitude, t, where)
            if ekf_as_fix and m.type == "GLOBAL_POSITION_INT":
                yield from _fix(ctx, m, t, where)
        elif m.type in ("ATTITUDE", "ATT"):
            attitude = m
            if xkf:
                yield Ignored(where, f"{m.type}: the {xkf} INS state carries the attitude")
            elif has_ekf:
                yield Ignored(where, f"{m.type} merged into the next INS state")
            else:
                yield _ins(ctx, None, m, t, where, depth)
        elif m.type == "BARO":
            if has_ekf:
                yield Ignored(where, "BARO: the EKF's depth is archived")
            elif int(m.fields.get("I", 0) or 0) != baro:
                yield Ignored(where, f"BARO instance {m.fields.get('I')} (instance {baro} measures depth)")
            else:
                depth = -_f(m.fields, "Alt")
                yield Ignored(where, "BARO depth merged into the next INS state")
        elif m.type in VELOCITY_TYPES:
            yield _velocity(ctx, m, t, where)
        elif m.type == "LOCAL_POSITION_NED":
            yield _local(ctx, m, origin, t, where)
        elif m.type == "GPS_GLOBAL_ORIGIN":
            here = _global_origin(m)
            origin = here or origin
            yield Ignored(where, "GPS_GLOBAL_ORIGIN: the origin of LOCAL_POSITION_NED" if here else
                          "GPS_GLOBAL_ORIGIN at 0, 0 or out of range: not an origin")
        else:
            yield Ignored(where, f"MAVLink {m.type} is not mapped")


MANIFEST_EXAMPLE = """[[vehicles.logs]]
format = "mavlink"                 # ArduSub/ArduPilot telemetry .tlog or dataflash .BIN
path = "bluerov/2016-10-12 02-00-00.tlog"
# a dataflash log without GPS time: the UTC instant of its boot (docs/time-bases.md)
# time_base = "boot"
# start = "2016-10-12T01:58:00Z"
# baro_instance = 1                # the depth sensor's BARO instance (default: the log's highest)
"""

CONVERTERS: dict[str, Converter] = {"mavlink": convert_mavlink}
# the formats whose logs are (or may be) binary: read as bytes, never cut into lines (`recorders.registry`)
BINARY_FORMATS = frozenset({"mavlink"})  # tlog or dataflash
