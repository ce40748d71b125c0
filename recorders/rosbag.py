"""ROS 1 / ROS 2 bags (`format = "rosbag"`) into the archive's sensor topics.

Which topic is which sensor: the manifest's ``topics`` table
(``topics = { "/gps/fix" = "gps", "/nmea" = "gps:nmea", "/auv2/odom" = { sensor = "ins", vehicle = "leader2" } }``;
a topic it does not list is not mapped), else by message type:

- ``sensor_msgs/NavSatFix`` -> ``/<v>/gps`` (LocationFix; its covariance and covariance type are the same ENU m²
  convention) and ``/<v>/gps/status``. Status -1 (no fix) or a NaN position gives the status only.
- ``nmea_msgs/Sentence`` and ``std_msgs/String`` whose text is a vendor sentence -> through our NMEA, PHINS,
  Micro-Modem, EvoLogics, NovAtel or Water Linked converters (`recorders.containers`), one text stream per topic,
  timed by the bag (a Water Linked report's own clock kept as ``device_time``).
- ``sensor_msgs/Imu`` -> ``/<v>/ins`` attitude (heading, roll, pitch and their sigmas), body rates and specific
  force (FRD); ``nav_msgs/Odometry``
  -> ``/<v>/ins`` with position (latitude/longitude from the manifest's ``origin = [lat, lon]``, depth = -z in
  an ENU frame), attitude and velocity rotated into NED.
- ``geometry_msgs/TwistWithCovarianceStamped`` / ``TwistStamped`` on a GNSS topic (named gps, gnss, navsat,
  fix_velocity; or mapped to "gps") -> ``/<v>/gps/velocity`` (its world frame, ENU unless ``_ned``); any other
  -> ``/<v>/dvl`` (BODY_FRD from a ROS body frame,
  EARTH_NED from a world frame), and DVL messages whose definitions the bag carries (any type named ``*Dvl*`` /
  ``*DVL*`` with a ``velocity`` vector: Water Linked, ds_sensor_msgs, cola2, marine_acoustic_msgs, UUV
  simulator) -> ``/<v>/dvl`` in the instrument frame (``dvl_frame`` overrides), with altitude, validity and
  figure of merit where they have them.

Each ROS topic is its own source (`_Sources`): the first of a vehicle's topic keeps it, any other goes below it
(``/<v>/ins/odometry_gps``).

The bag: a ROS 1 ``.bag`` (a list or glob of them for a split recording), or a ROS 2 bag folder (``path =
"dive3/"``, its ``metadata.yaml`` or a storage file in it: `recorders.manifest` makes every file of the folder a
part, all attached; the ``metadata.yaml`` reads the split or compressed storage files it lists); a ``.mcap`` or
``.db3`` alone is read alone. ``msg_paths = [...]`` (``.msg``/``.idl`` files or folders, relative to the manifest)
define custom types the bag does not.

Times: the header stamp is the measurement time (log time), the bag time the publish time; a message without a
header or with a zero stamp takes its bag time.

Every bag message is archived as itself on ``/<v>/ros/<topic>`` (`recorders.ros_raw`), or refused with a reason
(it does not decode by its type, or its type is defined nowhere); a mapped one gives ours as well, and says why
when it gives none (an ignored reason, counted). Standard types are read from their bytes (`OWN`): a
``sensor_msgs/Imu`` (`formats.ros_imu`) converted a batch at a time (`_ImuBatch`), ``nav_msgs/Odometry`` and
``sensor_msgs/NavSatFix`` (`formats.ros_standard`) one by one from their numbers, ``tf2_msgs/TFMessage`` only
checked; rosbags decodes the others, and any message those readers do not read (it then decides and says why).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from formats import ros_imu, ros_standard
from formats import rosbag as rb
from formats import schemas as S
from formats.records import FormatError, Reject, Where
from formats.units import NS

from . import dvl
from .base import Batch, Columns, Converter, Ignored, LogContext, Output, SourceBatch, output
from .containers import (
    EARLIEST_NS,
    LATEST_NS,
    TextStream,
    attitude_deg,
    body_to_ned,
    checked_times,
    convert_stream,
    enu_to_ned,
    finite_or_nan,
    flu_to_frd,
    is_ned,
    is_world,
    local_to_geodetic,
    origin_option,
)
from .gnss_velocity import SUFFIX as VELOCITY
from .gnss_velocity import gnss_velocity
from .gps import gnss_status
from .manifest import SENSORS
from .ros_raw import RosTopics

NAN = math.nan
LINEAR, POSE_COV = ros_standard.LINEAR.start, ros_standard.POSE_COV.start   # in an Odometry's doubles
IMU, ODOMETRY, NAVSATFIX = "sensor_msgs/Imu", "nav_msgs/Odometry", "sensor_msgs/NavSatFix"
RAW_TYPES = ("nmea_msgs/Sentence", "std_msgs/String")
INS_TYPES = ("sensor_msgs/Imu", "nav_msgs/Odometry")
TWIST_TYPES = ("geometry_msgs/TwistWithCovarianceStamped", "geometry_msgs/TwistStamped")
DEFAULT_FAMILY = {"sensor_msgs/NavSatFix": "gps", **{t: "" for t in RAW_TYPES},
                  **{t: "ins" for t in INS_TYPES}, **{t: "dvl" for t in TWIST_TYPES}}
# NavSatStatus.status -> GGA-style quality: -1 no fix, 0 fix, 1 SBAS, 2 GBAS (ground-based: DGPS/RTK)
NAVSAT_QUALITY = {-1: 0, 0: 1, 1: 2, 2: 2}
# names our topics use below a family's (gps/status, gps/velocity, gps/input, ins/local...): a ROS topic's own
# source never takes one
RESERVED_NAMES = frozenset({"status", "velocity", "input", "local", "sbg", "range", "node_report"})
GNSS_WORDS = ("gps", "gnss", "fix_velocity", "navsat")
# ds_sensor_msgs/Dvl (and marine_acoustic_msgs/Dvl) coordinate_mode: 0 beam, 1 instrument, 2 ship, 3 earth
DVL_COORDINATE_MODES = {1: "INSTRUMENT", 2: "BODY_FRD", 3: "EARTH_NED"}


def _is_dvl_type(msgtype: str) -> bool:
    return "dvl" in msgtype.rsplit("/", 1)[-1].lower()


def _target(topic: str, msgtype: str, ctx: LogContext) -> tuple[str, str, str] | None:
    """(family, vehicle, "family[:format]" for raw text) of a topic, or None when it is not mapped."""
    mapping = ctx.options.get("topics")
    if isinstance(mapping, dict):
        entry = mapping.get(topic)
        if entry is None:
            return None
        if isinstance(entry, dict):
            family = str(entry.get("sensor", ""))
            vehicle = str(entry.get("vehicle", ctx.vehicle))
            wanted = family + (":" + str(entry["format"]) if "format" in entry else "")
        else:
            wanted = str(entry)
            family, vehicle = wanted.partition(":")[0], ctx.vehicle
        return (None if family == "ignore" else (family, vehicle, wanted))
    if msgtype in TWIST_TYPES and any(w in topic.lower() for w in GNSS_WORDS):
        return "gps", ctx.vehicle, "gps"  # a GNSS receiver's velocity (ublox fix_velocity, /gps/vel...)
    if msgtype in DEFAULT_FAMILY:
        return DEFAULT_FAMILY[msgtype], ctx.vehicle, DEFAULT_FAMILY[msgtype]
    if _is_dvl_type(msgtype):
        return "dvl", ctx.vehicle, "dvl"
    return None


def _stamp_ns(msg: Any, bag_ns: int) -> int:
    """The header stamp (ns), else the bag time for a message without header or with a zero stamp."""
    stamp = getattr(getattr(msg, "header", None), "stamp", None)
    if stamp is None:
        return bag_ns
    sec = getattr(stamp, "sec", getattr(stamp, "secs", 0))
    nsec = getattr(stamp, "nanosec", getattr(stamp, "nsecs", 0))
    try:
        t = int(sec) * NS + int(nsec)
    except (TypeError, ValueError):
        return bag_ns
    return t if t > 0 else bag_ns


def _frame(msg: Any) -> str:
    return str(getattr(getattr(msg, "header", None), "frame_id", "") or "")


# a bag's few frame names, each looked at once (Imu and Odometry ask at every message)
_ned = functools.lru_cache(maxsize=1024)(is_ned)
_world = functools.lru_cache(maxsize=1024)(is_world)
_UNROUTED = object()


def _num(x: Any) -> float:
    """`finite_or_nan`, with a finite float (what a typed field holds) returned at once: x - x is 0 for those only."""
    return x if type(x) is float and x - x == 0.0 else finite_or_nan(x)


def _vec(v: Any) -> tuple[float, float, float]:
    return _num(getattr(v, "x", NAN)), _num(getattr(v, "y", NAN)), _num(getattr(v, "z", NAN))


def _quat(q: Any) -> tuple[float, float, float, float]:
    return _num(getattr(q, "x", NAN)), _num(getattr(q, "y", NAN)), _num(getattr(q, "z", NAN)), \
        _num(getattr(q, "w", NAN))


def _cov(values: Any, n: int) -> list[float]:
    if type(values) is np.ndarray and values.dtype == np.float64 and values.ndim == 1 and len(values) >= n:
        out = values[:n].tolist()   # the typed field's array: one conversion, then only non-finite ones replaced
        return out if all(map(math.isfinite, out)) else [v if math.isfinite(v) else NAN for v in out]
    out = [finite_or_nan(v) for v in list(values if values is not None else ())[:n]]
    return out + [NAN] * (n - len(out))


def _finite(values: tuple[float, ...]) -> list[float]:
    """Floats read from bytes with the non-finite ones NaN, as `_cov` gives a typed field's array."""
    out = list(values)
    return out if all(map(math.isfinite, out)) else [v if math.isfinite(v) else NAN for v in out]


