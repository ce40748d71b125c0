"""MOOS-IvP alogs (`format = "alog"`) into the archive's sensor topics.

Variables, by name (the manifest's ``variables = { "MY_DEPTH" = "NAV_DEPTH", "NMEA_RAW" = "gps:nmea" }``
renames a variable to one of these, sends it to a raw-text stream of a sensor family, or "ignore"s it):

- ``NAV_LAT``, ``NAV_LONG``, ``NAV_X``, ``NAV_Y``, ``NAV_DEPTH``, ``NAV_HEADING``, ``NAV_YAW``, ``NAV_SPEED``,
  ``NAV_PITCH``, ``NAV_ROLL``, ``NAV_Z`` -> ``/<v>/ins``, the vehicle's navigation solution (pNav, uSimMarine, an
  INS driver's NAV_*), one InsState per epoch (consecutive postings at one time, no variable twice). Position:
  NAV_LAT/LONG, else NAV_X/Y (east/north of the manifest's ``origin = [lat, lon]``); depth: NAV_DEPTH, else
  -NAV_Z; heading: NAV_HEADING (degrees), else NAV_YAW (radians, MOOS's convention "yaw = -heading·π/180",
  zero north, positive anticlockwise: heading = -degrees(yaw) mod 360); velocity north/east from NAV_SPEED
  along the heading (MOOS has no sideslip).
- ``INS_NAV``, ``INS_EULER``, ``INS_EEULER``: an INS driver's own key=value postings (iInsSBG for an SBG
  Ellipse: ``INS_NAV = "TIME=…,LAT=…,LON=…,ALT=…"`` in degrees and metres; ``INS_EULER = "ROLL=…,PITCH=…,YAW=…"``
  and ``INS_EEULER = "EROLL=…,EPITCH=…,EYAW=…"``, the EKF's NED Euler angles and their sigmas in radians) ->
  ``/<v>/ins/sbg``, one InsState per epoch, grouped as NAV_* is. A separate topic from ``/<v>/ins``: the
  device's solution is a second position source beside the vehicle's NAV_* (which may itself come from it).
- ``NODE_REPORT``, ``NODE_REPORT_LOCAL`` (pNodeReporter: ``NAME=alpha,X=…,Y=…,LAT=…,LON=…,SPD=…,HDG=…,DEP=…,
  TIME=…``) -> ``/<NAME>/node_report``, an InsState per report: LAT/LON, else X/Y about the manifest's
  ``origin``; HDG degrees; velocity from SPD along HDG; at the report's own TIME (Unix seconds) when it has
  one. NODE_REPORT_LOCAL is the log's own vehicle's report: it goes to ``/<v>/node_report`` whatever its
  NAME (a MOOS community name need not be the manifest's); NODE_REPORT names another vehicle.
- ``GPS_LAT``, ``GPS_LON``/``GPS_LONG``, ``GPS_X``, ``GPS_Y``, ``GPS_SPEED``, ``GPS_HEADING``, ``GPS_QUALITY``,
  ``GPS_SAT``, ``GPS_HDOP`` -> ``/<v>/gps``, ``/<v>/gps/status`` and (with GPS_SPEED; GPS_HEADING is the
  course) ``/<v>/gps/velocity``, grouped the same way.
- range reports (any variable with ``RANGE_REPORT`` in its name, e.g. uFldContactRangeSensor's
  ``CRS_RANGE_REPORT = "vname=alpha,range=87.2,target=bravo,time=..."``) -> ``/<v>/modem/range``, kind
  "range_report": ``target`` is the vehicle heard, ``vname`` the one that measured (default: the log's).
- string values that are vendor sentences (``$GPGGA...``, ``$CACMR...``, ``$PIXSE...``) -> through our NMEA,
  Micro-Modem, PHINS, EvoLogics converters (`recorders.containers`), one text stream per variable.

Every posting is archived as itself too, on ``/<v>/moos/<VARIABLE>`` (one topic per variable, as alogview
lists them): JSON of the shared schema ``moos.Posting``: ``value`` (a number, or the text; a multi-line value's
lines joined with "\n"), ``source`` (the posting app), ``aux`` (the source's ``:aux`` part, "" without),
``community`` (the MOOS community: an alog names none per posting, so the manifest's ``community``, else the
vehicle's name, MOOS-IvP's convention). A variable the manifest maps to "ignore" is left out.

Times: the alog's ``%% LOGSTART`` plus each posting's seconds, and the log's clock offset. Every posting is
counted: archived, or rejected with a reason; where a posting of a mapped variable gives none of ours, an
ignored reason says why (a NAV_X/NAV_Y epoch without the manifest's ``origin``, a value that is no number).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import replace

from formats import alog
from formats import json_messages as J
from formats import schemas as S
from formats.log_blocks import LogText
from formats.records import Reject, Where

from .base import BlockConverter, Converter, Ignored, LogContext, Output, blockwise, output
from .containers import (
    TextStream,
    checked_times,
    convert_stream,
    local_to_geodetic,
    origin_option,
    sentence_format,
)
from .gnss_velocity import SUFFIX as VELOCITY
from .gnss_velocity import gnss_velocity
from .gps import gnss_status
from .ins import ins_state
from .manifest import SENSORS

NAN = math.nan
NAV_VARS = {"NAV_LAT", "NAV_LONG", "NAV_X", "NAV_Y", "NAV_DEPTH", "NAV_HEADING", "NAV_YAW", "NAV_SPEED",
            "NAV_PITCH", "NAV_ROLL", "NAV_Z"}
GPS_VARS = {"GPS_LAT", "GPS_LON", "GPS_LONG", "GPS_X", "GPS_Y", "GPS_SPEED", "GPS_HEADING", "GPS_QUALITY",
            "GPS_SAT", "GPS_HDOP"}
# an INS driver's key=value postings: variable -> {key: our field}; angles of INS_EULER/INS_EEULER in radians
INS_VARS = {
    "INS_NAV": {"LAT": "lat", "LATITUDE": "lat", "LON": "lon", "LONG": "lon", "LONGITUDE": "lon",
                "ALT": "alt", "ALTITUDE": "alt", "DEPTH": "depth", "VN": "vn", "VE": "ve", "VD": "vd"},
    "INS_EULER": {"ROLL": "roll", "PITCH": "pitch", "YAW": "yaw"},
    "INS_EEULER": {"EROLL": "roll_std", "EPITCH": "pitch_std", "EYAW": "yaw_std"},
}
INS_SUFFIX = "ins/sbg"
EMPTY = {"NAV": "position, depth, heading or speed", "GPS": "position, depth, heading or speed",
         "INS": "position or attitude"}
NODE_REPORTS = ("NODE_REPORT", "NODE_REPORT_LOCAL")
# a vehicle name that is one topic level: what a NODE_REPORT's NAME must be to name a topic; not one of the
# archive's own namespaces (a run's /replay/..., /diagnostics/...)
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
RESERVED = ("replay", "diagnostics")
TOPIC = "moos"  # /<v>/moos/<VARIABLE>: every posting as itself
POSTING = "moos.Posting"
POSTING_SCHEMA = J.schema_text({
    "$schema": "https://json-schema.org/draft/2020-12/schema", "title": POSTING, "type": "object",
    "properties": {
        "value": {"type": ["number", "string"], "description": "the posting's number, else its text"},
        "source": {"type": "string", "description": "the MOOS app that posted it"},
        "aux": {"type": "string", "description": "the source's auxiliary part (after ':'), '' without"},
        "community": {"type": "string", "description": "the MOOS community (the manifest's, else the vehicle)"},
    },
    "required": ["value", "source", "aux", "community"],
})


def _posting(p: alog.Posting, t: int, community: str, ctx: LogContext) -> Output:
    """A posting as itself: JSON on /<v>/moos/<VARIABLE>."""
    source, _, aux = p.source.partition(":")
    value: float | str = p.number if math.isfinite(p.number) else p.text
    message = J.JsonMessage(POSTING, POSTING_SCHEMA, J.encode(
        {"value": value, "source": source, "aux": aux, "community": community}))
    return output(ctx, f"{TOPIC}/{J.topic_level(p.variable)}", message, t, p.where)


def _origin_note(group: str, ep: _Epoch, origin: tuple[float, float] | None) -> str:
    """For an epoch of NAV_X/NAV_Y (or GPS_X/GPS_Y) without an origin, why it has no position: the key to give."""
    if origin is None and {f"{group}_X", f"{group}_Y"} & set(ep.names):
        return (f"{group}_X/{group}_Y without an origin, so no position: give the log's origin = [lat, lon] "
                "(MOOS LatOrigin, LongOrigin) in its [[vehicles.logs]] entry")
    return ""


class _Epoch:
    """Consecutive postings of one group (NAV_*, GPS_* or INS_*) at one time, each variable once.

    `values` holds a numeric posting under its variable, a key=value posting's fields under our field names.
    """

    def __init__(self) -> None:
        self.names: list[str] = []
        self.values: dict[str, float] = {}
        self.wheres: list[Where] = []
        self.time_ns = 0

    def accepts(self, name: str, t_ns: int) -> bool:
        return not self.names or (name not in self.names and t_ns == self.time_ns)

    def add(self, name: str, values: dict[str, float], t_ns: int, where: Where) -> None:
        if not self.names:
            self.time_ns = t_ns
        self.names.append(name)
        self.values.update(values)
        self.wheres.append(where)


def _nav_output(ep: _Epoch, ctx: LogContext, origin: tuple[float, float] | None) -> Output | None:
    v = ep.values.get
    lat, lon = v("NAV_LAT", NAN), v("NAV_LONG", NAN)
    if not (math.isfinite(lat) and math.isfinite(lon)):
        lat, lon = local_to_geodetic(v("NAV_Y", NAN), v("NAV_X", NAN), origin)
    depth = v("NAV_DEPTH", -v("NAV_Z", NAN))
    heading, speed = v("NAV_HEADING", NAN), v("NAV_SPEED", NAN)
    if not math.isfinite(heading):
        heading = moos_yaw_heading(v("NAV_YAW", NAN))
    vn = speed * math.cos(math.radians(heading))
    ve = speed * math.sin(math.radians(heading))
    if not any(map(math.isfinite, (lat, depth, heading, vn))):
        return None
    state = ins_state(ep.time_ns, ctx, "alog:" + ",".join(ep.names), latitude=lat, longitude=lon, depth_m=depth,
                      heading_deg=heading % 360.0 if math.isfinite(heading) else NAN,
                      pitch_deg=v("NAV_PITCH", NAN), roll_deg=v("NAV_ROLL", NAN),
                      velocity_north_mps=vn, velocity_east_mps=ve)
    return output(ctx, "ins", state, ep.time_ns, ep.wheres[0])


def moos_yaw_heading(yaw_rad: float) -> float:
    """Heading (degrees true, clockwise from north, in [0, 360)) of a MOOS yaw: radians, zero north, positive
    anticlockwise ("yaw = -heading·π/180", MOOS Conventions); NaN for NaN."""
    return (-math.degrees(yaw_rad)) % 360.0 if math.isfinite(yaw_rad) else NAN


def _ins_output(ep: _Epoch, ctx: LogContext) -> Output | None:
    """The INS driver's own solution (INS_NAV + INS_EULER + INS_EEULER) as an InsState on /<v>/ins/sbg."""
    v = ep.values.get
    lat, lon = v("lat", NAN), v("lon", NAN)
    roll, pitch, yaw = (math.degrees(v(k, NAN)) for k in ("roll", "pitch", "yaw"))
    if not any(map(math.isfinite, (lat, lon, roll, pitch, yaw))):
        return None
    state = ins_state(ep.time_ns, ctx, "alog:" + ",".join(ep.names), latitude=lat,
                      longitude=_wrap_lon(lon),
                      altitude_m=v("alt", NAN), depth_m=v("depth", NAN),
                      roll_deg=roll, pitch_deg=pitch, heading_deg=yaw % 360.0 if math.isfinite(yaw) else NAN,
                      roll_std_deg=math.degrees(v("roll_std", NAN)), pitch_std_deg=math.degrees(v("pitch_std", NAN)),
                      heading_std_deg=math.degrees(v("yaw_std", NAN)), velocity_north_mps=v("vn", NAN),
                      velocity_east_mps=v("ve", NAN), velocity_down_mps=v("vd", NAN))
    return output(ctx, INS_SUFFIX, state, ep.time_ns, ep.wheres[0])


