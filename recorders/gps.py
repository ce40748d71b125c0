"""GNSS logs into ``/<vehicle>/gps`` (foxglove.LocationFix), ``/<vehicle>/gps/status`` and ``/<vehicle>/gps/velocity``.

Epochs. A receiver writes several sentences per fix (GGA, RMC, GST, VTG...)
and the order varies between receivers (GST often comes after GGA). The
converter therefore groups consecutive records into epochs before emitting
(`recorders.epochs.group_epochs`' rule): a record joins the open epoch unless its sentence type is
already in it or it carries a time of day different from the epoch's.
Records without a time (VTG, HDT, THS) join the epoch they arrive in. Each
epoch gives at most one LocationFix and one GnssStatus; a duplicated or
out-of-order epoch is kept as it is, never merged or reordered.

Position. GGA, else GLL (status A), else RMC (status A); never two fixes per
epoch. GGA quality 0 or an empty position gives a GnssStatus but no fix.
Altitude is the ellipsoidal height (MSL altitude plus geoid separation) when
the separation is given, else the MSL altitude; NovAtel likewise.

Covariance (ENU, m²): `recorders.gnss_covariance` (GST sigmas, else HDOP
times the UERE, else unknown); NovAtel BESTPOS sigmas as GST's.

Time. NMEA time of day plus the date of the last RMC/ZDA (or the manifest's
trial date), with midnight rollover (`recorders.clock.DayClock`); an epoch
with no time of its own takes the host-timestamp prefix; NovAtel GPS
week/seconds go through the leap-second table. The log's clock offset is
added to all of them. A time of day without any date is rejected.

Velocity. An epoch's speed and course over ground (`nmea_epochs.nmea_motion`: a
valid VTG, else an RMC with status A; NovAtel BESTVEL) give a GnssVelocity
stamped and placed like its fix (`recorders.gnss_velocity`); an NMEA epoch
whose VTG/RMC gives no speed and course yields an `Ignored` saying so.
Every line of an NMEA log is counted into the context's `counts`
(`formats.nmea.counts`), by the scan or the columns, whichever read it.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterable, Iterator
from math import isnan
from typing import Any, NamedTuple

import numpy as np

from formats import schemas as S
from formats.lines import PREFIX_STYLES
from formats.log_blocks import Block, blocks_of
from formats.nmea import columns as nmea_columns
from formats.nmea import sentences as nmea
from formats.nmea.sentences import KNOT_MPS
from formats.novatel import columns as novatel_columns
from formats.novatel import scan as novatel_scan
from formats.records import Reject, Where

from . import gps_columns
from .base import (
    ROWS_PER_BATCH,
    Batch,
    BlockConverter,
    Columns,
    Converter,
    Ignored,
    LogContext,
    Output,
    batched,
    int64_times,
)
from .clock import DayClock
from .gnss_covariance import Covariance, fix_covariance, sigma_covariance
from .gnss_velocity import NO_VELOCITY, components, components_column, gnss_velocity
from .gnss_velocity import SUFFIX as VELOCITY
from .nmea_epochs import NO_DATE, NO_TIME, vtg_speed, vtg_valid
from .novatel_epochs import (
    ColumnEpochs,
    chunks,
    epoch_member,
    novatel_column_path,
    novatel_publish_ns,
    novatel_scan_epochs,
    novatel_scan_time,
    scanned_epochs,
)

NAN = math.nan

# NovAtel position type -> GGA-style fix quality (NovAtel's own GPGGA mapping)
NOVATEL_QUALITY: dict[str, int] = {
    "NONE": 0, "SINGLE": 1, "INS_PSRSP": 1, "PSRDIFF": 2, "WAAS": 2, "INS_SBAS": 2, "INS_PSRDIFF": 2,
    "L1_INT": 4, "WIDE_INT": 4, "NARROW_INT": 4, "INS_RTKFIXED": 4, "RTK_DIRECT_INS": 4,
    "L1_FLOAT": 5, "IONOFREE_FLOAT": 5, "NARROW_FLOAT": 5, "INS_RTKFLOAT": 5, "PPP_CONVERGING": 5,
    "PPP": 5, "INS_PPP": 5, "INS_PPP_CONVERGING": 5, "PPP_BASIC": 5, "PPP_BASIC_CONVERGING": 5,
    "PROPAGATED": 6, "FIXEDPOS": 7,
}


def gnss_status(
    t_ns: int, frame_id: str, fix_quality: int, satellites: int, hdop: float, source_format: str,
    speed_mps: float, course_deg: float, heading_deg: float,
) -> S.GnssStatus:
    """An auvreplay.GnssStatus stamped `t_ns` (ns, UTC); a quality or satellite count no int32 holds is -1 (unknown)."""
    return S.gnss_status(t_ns, frame_id, _int32(fix_quality), _int32(satellites), hdop, source_format, speed_mps,
                         course_deg, heading_deg)


def _int32(value: int) -> int:
    return value if -2**31 <= value < 2**31 else -1


# ---------------------------------------------------------------- NMEA, fast path
# The same epochs and messages as tests/reference_converters.py's `convert_nmea_reference`, over `nmea.scan`
# tuples (kind, talker, values, offset, line, host): no record or Where objects
# per sentence, one dict per epoch. Value positions follow the record fields.


def _scan_date(epoch: dict[str, nmea.Scanned], clock: DayClock) -> None:
    """`nmea_update_date` on scanned values: ZDA's date, else a valid RMC's."""
    zda = epoch.get("ZDA")
    if zda is not None:
        time_s, day, _, _ = zda[2]
        if day is not None:
            clock.set_date(day, time_s)
            return
    rmc = epoch.get("RMC")
    if rmc is not None:
        time_s, valid, _, _, _, _, day, _, _ = rmc[2]
        if valid and day is not None:
            clock.set_date(day, time_s)


def _scan_time(epoch: dict[str, nmea.Scanned], clock: DayClock, ctx: LogContext) -> int | Reject:
    """`nmea_epoch_time` on scanned values (the clock's date already updated)."""
    time_index = nmea.TIME_INDEX
    for kind, _, values, offset, line, host in epoch.values():
        i = time_index.get(kind)
        if i is not None and not isnan(values[i]):
            resolved = clock.resolve(values[i])
            return Reject(Where(offset, line, host), NO_DATE.format(values[i])) if resolved is None else resolved
    for item in epoch.values():
        host = item[5]
        if host is not None:
            return host + ctx.clock_offset_ns
    _, _, _, offset, line, host = next(iter(epoch.values()))
    return Reject(Where(offset, line, host), NO_TIME)


def _scan_position(epoch: dict[str, nmea.Scanned]) -> tuple[nmea.Scanned, float, float, float] | None:
    """`nmea_position` on scanned values: (item, latitude, longitude, altitude)."""
    g = epoch.get("GGA")
    if g is not None:
        _, lat, lon, quality, _, _, msl, sep, _, _ = g[2]
        if quality != 0 and not (isnan(lat) or isnan(lon)):
            return g, lat, lon, (msl if isnan(sep) else msl + sep)
    ll = epoch.get("GLL")
    if ll is not None:
        lat, lon, _, valid, _ = ll[2]
        if valid and not (isnan(lat) or isnan(lon)):
            return ll, lat, lon, NAN
    rmc = epoch.get("RMC")
    if rmc is not None:
        _, valid, lat, lon, _, _, _, _, _ = rmc[2]
        if valid and not (isnan(lat) or isnan(lon)):
            return rmc, lat, lon, NAN
    return None


def _scan_covariance(epoch: dict[str, nmea.Scanned], ctx: LogContext) -> Covariance:
    """`fix_covariance` of scanned values."""
    lat_std = lon_std = alt_std = hdop = NAN
    quality = -1
    gst = epoch.get("GST")
    if gst is not None:
        _, _, _, _, _, lat_std, lon_std, alt_std = gst[2]
    g = epoch.get("GGA")
    if g is not None:
        _, _, _, quality, _, hdop, _, _, _, _ = g[2]
    return fix_covariance(lat_std, lon_std, alt_std, hdop, quality, ctx.options)


def _scan_motion(epoch: dict[str, nmea.Scanned]) -> tuple[float, float, float]:
    """`nmea_motion` on scanned values."""
    speed = course = heading = NAN
    vtg, rmc = epoch.get("VTG"), epoch.get("RMC")
    if vtg is not None and vtg_valid(vtg[2][4]):
        course, _, knots, kmh, _ = vtg[2]
        speed = vtg_speed(knots, kmh)
    elif rmc is not None:
        _, valid, _, _, knots, course_deg, _, _, _ = rmc[2]
        if valid:
            speed, course = knots * KNOT_MPS, course_deg
    hdt, ths = epoch.get("HDT"), epoch.get("THS")
    if hdt is not None:
        (heading,) = hdt[2]
    elif ths is not None:
        heading_deg, mode = ths[2]
        if mode != "V":
            heading = heading_deg
    return speed, course, heading


def _scan_outputs(
    epoch: dict[str, nmea.Scanned], ctx: LogContext, clock: DayClock, topics: tuple[str, str, str],
) -> tuple[Output | Reject | Ignored, ...]:
    """`_nmea_outputs` on scanned values, as a tuple (a generator per epoch costs more than the epoch)."""
    _scan_date(epoch, clock)
    if len(epoch) == 1 and "ZDA" in epoch:
        return ()  # a date-only epoch: nothing to emit, but the date counts
    t = _scan_time(epoch, clock, ctx)
    if isinstance(t, Reject):
        return (t,)
    pos = _scan_position(epoch)
    _, _, _, offset, line, host = pos[0] if pos is not None else next(iter(epoch.values()))
    where = Where(offset, line, host)
    publish = t if host is None else host + ctx.clock_offset_ns
    quality, satellites, hdop = -1, -1, NAN
    g = epoch.get("GGA")
    if g is not None:
        _, _, _, quality, satellites, hdop, _, _, _, _ = g[2]
    source = "nmea:" + ",".join(epoch)
    speed, course, heading = _scan_motion(epoch)
    status = gnss_status(t, ctx.vehicle, quality, satellites, hdop, source, speed, course, heading)
    out: tuple[Output | Reject | Ignored, ...] = (Output(topics[1], status, t, publish, where),)
    if pos is not None:
        cov, kind = _scan_covariance(epoch, ctx)
        fix = S.location_fix(t, ctx.vehicle, pos[1], pos[2], pos[3], cov, kind)
        out = (Output(topics[0], fix, t, publish, where), *out)
    if speed - speed == 0.0 and course - course == 0.0:  # both finite: inf - inf and NaN - NaN are NaN
        north, east = components(speed, course)
        velocity = S.gnss_velocity(t, ctx.vehicle, north, east, NAN, speed, course, NAN, source)
        return (*out, Output(topics[2], velocity, t, publish, where))
    if "VTG" in epoch or "RMC" in epoch:
        return (*out, Ignored(where, NO_VELOCITY))
    return out


def convert_nmea(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
    """NMEA 0183 GNSS sentences (GGA, RMC, GLL, GST, VTG, ZDA, HDT, THS; any talker)."""
    return convert_nmea_blocks(blocks_of(data), ctx)


class _NmeaState:
    """What goes on from one block of an NMEA log to the next: the day clock and the epoch still open."""

    __slots__ = ("clock", "topics", "epoch", "epoch_time")

    def __init__(self, ctx: LogContext):
        self.clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
        self.topics = (f"/{ctx.vehicle}/gps", f"/{ctx.vehicle}/gps/status", f"/{ctx.vehicle}/{VELOCITY}")
        self.epoch: dict[str, nmea.Scanned] = {}  # {sentence type: scanned tuple} in arrival order
        self.epoch_time: int | None = None


def convert_nmea_blocks(blocks: Iterable[Block], ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
    """`convert_nmea` over a log read in blocks (`formats.log_blocks`): the same outputs, one block in memory.

    A clean block takes the whole-block columns (`gps_columns`), any other the
    per-line path; the epoch that may go on in the next block is held open
    (as scanned sentences) and the clock's date carried, so the epochs are
    the whole log's wherever the blocks are cut.
    """
    state = _NmeaState(ctx)
    columns = ctx.prefix in PREFIX_STYLES  # an unknown style raises in `nmea.scan`, as before
    blocks = iter(blocks)
    block = next(blocks, None)
    while block is not None:
        following = next(blocks, None)
        yield from _nmea_block(block, following is None, ctx, state, columns)
        block = following
    if state.epoch:
        yield from _scan_outputs(state.epoch, ctx, state.clock, state.topics)


def _nmea_block(block: Block, last: bool, ctx: LogContext, state: _NmeaState, columns: bool
                ) -> Iterator[Output | Reject | Ignored | Batch]:
    """One block's outputs; the epoch still open at its end (unless `last`) is left in `state`."""
    data, base, lines = block.data, block.offset, block.lines
    counts = ctx.counts
    if state.epoch:  # the previous block's last epoch: line by line until a sentence closes it
        items = nmea.scan(data, ctx.prefix, base, lines, counts)
        closed = yield from _nmea_lines(items, ctx, state, until_closed=True)
        items.close()  # its lines counted up to the sentence that closed the epoch, which is read on from
        if closed is None:
            return
        start = closed[0] - base
        data, base, lines = data[start:], closed[0], closed[1] - 1
    cols = nmea_columns.decode_columns(data) if columns else None
    k = None if cols is None or last else gps_columns.last_epoch_start(cols)
    if cols is not None and last:  # a clean log of the types `nmea_columns` takes: columns to its end
        outputs = gps_columns.convert_columns(cols, ctx, NO_DATE, state.clock, base, lines)
        if outputs is not None:
            nmea_columns.count_sentences(cols, counts)
            yield from outputs
            return
    elif cols is not None and k is not None:  # columns up to the last epoch, which the next block may go on
        if k:
            outputs = gps_columns.convert_columns(nmea_columns.head(cols, k), ctx, NO_DATE, state.clock, base, lines)
            assert outputs is not None  # a head of columns that have epochs has them too
            yield from outputs
        tail, number = int(cols.offsets[k]), int(cols.numbers[k])
        nmea_columns.count_sentences(cols, counts, number)
        data, base, lines = data[tail:], base + tail, lines + number - 1
    yield from _nmea_lines(nmea.scan(data, ctx.prefix, base, lines, counts), ctx, state)


def _nmea_lines(items: Iterator[nmea.Scanned | Reject], ctx: LogContext, state: _NmeaState,
                until_closed: bool = False) -> Generator[Output | Reject | Ignored, None, tuple[int, int] | None]:
    """`convert_nmea` line by line over `nmea.scan` items: any log, damaged ones included.

    The epoch still open at the end is left in `state`. With `until_closed`, it
    stops at the sentence that closes the epoch open at the start, and returns
    that sentence's (offset, line), not taken: the caller goes on from there.
    """
    clock, topics = state.clock, state.topics
    # `group_epochs` over `nmea.scan`, inline: epochs as {sentence type: scanned tuple} in arrival order
    time_index = nmea.TIME_INDEX
    epoch, epoch_time = state.epoch, state.epoch_time
    last_tod, last_ms = NAN, None  # an epoch's sentences repeat its time: one round() per epoch
    for item in items:
        if isinstance(item, Reject):
            yield item
            continue
        kind = item[0]
        i = time_index.get(kind)
        t = None
        if i is not None:
            tod = item[2][i]
            if tod == last_tod:
                t = last_ms
            elif not isnan(tod):
                t = last_ms = round(tod * 1000)
                last_tod = tod
        if epoch and (kind in epoch or (t is not None and epoch_time is not None and t != epoch_time)):
            yield from _scan_outputs(epoch, ctx, clock, topics)
            epoch, epoch_time = {}, None
            if until_closed:
                state.epoch, state.epoch_time = epoch, epoch_time
                number = item[4]
                assert number is not None  # `nmea.scan` numbers every line
                return item[3], number
        epoch[kind] = item
        if epoch_time is None:
            epoch_time = t
    state.epoch, state.epoch_time = epoch, epoch_time
    return None


# ---------------------------------------------------------------- NovAtel, fast path
# The same epochs and messages as tests/reference_converters.py's `convert_novatel_reference`, over scanned
# tuples grouped by `novatel_epochs`: one dict per epoch, no records.


class _NovatelEpoch(NamedTuple):
    """What one epoch's fix, status and velocity are made of: the one rule both paths build from."""

    t: int
    fix: tuple[int, float, float, float, tuple[float, ...] | None, int, novatel_scan.Scanned] | None
    """publish, latitude, longitude, altitude, covariance, its kind, the BESTPOS item (None: no fix)"""
    status: tuple[int, int, int, str, float, float, novatel_scan.Scanned]
    """publish, quality, satellites, source, speed, course, the item it is stamped from"""
    velocity: tuple[int, float, float, float, novatel_scan.Scanned] | None
    """publish, speed, track, vertical speed, the BESTVEL item (None: no velocity)"""


def _novatel_epoch(epoch: dict[str, novatel_scan.Scanned], ctx: LogContext) -> _NovatelEpoch | Reject:
    """One epoch's messages as values: a fix from a computed BESTPOS, a status always, a velocity from a
    computed BESTVEL; or the epoch's time Reject."""
    t = novatel_scan_time(epoch, ctx)
    if isinstance(t, Reject):
        return t
    bp, bv = epoch.get("BestPos"), epoch.get("BestVel")
    where_item = next(iter(epoch.values()))
    fix = None
    quality = satellites = -1
    if bp is not None:
        pos = novatel_scan.BEST_POS._make(bp[4])
        quality, satellites = NOVATEL_QUALITY.get(pos.position_type, -1), pos.satellites_used
        if pos.solution_status == "SOL_COMPUTED" and pos.position_type != "NONE":
            u = pos.undulation_m
            alt = pos.height_msl_m if isnan(u) else pos.height_msl_m + u
            cov, kind = sigma_covariance(pos.lat_std_m, pos.lon_std_m, pos.height_std_m)
            fix = (novatel_publish_ns(bp, t, ctx), pos.latitude, pos.longitude, alt, cov, kind, bp)
            where_item = bp
    speed = course = NAN
    source = "novatel:" + ",".join([item[1] for item in epoch.values()])
    velocity = None
    if bv is not None:
        vel = novatel_scan.BEST_VEL._make(bv[4])
        if vel.solution_status == "SOL_COMPUTED":
            speed, course = vel.horizontal_speed_mps, vel.track_deg
            velocity = (novatel_publish_ns(bv, t, ctx), speed, course, vel.vertical_speed_mps, bv)
    status = (novatel_publish_ns(where_item, t, ctx), quality, satellites, source, speed, course, where_item)
    return _NovatelEpoch(t, fix, status, velocity)


def _novatel_scan_outputs(epoch: dict[str, novatel_scan.Scanned], ctx: LogContext, topics: tuple[str, str, str]
                          ) -> tuple[Output | Reject, ...]:
    """`_novatel_outputs` on scanned values, as a tuple."""
    e = _novatel_epoch(epoch, ctx)
    if isinstance(e, Reject):
        return (e,)
    t, out = e.t, []
    if e.fix is not None:
        publish, lat, lon, alt, cov, kind, bp = e.fix
        out.append(Output(topics[0], S.location_fix(t, ctx.vehicle, lat, lon, alt, cov, kind), t, publish,
                          novatel_scan.where_of(bp)))
    publish, quality, satellites, source, speed, course, item = e.status
    out.append(Output(topics[1], gnss_status(t, ctx.vehicle, quality, satellites, NAN, source, speed, course, NAN),
                      t, publish, novatel_scan.where_of(item)))
    if e.velocity is not None:
        publish, speed, course, up, bv = e.velocity
        out.append(Output(topics[2], novatel_velocity(ctx, t, source, speed, course, up), t, publish,
                          novatel_scan.where_of(bv)))
    return tuple(out)


def novatel_velocity(ctx: LogContext, t_ns: int, source: str, speed: float, track_deg: float,
                     vertical_mps: float) -> S.GnssVelocity:
    """A BESTVEL's velocity over ground (horizontal speed along the track, vertical speed up)."""
    return gnss_velocity(ctx, t_ns, source, speed=speed, course=track_deg, up=vertical_mps)


_GNSS_KINDS = frozenset(("BestPos", "BestVel"))


def convert_novatel(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
    """NovAtel BESTPOS/BESTVEL logs, ASCII (long or short header) or binary.

    For a consumer of batches a clean file takes the column path (`_novatel_column_batches`), any other the
    per-line one."""
    resume = yield from novatel_column_path(data, ctx, _GNSS_KINDS, _novatel_column_batches)
    if resume is None:
        return
    rows = _NovatelRows(ctx)
    for epoch in novatel_scan_epochs(data, ctx, _GNSS_KINDS, resume):
        reject = epoch if isinstance(epoch, Reject) else rows.add(epoch)
        if reject is not None or rows.full:
            yield from batched(ctx, rows.take())
            if reject is not None:
                yield reject
    yield from batched(ctx, rows.take())


class _NovatelRows:
    """Epochs' fix, status and velocity as rows of their builders' arguments (what `_novatel_scan_outputs` would
    build), taken as one Batch whose items one by one are that function's outputs of the same epochs."""

    def __init__(self, ctx: LogContext):
        self.ctx = ctx
        self.topics = (f"/{ctx.vehicle}/gps", f"/{ctx.vehicle}/gps/status", f"/{ctx.vehicle}/{VELOCITY}")
        self.epochs: list[dict[str, novatel_scan.Scanned]] = []
        self.order: list[int] = []  # per message, its topic: 0 fix, 1 status, 2 velocity
        self.keys: list[int] = []   # per message, its record's byte offset
        self.last: Where = Where(0)
        self.parts: tuple[list, list, list] = ([], [], [])  # per topic: (t, publish, builder arguments...) rows

    @property
    def full(self) -> bool:
        """Whether the rows should be taken now."""
        return len(self.order) >= ROWS_PER_BATCH

    def add(self, epoch: dict[str, novatel_scan.Scanned]) -> Reject | None:
        """One epoch's messages as rows (`_novatel_epoch`'s values, as `_novatel_scan_outputs` builds them), or
        its Reject."""
        e = _novatel_epoch(epoch, self.ctx)
        if isinstance(e, Reject):
            return e
        t = e.t
        fix, status, velocity = self.parts
        if e.fix is not None:
            publish, lat, lon, alt, cov, kind, bp = e.fix
            fix.append((t, publish, lat, lon, alt, cov, kind))
            self.order.append(0)
            self.keys.append(bp[5])
        publish, quality, satellites, source, speed, course, item = e.status
        status.append((t, publish, quality, satellites, source, speed, course))
        self.order.append(1)
        self.keys.append(item[5])
        self.last = novatel_scan.where_of(item)
        if e.velocity is not None:
            publish, speed, course, up, bv = e.velocity
            # `gnss_velocity`'s components: from the speed and course when both are finite
            north, east = components(speed, course) if math.isfinite(speed) and math.isfinite(course) \
                else (NAN, NAN)
            velocity.append((t, publish, north, east, up, speed, course, source))
            self.order.append(2)
            self.keys.append(bv[5])
            self.last = novatel_scan.where_of(bv)
        self.epochs.append(epoch)
        return None

    def take(self) -> Batch | None:
        """The rows so far as one Batch (None without any), and a fresh start."""
        if not self.order:
            return None
        ctx, topics, epochs = self.ctx, self.topics, self.epochs
        fix, status, velocity = self.parts
        order, keys, last = self.order, self.keys, self.last
        self.epochs, self.order, self.keys, self.parts = [], [], [], ([], [], [])

        def outputs() -> Iterator[Output | Reject | Ignored]:
            for epoch in epochs:
                yield from _novatel_scan_outputs(epoch, ctx, topics)

        times = [int64_times([r[0] for r in rows]) if rows else np.zeros(0, dtype=np.int64) for rows in (
            fix, status, velocity)]
        publish = [int64_times([r[1] for r in rows]) if rows else np.zeros(0, dtype=np.int64) for rows in (
            fix, status, velocity)]
        if any(t is None for t in times + publish):  # a time beyond int64: the messages one by one
            return Batch([], np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), last, outputs, one_by_one=True)
        vehicle = ctx.vehicle
        f: list[tuple] = list(zip(*fix)) if fix else [()] * 7
        st: list[tuple] = list(zip(*status))
        v: list[tuple] = list(zip(*velocity)) if velocity else [()] * 8
        columns: tuple[dict[str, Any], ...] = (
            {"timestamp": times[0], "frame_id": vehicle, "latitude": np.array(f[2], dtype=np.float64),
             "longitude": np.array(f[3], dtype=np.float64), "altitude": np.array(f[4], dtype=np.float64),
             "position_covariance": np.array(f[5], dtype=np.float64).reshape(-1, 9),
             "position_covariance_type": np.array(f[6], dtype=np.int64)},
            {"timestamp": times[1], "frame_id": vehicle, "fix_quality": np.array(st[2], dtype=np.int64),
             "satellites": np.array(st[3], dtype=np.int64), "hdop": NAN, "source_format": list(st[4]),
             "speed_over_ground_mps": np.array(st[5], dtype=np.float64),
             "course_over_ground_deg": np.array(st[6], dtype=np.float64), "heading_deg": NAN},
            {"timestamp": times[2], "frame_id": vehicle, "velocity_north_mps": np.array(v[2], dtype=np.float64),
             "velocity_east_mps": np.array(v[3], dtype=np.float64), "velocity_up_mps": np.array(v[4], dtype=np.float64),
             "speed_over_ground_mps": np.array(v[5], dtype=np.float64),
             "course_over_ground_deg": np.array(v[6], dtype=np.float64), "speed_std_mps": NAN,
             "source_format": list(v[7])},
        )
        parts = [Columns(topic, cls, cols, t, p) for topic, cls, cols, t, p in zip(
            topics, (S.LocationFix, S.GnssStatus, S.GnssVelocity), columns, times, publish)]
        return Batch(parts, np.array(order, dtype=np.int64), np.array(keys, dtype=np.int64), last, outputs)


def _novatel_column_batches(cols: novatel_columns.NovatelColumns, epochs: ColumnEpochs, ctx: LogContext
                            ) -> list[tuple[int, Batch]]:
    """The Batches `_NovatelRows` would take of a clean block's epochs, made from its columns at once, each with
    its first epoch; none where the per-line path must decide (a satellite count no int32 holds)."""
    n = len(epochs.starts)
    bp_log, bp_row = epoch_member(epochs, cols, ("BESTPOS",))
    bv_log, bv_row = epoch_member(epochs, cols, ("BESTVEL",))
    has_bp, has_bv = bp_row >= 0, bv_row >= 0
    first_log = epochs.logs[epochs.starts]
    # BESTPOS values per epoch (rows of epochs without one are read from row 0 and masked)
    bp = cols.values.get("BESTPOS")
    quality = np.full(n, -1, dtype=np.int64)
    satellites = np.full(n, -1, dtype=np.int64)
    fix = np.zeros(n, dtype=bool)
    lat = lon = alt = lat_std = lon_std = h_std = np.zeros(n)
    if bp is not None:
        r = bp_row[has_bp]
        status, ptype = [bp[0][i] for i in r.tolist()], [bp[1][i] for i in r.tolist()]
        used = [bp[14][i] for i in r.tolist()]
        if any(not -2**31 <= x < 2**31 for x in used):
            return []
        quality[has_bp] = [NOVATEL_QUALITY.get(p, -1) for p in ptype]
        satellites[has_bp] = used
        fix[has_bp] = [s == "SOL_COMPUTED" and p != "NONE" for s, p in zip(status, ptype)]
        take = np.maximum(bp_row, 0)
        lat, lon, height, und = (bp[k][take] for k in (2, 3, 4, 5))
        alt = np.where(np.isnan(und), height, height + und)
        lat_std, lon_std, h_std = (bp[k][take] for k in (7, 8, 9))
    speed, course, up = np.full(n, NAN), np.full(n, NAN), np.full(n, NAN)
    velocity = np.zeros(n, dtype=bool)
    bv = cols.values.get("BESTVEL")
    if bv is not None:
        r = bv_row[has_bv]
        velocity[has_bv] = [bv[0][i] == "SOL_COMPUTED" for i in r.tolist()]
        take = np.maximum(bv_row, 0)
        speed = np.where(velocity, bv[4][take], NAN)
        course = np.where(velocity, bv[5][take], NAN)
        up = bv[6][take]
    north, east = np.full(n, NAN), np.full(n, NAN)
    both = np.flatnonzero(velocity & np.isfinite(speed) & np.isfinite(course))
    if len(both):
        north[both], east[both] = components_column(speed[both], course[both].tolist())
    sources = _novatel_sources(cols, epochs)
    status_log = np.where(fix, bp_log, first_log)
    counts = 1 + fix.astype(np.int64) + velocity
    ctx_topics = (f"/{ctx.vehicle}/gps", f"/{ctx.vehicle}/gps/status", f"/{ctx.vehicle}/{VELOCITY}")
    vehicle, t = ctx.vehicle, epochs.t_ns
    batches = []
    for a, b in chunks(counts, ROWS_PER_BATCH):
        f, v = np.flatnonzero(fix[a:b]) + a, np.flatnonzero(velocity[a:b]) + a
        c = counts[a:b]
        at = np.cumsum(c) - c  # each epoch's first message in the batch
        order = np.ones(int(c.sum()), dtype=np.int64)
        keys = np.empty(len(order), dtype=np.int64)
        order[at[f - a]] = 0
        keys[at[f - a]] = cols.offsets[bp_log[f]]
        st = at + fix[a:b]
        keys[st] = cols.offsets[status_log[a:b]]
        vel_at = st[v - a] + 1
        order[vel_at] = 2
        keys[vel_at] = cols.offsets[bv_log[v]]
        last_log = bv_log[b - 1] if velocity[b - 1] else status_log[b - 1]
        src = sources[a:b]
        cov = np.zeros((len(f), 9))
        cov[:, 0], cov[:, 4], cov[:, 8] = lon_std[f] * lon_std[f], lat_std[f] * lat_std[f], h_std[f] * h_std[f]
        columns: tuple[dict[str, Any], ...] = (
            {"timestamp": t[f], "frame_id": vehicle, "latitude": lat[f], "longitude": lon[f], "altitude": alt[f],
             "position_covariance": cov,
             "position_covariance_type": np.full(len(f), S.COVARIANCE_DIAGONAL_KNOWN, dtype=np.int64)},
            {"timestamp": t[a:b], "frame_id": vehicle, "fix_quality": quality[a:b], "satellites": satellites[a:b],
             "hdop": NAN, "source_format": src, "speed_over_ground_mps": speed[a:b],
             "course_over_ground_deg": course[a:b], "heading_deg": NAN},
            {"timestamp": t[v], "frame_id": vehicle, "velocity_north_mps": north[v], "velocity_east_mps": east[v],
             "velocity_up_mps": up[v], "speed_over_ground_mps": speed[v], "course_over_ground_deg": course[v],
             "speed_std_mps": NAN, "source_format": [sources[i] for i in v.tolist()]},
        )
        parts = [Columns(topic, cls, cols_, times, times) for topic, cls, cols_, times in zip(
            ctx_topics, (S.LocationFix, S.GnssStatus, S.GnssVelocity), columns, (t[f], t[a:b], t[v]))]

        def outputs(a: int = a, b: int = b) -> Iterator[Output | Reject | Ignored]:
            for epoch in scanned_epochs(cols, epochs, a, b):
                yield from _novatel_scan_outputs(epoch, ctx, ctx_topics)

        batches.append((a, Batch(parts, order, keys, Where(int(cols.offsets[last_log]), int(cols.numbers[last_log])),
                                 outputs)))
    return batches


def _novatel_sources(cols: novatel_columns.NovatelColumns, epochs: Any) -> list[str]:
    """'novatel:BESTPOSA,BESTVELA' per epoch: its logs' names in arrival order."""
    n = len(epochs.starts)
    code = cols.code[epochs.logs]
    first = code[epochs.starts]
    ends = np.append(epochs.starts[1:], len(epochs.logs))
    second = np.where(ends - epochs.starts > 1, code[np.minimum(epochs.starts + 1, len(code) - 1)], -1)
    sig = first * 8 + second + 1  # an epoch holds BESTPOS and BESTVEL at most once each: two logs at most
    names = novatel_columns.NAMES
    table = {s: "novatel:" + ",".join(names[c] + "A" for c in (s // 8, s % 8 - 1) if c >= 0)
             for s in np.unique(sig).tolist()}
    return [table[s] for s in sig.tolist()] if n else []


CONVERTERS: dict[str, Converter] = {"nmea": convert_nmea, "novatel": convert_novatel}
# the formats whose logs are (or may be) binary: read as bytes, never cut into lines (`recorders.registry`)
BINARY_FORMATS = frozenset({"novatel"})  # OEM binary logs, or their ASCII form
# the formats whose logs are converted block by block, in bounded memory (`recorders.base.BlockConverter`)
BLOCK_CONVERTERS: dict[str, BlockConverter] = {"nmea": convert_nmea_blocks}