def _first(values: Any) -> float:
    """A covariance's first element (NaN when it has none or it is not a number)."""
    if type(values) is np.ndarray and values.ndim == 1 and len(values):
        return _num(float(values[0])) if values.dtype.kind == "f" else finite_or_nan(values[0])
    return _cov(values, 1)[0]


def _sigma_deg(variance_rad2: float) -> float:
    return math.degrees(math.sqrt(variance_rad2)) if variance_rad2 >= 0 else NAN


def _main_key(msgtype: str, family: str) -> str | None:
    """The archive topic (below the vehicle) a typed ROS topic writes first; None for raw text, whose vendor
    converter decides."""
    if msgtype == "sensor_msgs/NavSatFix":
        return "gps"
    if msgtype in INS_TYPES:
        return "ins"
    if msgtype in TWIST_TYPES:
        return VELOCITY if family == "gps" else "dvl"
    return "dvl" if _is_dvl_type(msgtype) else None


def source_name(topic: str) -> str:
    """The name of a ROS topic as a source of its own below its family's topic: "/odometry/gps" -> "odometry_gps"
    (a name our topics already use below a family, "status" say, gets a "ros_" prefix)."""
    name = re.sub(r"[^A-Za-z0-9_]+", "_", topic.strip("/")).strip("_") or "topic"
    return "ros_" + name if name in RESERVED_NAMES else name


class _Sources:
    """Each ROS topic its own source: the first ROS topic of a vehicle's archive topic keeps it; every other one
    mapped there (a second Odometry, an Imu beside an Odometry) writes below it, `/<v>/ins/<name>`, as MAVLink's
    GPS_INPUT writes `/<v>/gps/input`: two clocks never share a topic, and the replay draws each as a track."""

    def __init__(self) -> None:
        self.owner: dict[tuple[str, str], str] = {}   # (vehicle, archive topic below it) -> the ROS topic there
        self.name: dict[str, str] = {}                # ROS topic -> "" (owns its topic) or its name below it
        self.places: dict[tuple[str, str], str] = {}  # (archive topic, ROS topic) -> `placed`, once claimed

    def claim(self, vehicle: str, key: str, topic: str) -> None:
        """The ROS topic's place, once: its archive topic, or its own name below the one another topic holds."""
        if topic not in self.name:
            owner = self.owner.setdefault((vehicle, key), topic)
            self.name[topic] = "" if owner == topic else source_name(topic)

    def place(self, item: Output, topic: str) -> None:
        """Move an output of a ROS topic to that topic's own source (claimed by its first output if not yet)."""
        item.topic = self.placed(item.topic, topic)

    def placed(self, archive_topic: str, topic: str) -> str:
        """The archive topic an output of a ROS topic goes to: its own source's (claimed by its first output if
        not yet)."""
        place = self.places.get((archive_topic, topic))
        if place is not None:
            return place
        parts = archive_topic.split("/", 3)   # "", vehicle, family, rest
        if topic not in self.name and len(parts) >= 3:
            self.claim(parts[1], parts[2], topic)
        name = self.name.get(topic)
        place = "/".join([*parts[:3], name, *parts[3:]]) if name else archive_topic
        if topic in self.name:   # claimed: its place never changes
            self.places[(archive_topic, topic)] = place
        return place