def _ins_fields(p: alog.Posting, keys: dict[str, str]) -> dict[str, float] | Reject:
    """Our fields of an INS_* key=value posting (a value that is no number is NaN), or why it is none."""
    fields = _pairs(p.text)
    if not fields:
        return Reject(p.where, f"{p.variable}: not key=value text ({p.text[:60]!r})")
    out = {}
    for key, value in fields.items():
        name = keys.get(key.upper())
        if name is not None:
            out[name] = _number(value)
    if not out:
        return Reject(p.where, f"{p.variable}: none of {', '.join(sorted(keys))} in {p.text[:60]!r}")
    return out


def _wrap_lon(lon: float) -> float:
    """Longitude in [-180, 180), as it came when it already is (the wrap's arithmetic moves the last digit)."""
    return lon if -180.0 <= lon < 180.0 else (lon + 180.0) % 360.0 - 180.0


def _number(text: str) -> float:
    try:
        f = float(text)
    except ValueError:
        return NAN
    return f if math.isfinite(f) else NAN


def _gps_outputs(ep: _Epoch, ctx: LogContext, origin: tuple[float, float] | None) -> Iterator[Output]:
    v = ep.values.get
    lat, lon = v("GPS_LAT", NAN), v("GPS_LON", v("GPS_LONG", NAN))
    if not (math.isfinite(lat) and math.isfinite(lon)):
        lat, lon = local_to_geodetic(v("GPS_Y", NAN), v("GPS_X", NAN), origin)
    quality = v("GPS_QUALITY", NAN)
    quality_i = int(quality) if math.isfinite(quality) else -1
    t, where = ep.time_ns, ep.wheres[0]
    if math.isfinite(lat) and math.isfinite(lon) and quality_i != 0:
        yield output(ctx, "gps", S.location_fix(t, ctx.vehicle, lat, lon), t, where)
    sats = v("GPS_SAT", NAN)
    source = "alog:" + ",".join(ep.values)
    speed, course = v("GPS_SPEED", NAN), v("GPS_HEADING", NAN)
    yield output(ctx, "gps/status", gnss_status(
        t, ctx.vehicle, quality_i, int(sats) if math.isfinite(sats) else -1, v("GPS_HDOP", NAN), source,
        speed, course, NAN), t, where)
    if math.isfinite(speed) and quality_i != 0:
        yield output(ctx, VELOCITY, gnss_velocity(ctx, t, source, speed=speed, course=course), t, where)


