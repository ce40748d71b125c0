"""What the container recorders (ROS bags, MOOS alogs, MAVLink logs) share.

A container holds several sensors in one file, so each message goes to the
topic of its sensor family (`/<vehicle>/gps`, `/ins`, `/dvl`...). Raw vendor
text carried inside a container (NMEA sentences in a ROS string topic or a
MOOS variable, PHINS, Micro-Modem or EvoLogics lines) goes through the very
converter a vendor log of that format would (`registry.family_converter`):
the sentences of one stream are written as a text log whose host-timestamp
prefix is each message's own time, converted, and every output and reject
mapped back to the container message it came from. A message that gave
neither is counted as `Ignored` (merged into its epoch's message, as a GST
into its GGA's fix, or carrying nothing that is archived).

Frames. ROS (REP-103/105) uses ENU world frames and FLU body frames unless a
frame name ends in `_ned` / `_frd`; our messages are NED and FRD.
Orientation quaternions are converted to heading (true, clockwise), roll
(starboard down positive) and pitch (bow up positive).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from typing import TypeVar, cast

from formats import geodesy
from formats.records import FormatError, Reject, Where
from formats.units import NS

from .base import CONTAINER_TIME, Batch, Ignored, LogContext, Output, SourceBatch, one_by_one
from .clock import offset_problem, shift_text
from .registry import family_converter

NAN = math.nan

# first-match rules: a text stream's vendor format from what its lines start with or contain
_EVOLOGICS_WORDS = ("USBLLONG", "USBLANGLES", "RECVIM", "RECVIMS", "RECVPBM", "SENDEND", "RECVEND", "DELIVERED",
                    "FAILEDIM", "AT?T")

_WATERLINKED_SERIAL = ("wrz,", "wru,", "wrx,", "wrt,", "wrp,")


def sentence_format(text: str) -> tuple[str, str]:
    """(sensor family, format) of one raw vendor line; ("", "") when it is none we decode."""
    s = text.lstrip()
    if s.startswith(("$PIXSE", "$PHTRO", "$PHLIN", "$PHSPD", "$PHINF")):
        return "ins", "phins"
    if s.startswith("$PASHR"):
        return "ins", "pashr"
    if s.startswith(("$CA", "$CC")):
        return "modem", "micromodem"
    if any(w in s for w in _EVOLOGICS_WORDS):
        return ("usbl" if "USBL" in s else "modem"), "evologics"
    if s.startswith(("#INS", "%INS")) and ";" in s:
        return "ins", "novatel"  # SPAN INSPVA(S/X)
    if s.startswith(("#", "%")) and ";" in s:
        return "gps", "novatel"
    if s.startswith(_WATERLINKED_SERIAL) or (s.startswith("{") and '"type"' in s
                                              and ('"velocity"' in s or '"position_local"' in s)):
        return "dvl", "waterlinked"   # a DVL's serial report, or its TCP JSON (the A50 ROS driver's json_data)
    if s.startswith(("$HEHDT", "$HETHS", "$IN")):
        return "ins", "nmea"
    if s.startswith(("$", "!")):
        return "gps", "nmea"
    return "", ""


def stream_format(lines: Sequence[str], wanted: str = "") -> tuple[str, str]:
    """(family, format) of a whole text stream: the manifest's "family[:format]", else its lines' formats.

    PHINS bursts carry plain $HEHDT too, so any PHINS line makes the stream PHINS;
    otherwise the most common format of its lines wins.
    """
    family, _, fmt = wanted.partition(":")
    if family and fmt:
        return family, fmt
    found = [sentence_format(t) for t in lines]
    found = [f for f in found if f[0] and (not family or f[0] == family)]
    if not found:
        return (family, "nmea") if family in ("gps", "ins") else ("", "")
    if ("ins", "phins") in found:
        return "ins", "phins"
    return max(set(found), key=found.count)


@dataclass
class TextStream:
    """Raw vendor lines of one container stream, with where each came from, to convert in one pass."""

    vehicle: str
    wanted: str = ""                    # the manifest's "family[:format]" for it, or "" to guess
    lines: list[str] = field(default_factory=list)
    wheres: list[Where] = field(default_factory=list)   # the container message of each line
    times: list[int] = field(default_factory=list)      # measurement time of each (ns, before clock offset)
    publish: list[int] = field(default_factory=list)    # publish time of each (ns, offset applied)

    def add(self, text: str, where: Where, t_ns: int, publish_ns: int) -> None:
        """One raw line (several when the message holds a burst), timed `t_ns`."""
        for line in text.replace("\r", "\n").split("\n"):
            if line.strip():
                self.lines.append(line.strip())
                self.wheres.append(where)
                self.times.append(t_ns)
                self.publish.append(publish_ns)


def convert_stream(stream: TextStream, ctx: LogContext, label: str) -> Iterator[Output | Reject | Ignored]:
    """A stream's lines through the vendor converter of their format, mapped back to their container messages."""
    family, fmt = stream_format(stream.lines, stream.wanted)
    if not stream.lines:
        return
    if not family:
        for where in dict.fromkeys(stream.wheres):
            yield Ignored(where, f"{label}: text that is no vendor format we decode")
        return
    try:
        convert = family_converter(family, fmt)
    except KeyError:
        for where in dict.fromkeys(stream.wheres):
            yield Reject(where, f"{label}: {family} format {fmt!r} is not one we decode")
        return
    # "sec.nanosec line": the unix host-timestamp prefix every text decoder reads, exact to the nanosecond
    blob = "".join(f"{t // NS}.{t % NS:09d} {line}\n" for t, line in zip(stream.times, stream.lines))
    # time-of-day sentences need a date: the manifest's, else the day of the stream's first message
    day = ctx.trial_date or datetime.fromtimestamp(stream.times[0] // NS, UTC).date()
    sub = replace(ctx, vehicle=stream.vehicle, prefix="unix", path=f"{ctx.path} {label}", trial_date=day,
                  options={**ctx.options, **_stream_options(ctx, family), CONTAINER_TIME: True})
    used: set[Where] = set()
    for item in one_by_one(convert(blob.encode("utf-8", "replace"), sub)):
        line = item.where.line if item.where is not None and item.where.line is not None else 0
        i = min(max(line - 1, 0), len(stream.wheres) - 1)
        where = stream.wheres[i]
        used.add(where)
        if type(item) is Output:
            item.where = where
            item.publish_time_ns = stream.publish[i]
            yield item
        elif type(item) is Reject:
            yield Reject(where, f"{label}: {item.reason}", item.bad_checksum)
        else:
            yield Ignored(where, f"{label}: {item.reason}")  # type: ignore[union-attr]
    for where in dict.fromkeys(stream.wheres):
        if where not in used:
            yield Ignored(where, f"{label}: {fmt} record merged into its epoch's message or with nothing archived")


def _stream_options(ctx: LogContext, family: str) -> dict:
    """Per-family options a container's manifest entry may give as a table (`[...options.gps]`)."""
    nested = ctx.options.get(family)
    return dict(nested) if isinstance(nested, dict) else {}


# a container's times come from other people's clocks (header stamps, boot counters): outside these years a
# time is a wrong clock, not a measurement, and the archive cannot hold it (unsigned 64-bit nanoseconds)
EARLIEST_NS = 315_964_800 * NS     # 1980-01-06, the GPS epoch
LATEST_NS = 4_102_444_800 * NS     # 2100-01-01


_Item = TypeVar("_Item", bound="Output | Reject | Ignored | SourceBatch | Batch")


def checked_times(items: Iterable[_Item], ctx: LogContext) -> Iterator[_Item | Reject]:
    """The items, with each Output whose log or publish time lies outside 1980-2100 turned into a Reject.

    A record's other outputs at such a time (a fix and its status) give no second Reject: one record, one count.
    When the manifest moves the log's times (a clock offset, a start), its first Output outside is a FormatError
    naming the key and the date it gave instead (`recorders.clock.offset_problem`): a setting, not a record, is wrong.
    """
    rejected: Where | None = None
    unchecked = bool(shift_text(ctx.time_base, ctx.clock_offset_ns))
    for item in items:
        if type(item) is not Output:
            yield item
            continue
        out = cast(Output, item)
        if unchecked:
            unchecked = False
            problem = offset_problem(out.log_time_ns, ctx.time_base, ctx.clock_offset_ns)
            if problem is not None:
                raise FormatError(problem)
        if not (EARLIEST_NS <= out.log_time_ns <= LATEST_NS and EARLIEST_NS <= out.publish_time_ns <= LATEST_NS):
            where = out.where if out.where is not None else Where(0)
            if where == rejected:
                continue
            rejected = where
            yield Reject(where, f"{out.topic}: time {out.log_time_ns / NS:.3f} s (publish "
                                f"{out.publish_time_ns / NS:.3f} s) is not between 1980 and 2100")
        else:
            yield item


# ---------------------------------------------------------------- frames and attitude


def is_ned(frame_id: str) -> bool:
    """Whether a ROS frame name is NED / FRD by the marine convention (a `_ned` or `_frd` suffix)."""
    f = frame_id.strip().lower()
    return f.endswith(("_ned", "_frd")) or f in ("ned", "frd")


WORLD_FRAMES = ("map", "odom", "world", "earth", "enu", "utm", "ned")


def is_world(frame_id: str) -> bool:
    """Whether a ROS frame name is a world (earth-fixed) frame rather than a body frame."""
    f = frame_id.strip().lower().lstrip("/")
    base = f.rsplit("/", 1)[-1]
    return base in WORLD_FRAMES or base.startswith(WORLD_FRAMES) or base.endswith(("_enu", "_ned", "_map", "_odom"))


def enu_to_ned(v: Sequence[float]) -> tuple[float, float, float]:
    """An ENU vector as NED."""
    return v[1], v[0], -v[2]


def flu_to_frd(v: Sequence[float]) -> tuple[float, float, float]:
    """A FLU (ROS body) vector as FRD."""
    return v[0], -v[1], -v[2]


def quaternion_euler(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad, ZYX, about the frame's own axes) of a quaternion; NaN for a zero one."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not n > 1e-9 or not math.isfinite(n):
        return NAN, NAN, NAN
    x, y, z, w = x / n, y / n, z / n, w / n
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def attitude_deg(q: Sequence[float], ned: bool) -> tuple[float, float, float]:
    """(roll, pitch, heading) in our conventions (deg) of an orientation quaternion (x, y, z, w).

    ENU/FLU (ROS default): heading = 90° - yaw, pitch = -pitch (FLU pitch is bow down),
    roll unchanged (left side up = starboard down). NED/FRD: as they are.
    """
    roll, pitch, yaw = quaternion_euler(*q)
    if ned:
        heading = math.degrees(yaw)
    else:
        heading, pitch = 90.0 - math.degrees(yaw), -pitch
    return math.degrees(roll), math.degrees(pitch), wrap_deg(heading)


def wrap_deg(angle: float) -> float:
    """An angle in [0, 360) degrees (a tiny negative one is 0, not 360); NaN stays NaN."""
    if not math.isfinite(angle):
        return NAN
    wrapped = angle % 360.0
    return 0.0 if wrapped >= 360.0 else wrapped


def body_to_ned(v_frd: Sequence[float], roll_deg: float, pitch_deg: float,
                heading_deg: float) -> tuple[float, float, float]:
    """An FRD body vector in NED, by our attitude (ZYX: heading, pitch, roll)."""
    r, p, h = (math.radians(a) for a in (roll_deg, pitch_deg, heading_deg))
    cr, sr, cp, sp, ch, sh = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(h), math.sin(h)
    x, y, z = v_frd
    n = ch * cp * x + (ch * sp * sr - sh * cr) * y + (ch * sp * cr + sh * sr) * z
    e = sh * cp * x + (sh * sp * sr + ch * cr) * y + (sh * sp * cr - ch * sr) * z
    d = -sp * x + cp * sr * y + cp * cr * z
    return n, e, d


def local_to_geodetic(north_m: float, east_m: float, origin: tuple[float, float] | None) -> tuple[float, float]:
    """Latitude and longitude of local east/north metres about `origin` (`formats.geodesy`), else NaN."""
    if origin is None or not (math.isfinite(north_m) and math.isfinite(east_m)):
        return NAN, NAN
    lat, lon = geodesy.local_to_geodetic(east_m, north_m, *origin)
    return lat, (lon + 180.0) % 360.0 - 180.0


def origin_option(ctx: LogContext) -> tuple[float, float] | None:
    """The manifest's `origin = [lat, lon]` (the local frame's datum), or None when absent or unusable."""
    raw = ctx.options.get("origin")
    if isinstance(raw, (list, tuple)) and len(raw) == 2:
        try:
            lat, lon = float(raw[0]), float(raw[1])
        except (TypeError, ValueError):
            return None
        if -90 <= lat <= 90 and -180 <= lon <= 360:
            return lat, lon
    return None


def finite_or_nan(value: object) -> float:
    """A float from anything numeric; NaN for None, text, infinities."""
    try:
        f = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        return NAN
    return f if math.isfinite(f) else NAN