class _Bag:
    """One recording of a bag's messages: converts each, keeps raw text streams to convert at the end."""

    def __init__(self, ctx: LogContext, topics: list[tuple[str, str]]):
        self.ctx = ctx
        self.origin = origin_option(ctx)
        self.streams: dict[str, TextStream] = {}
        self.sources = _Sources()
        self.targets: dict[tuple[str, str], bool] = {}   # (topic, type) -> mapped to ours
        self.found: dict[tuple[str, str], tuple[str, str, str] | None] = {}   # (topic, type) -> its `_target`
        self.imus: dict[str, _ImuBatch] = {}              # Imu topic -> its messages read from their bytes
        # (topic, type) -> the context an Odometry or NavSatFix of it converts in, None when `item` must take it
        self.routes: dict[tuple[str, str], LogContext | None] = {}
        self.oldest: int | None = None   # the number of the earliest bag message an Imu batch holds
        # typed topics claim their archive topics first, a position (Odometry) before an attitude alone (Imu)
        ranked = []
        for topic, msgtype in dict.fromkeys(topics):
            target = _target(topic, msgtype, ctx)
            key = _main_key(msgtype, target[0]) if target is not None else None
            if target is not None and key is not None:
                ranked.append((target[1], key, msgtype == "sensor_msgs/Imu", topic))
        for vehicle, key, _, topic in sorted(ranked):
            self.sources.claim(vehicle, key, topic)

    def maps(self, topic: str, msgtype: str) -> bool:
        """Whether a topic of this type gives messages of ours (the manifest's topics, else its type)."""
        key = (topic, msgtype)
        found = self.targets.get(key)
        if found is None:
            found = self.targets[key] = _target(topic, msgtype, self.ctx) is not None
        return found

    def kept_imu(self, m: rb.BagMessage, where: Where) -> bool:
        """Keep an Imu read from its bytes (`OWN`) in its topic's batch when `item` would, without filling it;
        whether it was kept (else `item` takes it). The busiest topic of a bag, without `item`'s generators."""
        batch = self.imus.get(m.topic)
        if batch is None or len(batch.data) + 1 >= IMU_BATCH or not m.undecoded or m.msgtype != IMU:
            return False   # (a batch is made by `item`, for a topic mapped to a sensor only)
        stamp = m.message[0]
        batch.add((stamp if stamp > 0 else m.bag_time_ns) + batch.ctx.clock_offset_ns,
                  m.bag_time_ns + batch.ctx.clock_offset_ns, where, m.message[1], m.data)
        if self.oldest is None:
            self.oldest = where.message
        return True

    def item(self, m: rb.BagMessage, where: Where) -> Iterator[Output | Reject | Ignored | Batch]:
        """The archive messages of one bag message (raw text kept for `finish`; an Imu read from its bytes, `OWN`,
        for its topic's batch), each on its topic's source."""
        for item in self._item(m, where):
            if type(item) is Output:
                self.sources.place(item, m.topic)
            yield item

    def take(self, m: rb.BagMessage, where: Where) -> Iterable[Output | Reject | Ignored | Batch] | None:
        """The archive messages of ours of one bag message (`item`'s), or None when it gives none now: its topic is
        not mapped, or it went into its topic's Imu batch (`kept_imu`). An Odometry or NavSatFix read from its
        bytes gives a list (`standard`)."""
        mapped = self.targets.get((m.topic, m.msgtype))
        if mapped is None:
            mapped = self.maps(m.topic, m.msgtype)
        if not mapped:
            return None
        if m.undecoded:
            if m.msgtype == IMU:
                if self.kept_imu(m, where):
                    return None
            else:
                items = self.standard(m, where)
                if items is not None:
                    return items
        return self.item(m, where)

    def standard(self, m: rb.BagMessage, where: Where) -> list[Output | Reject] | None:
        """`item`'s archive messages of an Odometry or NavSatFix read from its bytes (`OWN`), as a list; None for
        any other message (`item` takes it)."""
        if not m.undecoded or (m.msgtype != ODOMETRY and m.msgtype != NAVSATFIX):
            return None
        key = (m.topic, m.msgtype)
        ctx = self.routes.get(key, _UNROUTED)
        if ctx is _UNROUTED:
            ctx = self.routes[key] = self._route(key)
        if ctx is None:
            return None
        assert isinstance(ctx, LogContext)
        head = m.message
        offset = ctx.clock_offset_ns
        publish = m.bag_time_ns + offset
        t = (head[0] if head[0] > 0 else m.bag_time_ns) + offset
        vehicle = ctx.vehicle
        out: list[Output | Reject] = []
        if m.msgtype == ODOMETRY:
            _, frame, child, v = head   # the doubles: `ros_standard.ODOMETRY_DOUBLES`
            # position, orientation, linear velocity, the x, y and yaw variances: read from bytes, so floats
            used = (*v[0:7], *v[LINEAR:LINEAR + 3], v[POSE_COV], v[POSE_COV + 7], v[POSE_COV + 35])
            if not all(map(math.isfinite, used)):
                used = tuple(map(_num, used))
            fields = _odometry_fields(frame, child, used[0:3], used[3:7], used[7:10], used[10:13], self.origin)
            if fields is None:
                out.append(Reject(where, NO_ODOMETRY))
            else:
                out.append(Output(self.sources.placed(f"/{vehicle}/ins", m.topic), S.ins_state(t, vehicle, *fields),
                                  t, publish, where))
            return out
        _, _, status, v, kind = head
        fix, quality = _navsatfix_values(status, _num(v[0]), _num(v[1]), _num(v[2]), _finite(v[3:]), kind)
        if fix is not None:
            out.append(Output(self.sources.placed(f"/{vehicle}/gps", m.topic), _fix(t, vehicle, *fix), t, publish,
                              where))
        out.append(Output(self.sources.placed(f"/{vehicle}/gps/status", m.topic), _status(t, vehicle, quality), t,
                          publish, where))
        return out

    def _route(self, key: tuple[str, str]) -> LogContext | None:
        """The context a topic's messages convert in (its vehicle's); None when its target is none, or refused
        (`item` says why, message by message)."""
        target = self.found[key] if key in self.found else self.found.setdefault(key, _target(*key, self.ctx))
        if target is None or (target[0] and target[0] not in SENSORS):
            return None
        return self.ctx if target[1] == self.ctx.vehicle else _with_vehicle(self.ctx, target[1])

    def due(self, number: int) -> bool:
        """Whether an Imu batch holds a message more than IMU_SPAN bag messages before message `number`."""
        return self.oldest is not None and number - self.oldest >= IMU_SPAN

    def flush(self) -> Iterator[Output | Reject | Batch]:
        """Every Imu batch's messages, each on its topic's source."""
        self.oldest = None
        for topic, batch in self.imus.items():
            for item in batch.flush(self.sources.placed(f"/{batch.ctx.vehicle}/ins", topic)):
                if type(item) is Output:
                    self.sources.place(item, topic)
                yield item

    def _item(self, m: rb.BagMessage, where: Where) -> Iterator[Output | Reject | Ignored | Batch]:
        key = (m.topic, m.msgtype)
        target = self.found[key] if key in self.found else self.found.setdefault(key, _target(*key, self.ctx))
        if target is None:   # archived as itself alone (`recorders.ros_raw`)
            return
        family, vehicle, wanted = target
        if family and family not in SENSORS:
            yield Reject(where, f"{m.topic} ({m.msgtype}): the manifest maps it to {family!r}, not one of "
                                f"{', '.join(SENSORS)}")
            return
        ctx = self.ctx if vehicle == self.ctx.vehicle else _with_vehicle(self.ctx, vehicle)
        publish = m.bag_time_ns + ctx.clock_offset_ns
        head = m.message if m.undecoded else None   # what `OWN`'s reader read of it
        if head is not None and m.msgtype == IMU:   # an Imu read from its bytes: converted with its topic's batch
            batch = self.imus.get(m.topic)
            if batch is None:
                batch = self.imus[m.topic] = _ImuBatch(ctx)
            if self.oldest is None:
                self.oldest = where.message
            stamp = head[0] if head[0] > 0 else m.bag_time_ns
            if batch.add(stamp + ctx.clock_offset_ns, publish, where, head[1], m.data):
                yield from batch.flush(self.sources.placed(f"/{ctx.vehicle}/ins", m.topic))
            return
        if head is not None and m.msgtype in (ODOMETRY, NAVSATFIX):   # read from its bytes (`formats.ros_standard`)
            t = (head[0] if head[0] > 0 else m.bag_time_ns) + ctx.clock_offset_ns
            if m.msgtype == ODOMETRY:
                _, frame, child, v = head
                x, y, z, qx, qy, qz, qw = map(_num, v[:7])   # position, orientation (`ros_standard.ODOMETRY_DOUBLES`)
                vx, vy, vz = map(_num, v[LINEAR:LINEAR + 3])
                cov = v[POSE_COV:POSE_COV + 36]
                fields = _odometry_fields(frame, child, (x, y, z), (qx, qy, qz, qw), (vx, vy, vz),
                                          (_num(cov[0]), _num(cov[7]), _num(cov[35])), self.origin)
                if fields is None:
                    yield Reject(where, NO_ODOMETRY)
                else:
                    yield _out(ctx, "ins", S.ins_state(t, ctx.vehicle, *fields), t, publish, where)
            else:
                _, _, status, v, kind = head
                fix, quality = _navsatfix_values(status, _num(v[0]), _num(v[1]), _num(v[2]), _finite(v[3:]), kind)
                yield from _navsatfix_outputs(ctx, fix, quality, t, publish, where)
            return
        t = _stamp_ns(m.message, m.bag_time_ns) + ctx.clock_offset_ns
        msg = m.message
        if m.msgtype in RAW_TYPES:
            text = getattr(msg, "sentence", None) if m.msgtype == "nmea_msgs/Sentence" else getattr(msg, "data", None)
            if not isinstance(text, str):
                yield Reject(where, f"{m.topic} ({m.msgtype}): no text")
                return
            stream = self.streams.get(m.topic)
            if stream is None:
                stream = self.streams[m.topic] = TextStream(vehicle, wanted)
            stream.add(text, where, t - ctx.clock_offset_ns, publish)
            return
        if m.msgtype == "sensor_msgs/NavSatFix":
            yield from _navsatfix(ctx, msg, t, publish, where)
        elif m.msgtype == "sensor_msgs/Imu":
            yield from _imu(ctx, msg, t, publish, where)
        elif m.msgtype == "nav_msgs/Odometry":
            yield from _odometry(ctx, msg, t, publish, where, self.origin)
        elif m.msgtype in TWIST_TYPES and family == "gps":
            yield _gnss_twist(ctx, m.msgtype, msg, t, publish, where)
        elif m.msgtype in TWIST_TYPES or _is_dvl_type(m.msgtype):
            yield from _velocity(ctx, m.msgtype, msg, t, publish, where)
        else:
            yield Reject(where, f"{m.topic} ({m.msgtype}): mapped to {family}, but we convert no {m.msgtype} message")

    def finish(self) -> Iterator[Output | Reject | Ignored | Batch]:
        """The Imu batches, then the raw text streams through their vendor converters, each on its topic's
        source."""
        yield from self.flush()
        for topic, stream in self.streams.items():
            for item in convert_stream(stream, self.ctx, topic):
                if type(item) is Output:
                    self.sources.place(item, topic)
                yield item