def _pairs(text: str) -> dict[str, str]:
    out = {}
    for piece in text.split(","):
        key, eq, value = piece.partition("=")
        if eq:
            out[key.strip().lower()] = value.strip()
    return out


def _report_time_ns(p: alog.Posting, fields: dict[str, str], ctx: LogContext) -> int:
    """A report's own Unix time (its time= or utc_time= field) when it has a usable one, else the posting's;
    with the log's clock offset."""
    own = _number(fields.get("time", fields.get("utc_time", "nan")))  # utc_time: older pNodeReporter
    if math.isfinite(own) and abs(own) < 1e11:    # anything else is not a Unix time
        return round(own * 1e9) + ctx.clock_offset_ns
    return p.time_ns + ctx.clock_offset_ns


def _node_report(p: alog.Posting, ctx: LogContext, origin: tuple[float, float] | None) -> Output | Reject:
    """A pNodeReporter report as an InsState on /<vehicle>/node_report (see the module docstring)."""
    fields = _pairs(p.text)
    name = ctx.vehicle if p.variable == "NODE_REPORT_LOCAL" else fields.get("name", "")
    if not _NAME.match(name) or name in RESERVED:
        return Reject(p.where, f"{p.variable}: NAME={name[:40]!r} is not a vehicle name ({p.text[:60]!r})")
    f = {k: _number(v) for k, v in fields.items() if k in ("lat", "lon", "x", "y", "spd", "hdg", "dep", "depth")}
    g = f.get
    lat, lon = g("lat", NAN), g("lon", NAN)
    if not (math.isfinite(lat) and math.isfinite(lon)):
        lat, lon = local_to_geodetic(g("y", NAN), g("x", NAN), origin)
    if not (math.isfinite(lat) and math.isfinite(lon)):
        why = "X=/Y= without a manifest origin" if "x" in f else "no LAT=/LON= or X=/Y="
        return Reject(p.where, f"{p.variable}: no position: {why} ({p.text[:60]!r})")
    heading, speed = g("hdg", NAN), g("spd", NAN)
    heading = heading % 360.0 if math.isfinite(heading) else NAN
    t = _report_time_ns(p, fields, ctx)
    vctx = ctx if name == ctx.vehicle else replace(ctx, vehicle=name)
    state = ins_state(t, vctx, "alog:" + p.variable, latitude=lat, longitude=_wrap_lon(lon),
                      depth_m=g("dep", g("depth", NAN)), heading_deg=heading,
                      velocity_north_mps=speed * math.cos(math.radians(heading)),
                      velocity_east_mps=speed * math.sin(math.radians(heading)))
    return Output(f"/{name}/node_report", state, t, p.time_ns + ctx.clock_offset_ns, p.where)


