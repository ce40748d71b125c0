"""MOOS-IvP alogs (`format = "alog"`) into the archive's sensor topics.

Variables, by name (the manifest's ``variables = { "MY_DEPTH" = "NAV_DEPTH", "NMEA_RAW" = "gps:nmea" }``
renames a variable to one of these, sends it to a raw-text stream of a sensor family, or "ignore"s it):

- ``NAV_LAT``, ``NAV_LONG``, ``NAV_X``, ``NAV_Y``, ``NAV_DEPTH``, ``NAV_HEADING``, ``NAV_SPEED``, ``NAV_PITCH``,
  ``NAV_ROLL``, ``NAV_Z`` -> ``/<v>/ins``, one InsState per epoch (consecutive postings at one time, no variable
  twice). Position: NAV_LAT/LONG, else NAV_X/Y (east/north of the manifest's ``origin = [lat, lon]``); depth:
  NAV_DEPTH, else -NAV_Z; velocity north/east from NAV_SPEED along NAV_HEADING (MOOS has no sideslip).
- ``GPS_LAT``, ``GPS_LON``/``GPS_LONG``, ``GPS_X``, ``GPS_Y``, ``GPS_SPEED``, ``GPS_HEADING``, ``GPS_QUALITY``,
  ``GPS_SAT``, ``GPS_HDOP`` -> ``/<v>/gps``, ``/<v>/gps/status`` and (with GPS_SPEED; GPS_HEADING is the
  course) ``/<v>/gps/velocity``, grouped the same way.
- range reports (any variable with ``RANGE_REPORT`` in its name, e.g. uFldContactRangeSensor's
  ``CRS_RANGE_REPORT = "vname=alpha,range=87.2,target=bravo,time=..."``) -> ``/<v>/modem/range``, kind
  "range_report": ``target`` is the vehicle heard, ``vname`` the one that measured (default: the log's).
- string values that are vendor sentences (``$GPGGA...``, ``$CACMR...``, ``$PIXSE...``) -> through our NMEA,
  Micro-Modem, PHINS, EvoLogics converters (`recorders.containers`), one text stream per variable.

Times: the alog's ``%% LOGSTART`` plus each posting's seconds, and the log's clock offset. Every posting is
counted: archived, rejected with a reason, or ignored with a reason (unmapped variables are listed once each,
with their count).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from formats import alog
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
NAV_VARS = {"NAV_LAT", "NAV_LONG", "NAV_X", "NAV_Y", "NAV_DEPTH", "NAV_HEADING", "NAV_SPEED", "NAV_PITCH",
            "NAV_ROLL", "NAV_Z"}
GPS_VARS = {"GPS_LAT", "GPS_LON", "GPS_LONG", "GPS_X", "GPS_Y", "GPS_SPEED", "GPS_HEADING", "GPS_QUALITY",
            "GPS_SAT", "GPS_HDOP"}


class _Epoch:
    """Consecutive numeric postings of one group (NAV_* or GPS_*) at one time."""

    def __init__(self) -> None:
        self.values: dict[str, float] = {}
        self.wheres: list[Where] = []
        self.time_ns = 0

    def accepts(self, name: str, t_ns: int) -> bool:
        return not self.values or (name not in self.values and t_ns == self.time_ns)

    def add(self, name: str, value: float, t_ns: int, where: Where) -> None:
        if not self.values:
            self.time_ns = t_ns
        self.values[name] = value
        self.wheres.append(where)


def _nav_output(ep: _Epoch, ctx: LogContext, origin: tuple[float, float] | None) -> Output | None:
    v = ep.values.get
    lat, lon = v("NAV_LAT", NAN), v("NAV_LONG", NAN)
    if not (math.isfinite(lat) and math.isfinite(lon)):
        lat, lon = local_to_geodetic(v("NAV_Y", NAN), v("NAV_X", NAN), origin)
    depth = v("NAV_DEPTH", -v("NAV_Z", NAN))
    heading, speed = v("NAV_HEADING", NAN), v("NAV_SPEED", NAN)
    vn = speed * math.cos(math.radians(heading))
    ve = speed * math.sin(math.radians(heading))
    if not any(map(math.isfinite, (lat, depth, heading, vn))):
        return None
    state = ins_state(ep.time_ns, ctx, "alog:" + ",".join(ep.values), latitude=lat, longitude=lon, depth_m=depth,
                      heading_deg=heading % 360.0 if math.isfinite(heading) else NAN,
                      pitch_deg=v("NAV_PITCH", NAN), roll_deg=v("NAV_ROLL", NAN),
                      velocity_north_mps=vn, velocity_east_mps=ve)
    return output(ctx, "ins", state, ep.time_ns, ep.wheres[0])


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


def _range_report(p: alog.Posting, ctx: LogContext) -> Output | Reject:
    fields = _pairs(p.text)
    try:
        range_m = float(fields.get("range", "nan"))
    except ValueError:
        range_m = NAN
    heard = fields.get("target") or fields.get("contact") or ""
    if not math.isfinite(range_m) or range_m < 0 or not heard:
        return Reject(p.where, f"{p.variable}: a range report needs range= and target= ({p.text[:60]!r})")
    t = p.time_ns + ctx.clock_offset_ns
    if "time" in fields:
        try:
            own = float(fields["time"])
        except ValueError:
            own = NAN
        if math.isfinite(own) and abs(own) < 1e11:    # the report's own Unix time; anything else is not one
            t = round(own * 1e9) + ctx.clock_offset_ns
    measured_by = fields.get("vname") or ctx.vehicle
    book = {name: address for address, name in ctx.address_book.items()}
    msg = S.AcousticRange(
        timestamp=S.timestamp(t), source=heard, destination=measured_by,
        source_address=book.get(heard, -1), destination_address=book.get(measured_by, -1),
        travel_time_s=range_m / ctx.sound_speed_mps, range_m=range_m, sound_speed_mps=ctx.sound_speed_mps,
        kind="range_report", source_format="alog:" + p.variable)
    return Output(f"/{measured_by}/modem/range", msg, t, t, p.where)


def convert_alog(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    """MOOS-IvP .alog: NAV_* -> INS state, GPS_* -> fixes, range reports, raw sentences via our decoders."""
    return checked_times(_convert_alog(data, ctx), ctx)


def _convert_alog(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    mapping = ctx.options.get("variables")
    mapping = mapping if isinstance(mapping, dict) else {}
    origin = origin_option(ctx)
    epochs = {"NAV": _Epoch(), "GPS": _Epoch()}
    streams: dict[str, TextStream] = {}

    def close(group: str) -> Iterator[Output | Ignored]:
        ep = epochs[group]
        if not ep.values:
            return
        outs = [_nav_output(ep, ctx, origin)] if group == "NAV" else list(_gps_outputs(ep, ctx, origin))
        outs = [o for o in outs if o is not None]
        yield from outs
        for where in ep.wheres[1:] if outs else ep.wheres:
            yield Ignored(where, f"{group}_* posting merged into its epoch's message" if outs else
                          f"{group}_* epoch without position, depth, heading or speed")
        epochs[group] = _Epoch()

    for p in alog.decode(data):
        if isinstance(p, Reject):
            yield p
            continue
        name = str(mapping.get(p.variable, p.variable))
        t = p.time_ns + ctx.clock_offset_ns
        if name == "ignore":
            yield Ignored(p.where, f"variable {p.variable} ignored by the manifest")
            continue
        group = name[:3]
        if name in NAV_VARS or name in GPS_VARS:
            if not math.isfinite(p.number):
                yield Reject(p.where, f"{p.variable} = {p.text[:40]!r} is not a number")
                continue
            if not epochs[group].accepts(name, t):
                yield from close(group)
            epochs[group].add(name, p.number, t, p.where)
            continue
        if "RANGE_REPORT" in name:
            yield _range_report(p, ctx)
            continue
        wanted = name if name.partition(":")[0] in SENSORS else ""
        if wanted or sentence_format(p.text)[0]:
            stream = streams.get(p.variable)
            if stream is None:
                stream = streams[p.variable] = TextStream(ctx.vehicle, wanted)
            stream.add(p.text, Where(p.where.offset, p.where.line, p.time_ns), p.time_ns, t)
            continue
        yield Ignored(p.where, f"variable {p.variable} is not mapped")
    for group in epochs:
        yield from close(group)
    for variable, stream in streams.items():
        yield from convert_stream(stream, ctx, variable)


MANIFEST_EXAMPLE = """[[vehicles.logs]]
format = "alog"                    # MOOS-IvP pLogger .alog
path = "auv1/LOG_AUV1_12_10_2016/LOG_AUV1_12_10_2016.alog"
origin = [45.70, 126.60]           # MOOS LatOrigin/LongOrigin, for NAV_X/NAV_Y
variables = { "DEPTH_SENSOR" = "NAV_DEPTH", "NMEA_FROM_GPS" = "gps:nmea", "ACOMMS_RAW" = "modem" }
"""

CONVERTERS: dict[str, Converter] = {"alog": convert_alog}
# read block by block, in bounded memory (`recorders.base.blockwise`)
BLOCK_CONVERTERS: dict[str, BlockConverter] = {"alog": blockwise(convert_alog)}