_new = object.__new__
_SET_WHERE: tuple[Any, ...] = tuple(vars(Where)[name].__set__ for name in ("offset", "line", "host_time_ns", "message"))


def _where(offset: int, host_time_ns: int, message: int) -> Where:
    """`Where(offset, None, host_time_ns, message)`, made through its slots: one per bag message, and a frozen
    dataclass's __init__ (object.__setattr__ per field) costs twice as much."""
    where = _new(Where)
    set_offset, set_line, set_host, set_message = _SET_WHERE
    set_offset(where, offset)
    set_line(where, None)
    set_host(where, host_time_ns)
    set_message(where, message)
    return where


def _with_vehicle(ctx: LogContext, vehicle: str) -> LogContext:
    return replace(ctx, vehicle=vehicle)


def _out(ctx: LogContext, suffix: str, message: Any, t: int, publish: int, where: Where) -> Output:
    item = output(ctx, suffix, message, t, where)
    item.publish_time_ns = publish
    return item


def _navsatfix(ctx: LogContext, msg: Any, t: int, publish: int, where: Where) -> Iterator[Output | Reject]:
    lat, lon = finite_or_nan(getattr(msg, "latitude", NAN)), finite_or_nan(getattr(msg, "longitude", NAN))
    yield from _navsatfix_fix(ctx, getattr(getattr(msg, "status", None), "status", -1), lat, lon,
                              finite_or_nan(getattr(msg, "altitude", NAN)),
                              _cov(getattr(msg, "position_covariance", ()), 9),
                              getattr(msg, "position_covariance_type", 0), t, publish, where)