def _range_report(p: alog.Posting, ctx: LogContext) -> Output | Reject:
    fields = _pairs(p.text)
    try:
        range_m = float(fields.get("range", "nan"))
    except ValueError:
        range_m = NAN
    heard = fields.get("target") or fields.get("contact") or ""
    if not math.isfinite(range_m) or range_m < 0 or not heard:
        return Reject(p.where, f"{p.variable}: a range report needs range= and target= ({p.text[:60]!r})")
    t = _report_time_ns(p, fields, ctx)
    measured_by = fields.get("vname") or ctx.vehicle
    book = {name: address for address, name in ctx.address_book.items()}
    msg = S.AcousticRange(
        timestamp=S.timestamp(t), source=heard, destination=measured_by,
        source_address=book.get(heard, -1), destination_address=book.get(measured_by, -1),
        travel_time_s=range_m / ctx.sound_speed_mps, range_m=range_m, sound_speed_mps=ctx.sound_speed_mps,
        kind="range_report", source_format="alog:" + p.variable)
    return Output(f"/{measured_by}/modem/range", msg, t, t, p.where)


def convert_alog(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    """MOOS-IvP .alog: NAV_* and INS_* -> INS states, GPS_* -> fixes, node and range reports, raw sentences via
    our decoders."""
    return checked_times(_convert_alog(data, ctx), ctx)


def _convert_alog(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    mapping = ctx.options.get("variables")
    mapping = mapping if isinstance(mapping, dict) else {}
    origin = origin_option(ctx)
    community = str(ctx.options.get("community") or ctx.vehicle)
    epochs = {"NAV": _Epoch(), "GPS": _Epoch(), "INS": _Epoch()}
    streams: dict[str, TextStream] = {}

    def close(group: str) -> Iterator[Output | Ignored]:
        ep = epochs[group]
        if not ep.names:
            return
        outs = ([_nav_output(ep, ctx, origin)] if group == "NAV" else [_ins_output(ep, ctx)] if group == "INS"
                else list(_gps_outputs(ep, ctx, origin)))
        outs = [o for o in outs if o is not None]
        yield from outs
        note = _origin_note(group, ep, origin)
        if note or not outs:  # its postings are archived as themselves: one reason for the epoch
            yield Ignored(ep.wheres[0], note or f"{group}_* epoch without {EMPTY[group]}")
        epochs[group] = _Epoch()

    def mapped(p: alog.Posting, name: str, t: int) -> Iterator[Output | Reject | Ignored]:
        """Our messages of one posting: an epoch closed by it, a report, a line for a vendor stream."""
        group = name[:3]
        if name in NAV_VARS or name in GPS_VARS:
            if not math.isfinite(p.number):
                yield Reject(p.where, f"{p.variable} = {p.text[:40]!r} is not a number")
                return
            if not epochs[group].accepts(name, t):
                yield from close(group)
            epochs[group].add(name, {name: p.number}, t, p.where)
            return
        if name in INS_VARS:
            fields = _ins_fields(p, INS_VARS[name])
            if isinstance(fields, Reject):
                yield fields
                return
            if not epochs["INS"].accepts(name, t):
                yield from close("INS")
            epochs["INS"].add(name, fields, t, p.where)
            return
        if name in NODE_REPORTS:
            yield _node_report(replace(p, variable=name), ctx, origin)
            return
        if "RANGE_REPORT" in name:
            yield _range_report(p, ctx)
            return
        wanted = name if name.partition(":")[0] in SENSORS else ""
        if wanted or sentence_format(p.text)[0]:
            stream = streams.get(p.variable)
            if stream is None:
                stream = streams[p.variable] = TextStream(ctx.vehicle, wanted)
            stream.add(p.text, Where(p.where.offset, p.where.line, p.time_ns), p.time_ns, t)

    for p in alog.decode(data):
        if isinstance(p, Reject):
            yield p
            continue
        name = str(mapping.get(p.variable, p.variable))
        t = p.time_ns + ctx.clock_offset_ns
        if name == "ignore":
            yield Ignored(p.where, f"variable {p.variable} ignored by the manifest")
            continue
        yield _posting(p, t, community, ctx)
        for item in mapped(p, name, t):
            # the posting is archived: where ours cannot be made of it, that is a reason, not a record refused
            yield Ignored(item.where, item.reason) if type(item) is Reject else item

    for group in epochs:
        yield from close(group)
    for variable, stream in streams.items():
        yield from convert_stream(stream, ctx, variable)


MANIFEST_EXAMPLE = """[[vehicles.logs]]
format = "alog"                    # MOOS-IvP pLogger .alog
path = "auv1/LOG_AUV1_12_10_2016/LOG_AUV1_12_10_2016.alog"
origin = [45.70, 126.60]           # MOOS LatOrigin/LongOrigin, for NAV_X/NAV_Y
variables = { "DEPTH_SENSOR" = "NAV_DEPTH", "NMEA_FROM_GPS" = "gps:nmea", "ACOMMS_RAW" = "modem" }
# community = "auv1"               # the MOOS community named on /<v>/moos/* postings (default: the vehicle)
"""

CONVERTERS: dict[str, Converter] = {"alog": convert_alog}
# read block by block, in bounded memory (`recorders.base.blockwise`)
BLOCK_CONVERTERS: dict[str, BlockConverter] = {"alog": blockwise(convert_alog)}