def _navsatfix_fix(ctx: LogContext, status: Any, lat: float, lon: float, alt: float, cov: list[float], kind: Any,
                   t: int, publish: int, where: Where) -> Iterator[Output]:
    """A NavSatFix's LocationFix (when it has a fix) and status, from its fields (non-finite numbers NaN)."""
    yield from _navsatfix_outputs(ctx, *_navsatfix_values(status, lat, lon, alt, cov, kind), t, publish, where)


NAVSATFIX_SOURCE = "rosbag:sensor_msgs/NavSatFix"
_NAN9 = (NAN,) * 9


def _navsatfix_values(status: Any, lat: float, lon: float, alt: float, cov: list[float],
                      kind: Any) -> tuple[tuple[float, float, float, tuple[float, ...], int] | None, int]:
    """A NavSatFix's fix as `_fix`'s arguments after time and frame (None without a fix), and its status's quality."""
    try:
        quality = NAVSAT_QUALITY.get(int(status), 0)
    except (TypeError, ValueError):
        quality = 0
    if quality > 0 and math.isfinite(lat) and math.isfinite(lon) and -90 <= lat <= 90:
        kind = int(kind) if isinstance(kind, int) and 0 <= kind <= 3 and all(map(math.isfinite, cov)) else 0
        # no covariance is NaNs of type unknown: what S.location_fix writes for none
        return (lat, (lon + 180.0) % 360.0 - 180.0, alt, tuple(cov) if kind else _NAN9, kind), quality
    return None, quality


def _fix(t: int, vehicle: str, lat: float, lon: float, alt: float, cov: tuple[float, ...], kind: int) -> Any:
    return S.location_fix(t, vehicle, lat, lon, alt, cov, kind)


def _status(t: int, vehicle: str, quality: int) -> Any:
    return gnss_status(t, vehicle, quality, -1, NAN, NAVSATFIX_SOURCE, NAN, NAN, NAN)


def _navsatfix_outputs(ctx: LogContext, fix: tuple | None, quality: int, t: int, publish: int,
                       where: Where) -> Iterator[Output]:
    if fix is not None:
        yield _out(ctx, "gps", _fix(t, ctx.vehicle, *fix), t, publish, where)
    yield _out(ctx, "gps/status", _status(t, ctx.vehicle, quality), t, publish, where)


def _imu(ctx: LogContext, msg: Any, t: int, publish: int, where: Where) -> Iterator[Output | Reject]:
    cov = _cov(getattr(msg, "orientation_covariance", ()), 9)
    if cov[0] == -1:  # REP-145: -1 in the first element means the IMU gives no orientation
        yield Reject(where, "sensor_msgs/Imu without orientation (orientation_covariance[0] = -1)")
        return
    frd = _ned(_frame(msg))
    roll, pitch, heading = attitude_deg(_quat(getattr(msg, "orientation", None)), frd)
    if not math.isfinite(heading):
        yield Reject(where, "sensor_msgs/Imu orientation is not a rotation (zero or NaN quaternion)")
        return
    state = S.ins_state(t, ctx.vehicle, "rosbag:sensor_msgs/Imu", "", NAN, NAN, NAN, roll, pitch, heading, NAN, NAN,
                        NAN, _sigma_deg(cov[8]), NAN, NAN, _sigma_deg(cov[0]), _sigma_deg(cov[4]), NAN)
    _imu_rates(state, msg, frd)
    yield _out(ctx, "ins", state, t, publish, where)


def _imu_rates(state: S.InsState, msg: Any, frd: bool) -> None:
    """An Imu's angular velocity and linear acceleration in FRD body axes (REP-103: FLU unless the frame is
    _frd/_ned) set on its state, each left out when its covariance[0] is -1 (REP-145: not given)."""
    if _first(getattr(msg, "angular_velocity_covariance", ())) != -1:
        x, y, z = _vec(getattr(msg, "angular_velocity", None))
        state.angular_velocity_x_radps = x
        state.angular_velocity_y_radps, state.angular_velocity_z_radps = (y, z) if frd else (-y, -z)
    if _first(getattr(msg, "linear_acceleration_covariance", ())) != -1:
        x, y, z = _vec(getattr(msg, "linear_acceleration", None))
        state.linear_acceleration_x_mps2 = x
        state.linear_acceleration_y_mps2, state.linear_acceleration_z_mps2 = (y, z) if frd else (-y, -z)


# Imu messages converted together (`_ImuBatch`); a batch is given out before a record it holds lies IMU_SPAN bag
# messages back, well inside the window the recording counts distinct records in (record.RECORDS_WINDOW)
IMU_BATCH = 512
IMU_SPAN = 2048
IMU_SOURCE = "rosbag:sensor_msgs/Imu"


class _ImuBatch:
    """An Imu topic's messages read from their bytes (`formats.ros_imu`), converted IMU_BATCH at a time: the
    attitude, sigmas and FRD rates over numpy columns, as `_imu` gives them one by one; one InsState each."""

    def __init__(self, ctx: LogContext):
        self.ctx = ctx
        self.rows: list[tuple[int, int, Where, bytes]] = []   # (time, publish time, where, frame_id)
        self.frames: list[bytes] = []                          # each one's frame_id (most often one name)
        self.data: list[bytes] = []

    def add(self, t: int, publish: int, where: Where, frame: bytes, data: bytes) -> bool:
        """Keep one message; whether the batch is full."""
        self.rows.append((t, publish, where, frame))
        self.frames.append(frame)
        self.data.append(data)
        return len(self.data) >= IMU_BATCH

    def flush(self, topic: str) -> Iterator[Output | Reject | Batch]:
        """The batch's InsStates (or rejects, as `_imu` gives them), in the order the messages came: one Batch of
        columns on `topic` (the ROS topic's own source) when the recording takes them and none is refused here,
        else one by one on the vehicle's INS topic (the caller places them, as `_imu`'s)."""
        rows, data, frames = self.rows, self.data, self.frames
        if not rows:
            return
        self.rows, self.data, self.frames = [], [], []
        v = ros_imu.values(data)
        if frames.count(frames[0]) == len(frames):   # one frame name: one look at it
            frd = np.full(len(frames), _ned_bytes(frames[0]))
        else:
            frd = np.array([_ned_bytes(frame) for frame in frames])
        x, y, z, w = (v[:, k] for k in range(4))
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            n = np.sqrt(x * x + y * y + z * z + w * w)
            x, y, z, w = x / n, y / n, z / n, w / n
            roll = np.degrees(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))
            pitch = np.degrees(np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0)))
            yaw = np.degrees(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
            rotation = (n > 1e-9) & np.isfinite(n)   # as quaternion_euler: a zero or overflowing one is none
            heading = np.where(frd, yaw, 90.0 - yaw) % 360.0
            heading = np.where(rotation & np.isfinite(heading), np.where(heading >= 360.0, 0.0, heading), np.nan)
            pitch = np.where(frd, pitch, -pitch)
            cov = v[:, ros_imu.ORIENTATION_COV]
            sigma = np.where(cov >= 0, np.degrees(np.sqrt(np.abs(cov))), np.nan)
        sign = np.where(frd, 1.0, -1.0)
        angular, linear = v[:, ros_imu.ANGULAR].copy(), v[:, ros_imu.LINEAR].copy()
        angular[:, 1:] *= sign[:, None]
        linear[:, 1:] *= sign[:, None]
        none = v[:, 4] == -1   # REP-145: -1 in the first element means the IMU gives no orientation
        has_av, has_la = v[:, ros_imu.ANGULAR_COV0] != -1, v[:, ros_imu.LINEAR_COV0] != -1
        vehicle = self.ctx.vehicle
        if self.ctx.batches and not (none.any() or np.isnan(heading).any()):
            batch = _imu_batch(topic, vehicle, rows, (roll, pitch, heading, sigma), (angular, has_av),
                               (linear, has_la))
            if batch is not None:
                yield batch
                return
        cols = zip(roll.tolist(), pitch.tolist(), heading.tolist(), sigma[:, 0].tolist(), sigma[:, 4].tolist(),
                   sigma[:, 8].tolist(), none.tolist(), has_av.tolist(), angular.tolist(), has_la.tolist(),
                   linear.tolist())
        for (t, publish, where, _), (r, p, h, rs, ps, hs, no, av_given, av, la_given, la) in zip(rows, cols):
            if no:
                yield Reject(where, "sensor_msgs/Imu without orientation (orientation_covariance[0] = -1)")
                continue
            if h != h:
                yield Reject(where, "sensor_msgs/Imu orientation is not a rotation (zero or NaN quaternion)")
                continue
            yield Output(f"/{vehicle}/ins", _imu_state(t, vehicle, r, p, h, rs, ps, hs, av if av_given else None,
                                                       la if la_given else None), t, publish, where)


def _imu_state(t: int, vehicle: str, roll: float, pitch: float, heading: float, roll_std: float, pitch_std: float,
               heading_std: float, angular: list[float] | None, linear: list[float] | None) -> S.InsState:
    """An Imu's InsState: attitude and sigmas, and the FRD rates and specific force where given (None: not)."""
    state = S.ins_state(t, vehicle, IMU_SOURCE, "", NAN, NAN, NAN, roll, pitch, heading, NAN, NAN, NAN, heading_std,
                        NAN, NAN, roll_std, pitch_std, NAN)
    if angular is not None:
        state.angular_velocity_x_radps, state.angular_velocity_y_radps, state.angular_velocity_z_radps = angular
    if linear is not None:
        (state.linear_acceleration_x_mps2, state.linear_acceleration_y_mps2,
         state.linear_acceleration_z_mps2) = linear
    return state


IMU_RATES = ("angular_velocity_x_radps", "angular_velocity_y_radps", "angular_velocity_z_radps")
IMU_FORCES = ("linear_acceleration_x_mps2", "linear_acceleration_y_mps2", "linear_acceleration_z_mps2")


def _imu_batch(topic: str, vehicle: str, rows: list[tuple[int, int, Where, bytes]],
               attitude: tuple[np.ndarray, ...], angular: tuple[np.ndarray, np.ndarray],
               linear: tuple[np.ndarray, np.ndarray]) -> Batch | None:
    """An Imu batch's InsStates (none refused here) as one Batch of columns, `_imu_state`'s messages; None when a
    time lies outside 1980-2100 (`checked_times` refuses those one by one)."""
    times = [r[0] for r in rows]
    publish = [r[1] for r in rows]
    if not (EARLIEST_NS <= min(times) and max(times) <= LATEST_NS and EARLIEST_NS <= min(publish)
            and max(publish) <= LATEST_NS):
        return None
    log_ns, publish_ns = np.array(times, dtype=np.int64), np.array(publish, dtype=np.int64)
    wheres = [r[2] for r in rows]
    roll, pitch, heading, sigma = attitude
    columns: dict[str, Any] = {
        "timestamp": log_ns, "frame_id": vehicle, "source_format": IMU_SOURCE, "latitude": NAN, "longitude": NAN,
        "depth_m": NAN, "roll_deg": roll, "pitch_deg": pitch, "heading_deg": heading, "velocity_north_mps": NAN,
        "velocity_east_mps": NAN, "velocity_down_mps": NAN, "heading_std_deg": sigma[:, 8],
        "position_std_north_m": NAN, "position_std_east_m": NAN, "roll_std_deg": sigma[:, 0],
        "pitch_std_deg": sigma[:, 4], "altitude_m": NAN}
    for names, (values, given) in ((IMU_RATES, angular), (IMU_FORCES, linear)):
        if given.all():   # set in every row
            for k, name in enumerate(names):
                columns[name] = values[:, k]
        elif given.any():   # a masked row leaves the three unset, as `_imu_state` does without them
            for k, name in enumerate(names):
                columns[name] = np.ma.masked_array(values[:, k], mask=~given)

    def outputs() -> Iterator[Output]:
        for (t, p, where, _), r, pt, h, s, av, la, av_given, la_given in zip(
                rows, roll.tolist(), pitch.tolist(), heading.tolist(), sigma.tolist(), angular[0].tolist(),
                linear[0].tolist(), angular[1].tolist(), linear[1].tolist()):
            yield Output(topic, _imu_state(t, vehicle, r, pt, h, s[0], s[4], s[8], av if av_given else None,
                                           la if la_given else None), t, p, where)

    return Batch([Columns(topic, S.InsState, columns, log_ns, publish_ns)], np.zeros(len(rows), dtype=np.int64),
                 np.array([w.offset for w in wheres], dtype=np.int64), wheres[-1], outputs)


@functools.lru_cache(maxsize=1024)
def _ned_bytes(frame: bytes) -> bool:
    return is_ned(frame.decode("utf-8", "replace"))


def _odometry(ctx: LogContext, msg: Any, t: int, publish: int, where: Where,
              origin: tuple[float, float] | None) -> Iterator[Output | Reject]:
    pose = getattr(getattr(msg, "pose", None), "pose", None)
    yield from _odometry_state(ctx, _frame(msg), str(getattr(msg, "child_frame_id", "") or ""),
                               _vec(getattr(pose, "position", None)), _quat(getattr(pose, "orientation", None)),
                               _vec(getattr(getattr(getattr(msg, "twist", None), "twist", None), "linear", None)),
                               _cov(getattr(getattr(msg, "pose", None), "covariance", ()), 36), t, publish, where,
                               origin)


def _odometry_state(ctx: LogContext, frame: str, child: str, position: tuple[float, float, float],
                    quaternion: tuple[float, float, float, float], linear: tuple[float, float, float],
                    pcov: list[float], t: int, publish: int, where: Where,
                    origin: tuple[float, float] | None) -> Iterator[Output | Reject]:
    """An Odometry's InsState from its fields (non-finite numbers NaN), or why it gives none."""
    fields = _odometry_fields(frame, child, position, quaternion, linear, (pcov[0], pcov[7], pcov[35]), origin)
    if fields is None:
        yield Reject(where, NO_ODOMETRY)
        return
    yield _out(ctx, "ins", S.ins_state(t, ctx.vehicle, *fields), t, publish, where)


NO_ODOMETRY = "nav_msgs/Odometry with neither position, orientation nor velocity"
ODOMETRY_SOURCE = "rosbag:nav_msgs/Odometry"


def _odometry_fields(frame: str, child: str, position: tuple[float, float, float],
                     quaternion: tuple[float, float, float, float], linear: tuple[float, float, float],
                     variances: tuple[float, float, float], origin: tuple[float, float] | None) -> tuple | None:
    """An Odometry's InsState as S.ins_state's arguments after time and frame (`ins.INS_FIELDS`), or None when it
    has neither position, orientation nor velocity. `variances`: its pose covariance's x, y and yaw ones."""
    ned = _ned(frame)
    north, east, down = position if ned else enu_to_ned(position)
    roll, pitch, heading = attitude_deg(quaternion, ned)
    lat, lon = local_to_geodetic(north, east, origin)
    if _world(child):  # a twist given in a world frame, against REP-103's child frame
        vn, ve, vd = linear if _ned(child) else enu_to_ned(linear)
    elif math.isfinite(heading):
        vn, ve, vd = body_to_ned(linear if _ned(child) else flu_to_frd(linear), roll, pitch, heading)
    else:
        vn = ve = vd = NAN
    sn, se = (variances[0], variances[1]) if ned else (variances[1], variances[0])
    if not any(map(math.isfinite, (north, east, down, heading, vn))):
        return None
    return (ODOMETRY_SOURCE, "", lat, lon, down, roll, pitch, heading, vn, ve, vd, _sigma_deg(variances[2]),
            math.sqrt(sn) if sn >= 0 else NAN, math.sqrt(se) if se >= 0 else NAN, NAN, NAN, NAN)


def _gnss_twist(ctx: LogContext, msgtype: str, msg: Any, t: int, publish: int, where: Where) -> Output:
    """A GNSS receiver's Twist: linear velocity in its world frame (ENU unless the frame is _ned)."""
    twist = getattr(msg, "twist", None)
    twist = getattr(twist, "twist", twist)
    v = _vec(getattr(twist, "linear", None))
    north, east, down = v if is_ned(_frame(msg)) else enu_to_ned(v)
    cov = _cov(getattr(getattr(msg, "twist", None), "covariance", ()), 36)
    horizontal = cov[0] + cov[7]
    velocity = gnss_velocity(ctx, t, "rosbag:" + msgtype, north=north, east=east, up=-down,
                             speed_std=math.sqrt(horizontal) if horizontal >= 0 else NAN)
    return _out(ctx, VELOCITY, velocity, t, publish, where)


def _velocity(ctx: LogContext, msgtype: str, msg: Any, t: int, publish: int,
              where: Where) -> Iterator[Output | Reject]:
    source = "rosbag:" + msgtype
    if msgtype in TWIST_TYPES:
        twist = getattr(msg, "twist", None)
        twist = getattr(twist, "twist", twist)  # WithCovariance nests one more level
        v = _vec(getattr(twist, "linear", None))
        frame_id = _frame(msg)
        if is_world(frame_id):
            frame, v = "EARTH_NED", (v if is_ned(frame_id) else enu_to_ned(v))
        else:
            frame, v = "BODY_FRD", (v if is_ned(frame_id) else flu_to_frd(v))
        if "dvl_frame" in ctx.options:
            frame = dvl.frame_option(ctx, frame)
        yield _out(ctx, "dvl", dvl.message(ctx, t, frame, v, source=source), t, publish, where)
        return
    velocity = getattr(msg, "velocity", None)
    if velocity is None or not hasattr(velocity, "x"):
        yield Reject(where, f"{msgtype} has no velocity vector")
        return
    v = _vec(velocity)
    valid = None
    for name in ("velocity_valid", "valid"):
        flag = getattr(msg, name, None)
        if isinstance(flag, (bool, int)):
            valid = bool(flag) and all(map(math.isfinite, v))
    altitude = finite_or_nan(getattr(msg, "altitude", NAN))
    fom = finite_or_nan(getattr(msg, "fom", getattr(msg, "figure_of_merit", NAN)))
    frame = "INSTRUMENT"
    mode = getattr(msg, "coordinate_mode", None)  # ds_sensor_msgs / marine_acoustic_msgs: the frame it is in
    if isinstance(mode, int):
        if mode not in DVL_COORDINATE_MODES:
            yield Reject(where, f"{msgtype}: velocity in beam coordinates (coordinate_mode {mode}): not archived")
            return
        frame = DVL_COORDINATE_MODES[mode]
    frame = dvl.frame_option(ctx, frame)
    sound = finite_or_nan(getattr(msg, "sound_speed", NAN))
    yield _out(ctx, "dvl", dvl.message(ctx, t, frame, v, altitude=altitude, valid=valid, fom=fom, sound_speed=sound,
                                       source=source), t, publish, where)


def convert_rosbag(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored | SourceBatch | Batch]:
    """ROS 1 .bag, ROS 2 .mcap/.db3 (rosbags): NavSatFix, NMEA/text sentences, Imu, Odometry, Twist, DVL."""
    return checked_times(_convert_rosbag(data, ctx), ctx)


def _convert_rosbag(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored | SourceBatch | Batch]:
    if not ctx.files:
        raise FormatError("a bag is read from its file: no file given")
    folders = {p.parent for p in ctx.files if p.name == "metadata.yaml"}
    # a ROS 2 bag folder given whole (path = "dive3/"): its metadata.yaml reads every storage file of it
    files = [p for p in ctx.files if p.name == "metadata.yaml" or p.parent not in folders]
    # the first file stays open from its topics to its messages (a bag of one file or folder: opened once); the
    # others are opened for their topics, then again to be read (an open ROS 1 bag holds its whole index)
    try:
        first: rb.OpenBag | None = rb.open_bag(files[0])
    except FormatError:
        first = None   # reading it says why
    try:
        topics = (rb.opened_topics(first) if first is not None else []) + [t for p in files[1:] for t in _topics(p)]
        yield from _bag_items(ctx, _Bag(ctx, topics), files, first)
    finally:
        if first is not None:
            rb.close_bag(first)


def _bag_items(ctx: LogContext, bag: _Bag, files: list[Path], first: rb.OpenBag | None
               ) -> Iterator[Output | Reject | Ignored | SourceBatch | Batch]:
    """The archive items of a bag's files, in order (the first one read from `first` when it is open)."""
    raw = RosTopics(ctx)
    own = OWN
    msg_paths = ctx.options.get("msg_paths")
    types = rb.definitions([Path(p) for p in msg_paths]) if isinstance(msg_paths, list) else {}
    start, number = 0, 0
    for path in files:
        try:
            size = path.stat().st_size
        except OSError as exc:
            raise FormatError(f"cannot read {path.name} ({exc.strerror or exc})") from exc
        # offset: the file's first byte in the log plus the message's index in it, so that the recorder maps
        # each message to its file (a message takes more than one byte) for a split bag's gap report
        last = max(size - 1, 0)
        for m in rb.read_bag(path, types, own, first if path is files[0] else None):
            number += 1
            where = _where(start + (m.index if m.index < last else last), m.bag_time_ns, number)
            if m.problem or not m.topic:   # neither itself nor ours: refused, with the reason
                yield from raw.flush()
                yield Reject(where, f"{m.topic} ({m.msgtype}): {m.problem}" if m.topic else m.problem)
            else:
                item = raw.output(m, where)
                if item is not None:   # not in its topic's batch
                    yield from raw.released(iter((item,)))
                items = bag.take(m, where)
                if items is not None:
                    yield from raw.released(items)
            if bag.due(number):
                yield from raw.released(bag.flush())
            if raw.due(number):
                yield from raw.flush()
        start += size
    yield from raw.released(bag.finish())
    yield from raw.flush()
    note = raw.note(ctx.path or files[0].name, Where(0))
    if note is not None:
        yield note


# types read from their bytes (rosbags decodes a bag whose definition differs, or bytes these do not read): the Imu
# converted a batch at a time, Odometry and NavSatFix one by one from their numbers, TFMessage only checked
OWN: dict[str, rb.OwnReader] = {
    ros_imu.MSGTYPE: (ros_imu.STANDARD, ros_imu.header),
    ros_standard.ODOMETRY: (ros_standard.STANDARD[ros_standard.ODOMETRY], ros_standard.odometry),
    ros_standard.NAVSATFIX: (ros_standard.STANDARD[ros_standard.NAVSATFIX], ros_standard.navsatfix),
    ros_standard.TF: (ros_standard.STANDARD[ros_standard.TF], ros_standard.transforms),
}


def _topics(path: Path) -> list[tuple[str, str]]:
    """A bag file's topics and types, or none when it does not open (reading it then says why)."""
    try:
        return rb.bag_topics(path)
    except FormatError:
        return []


MANIFEST_EXAMPLE = """[[vehicles.logs]]
format = "rosbag"                  # ROS 1 .bag, or a ROS 2 bag folder (.mcap or .db3 storage)
path = "auv1/dive3/"
# msg_paths = ["auv1/msgs"]        # .msg/.idl files (or folders) for custom types the bag does not define
origin = [45.70, 126.60]           # datum of the bag's local (odom/map) frame, for Odometry positions
# time_base = "sim"                # a bag in simulated time: start is the UTC instant of its time 0
# start = "2024-05-01T10:00:00Z"   # (docs/time-bases.md)

[vehicles.logs.topics]             # optional: topic -> sensor (else by message type); others are not mapped
"/gps/fix" = "gps"
"/nmea" = "gps:nmea"               # raw sentences: family and vendor format
"/phins/raw" = "ins:phins"
"/odometry/filtered" = "ins"
"/dvl/twist" = "dvl"
"/buddy/fix" = { sensor = "gps", vehicle = "follower" }
"""

CONVERTERS: dict[str, Converter] = {"rosbag": convert_rosbag}
# the formats whose logs are (or may be) binary: read as bytes, never cut into lines (`recorders.registry`)
BINARY_FORMATS = frozenset({"rosbag"})
