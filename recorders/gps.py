"""GNSS logs into ``/<vehicle>/gps`` (foxglove.LocationFix) and ``/<vehicle>/gps/status``.

Epochs. A receiver writes several sentences per fix (GGA, RMC, GST, VTG...)
and the order varies between receivers (GST often comes after GGA). The
converter therefore groups consecutive records into epochs before emitting
(`group_epochs`): a record joins the open epoch unless its sentence type is
already in it or it carries a time of day different from the epoch's.
Records without a time (VTG, HDT, THS) join the epoch they arrive in. Each
epoch gives at most one LocationFix and one GnssStatus; a duplicated or
out-of-order epoch is kept as it is, never merged or reordered.

Position. GGA, else GLL (status A), else RMC (status A); never two fixes per
epoch. GGA quality 0 or an empty position gives a GnssStatus but no fix.
Altitude is the ellipsoidal height (MSL altitude plus geoid separation) when
the separation is given, else the MSL altitude; NovAtel likewise.

Covariance (ENU, m²). GST of the same epoch: diag(lon σ², lat σ², alt σ²),
DIAGONAL_KNOWN; NovAtel BESTPOS σ the same way. Else, from GGA's HDOP:
horizontal σ = HDOP × UERE split equally on east and north
(σ_E² = σ_N² = (HDOP·UERE)²/2), vertical σ = 2·HDOP·UERE (VDOP is not in
GGA; about twice HDOP is typical), APPROXIMATED. UERE depends on the fix
quality (`UERE_M`) unless the log's manifest entry sets ``uere_m``. Else
NaN and UNKNOWN.

Time. NMEA time of day plus the date of the last RMC/ZDA (or the manifest's
trial date), with midnight rollover (`recorders.clock.DayClock`); an epoch
with no time of its own takes the host-timestamp prefix; NovAtel GPS
week/seconds go through the leap-second table. The log's clock offset is
added to all of them. A time of day without any date is rejected.
"""

from __future__ import annotations

import math
from typing import Callable, Hashable, Iterable, Iterator, TypeVar

from formats import nmea, nmea_columns, novatel, novatel_scan
from formats.lines import PREFIX_STYLES
from formats import schemas as S
from formats.records import Reject, Where

from . import gps_columns
from .base import NS, Converter, LogContext, Output, output
from .clock import DayClock
from .novatel_epochs import novatel_scan_epochs, novatel_scan_time

R = TypeVar("R")
NAN = float("nan")

# User-equivalent range error (m, 1 sigma) by GGA fix quality, for HDOP-based covariance
UERE_M: dict[int, float] = {1: 4.0, 2: 1.0, 3: 4.0, 4: 0.05, 5: 0.5, 6: 10.0, 7: 4.0, 8: 4.0, 9: 2.0}
DEFAULT_UERE_M = 4.0

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
    """An auvreplay.GnssStatus stamped `t_ns` (ns, UTC)."""
    return S.gnss_status(t_ns, frame_id, fix_quality, satellites, hdop, source_format, speed_mps, course_deg, heading_deg)


def group_epochs(
    items: Iterable[R | Reject], key: Callable[[R], tuple[str, Hashable | None]]
) -> Iterator[list[R] | Reject]:
    """Consecutive records as epochs; `key` gives (kind, time or None). Rejects pass straight through.

    An epoch closes when a record's kind is already in it, or when the
    record has a time and the epoch has a different one.
    """
    epoch: list[R] = []
    kinds: set[str] = set()
    epoch_time: Hashable | None = None
    for item in items:
        if type(item) is Reject:
            yield item
            continue
        kind, t = key(item)  # type: ignore[arg-type]
        if epoch and (kind in kinds or (t is not None and epoch_time is not None and t != epoch_time)):
            yield epoch
            epoch, kinds, epoch_time = [], set(), None
        epoch.append(item)  # type: ignore[arg-type]
        kinds.add(kind)
        if epoch_time is None:
            epoch_time = t
    if epoch:
        yield epoch


def host_time_ns(records: Iterable[object], ctx: LogContext) -> int | None:
    """The first host-timestamp prefix among the records, plus the clock offset."""
    for rec in records:
        host = rec.where.host_time_ns  # type: ignore[attr-defined]
        if host is not None:
            return host + ctx.clock_offset_ns
    return None


# ---------------------------------------------------------------- NMEA

NO_DATE = "no date for time of day {:.3f} s: no RMC/ZDA date yet and no [trial] date in the manifest"
NO_TIME = "no time: the epoch has no timed sentence and no host timestamp"


def nmea_key(rec: nmea.NmeaRecord) -> tuple[str, int | None]:
    """Epoch key of an NMEA record: its sentence type and time of day in ms (None if untimed)."""
    t = getattr(rec, "time_s", NAN)
    return type(rec).__name__, (round(t * 1000) if t == t else None)


def nmea_update_date(by: dict[type, object], clock: DayClock) -> None:
    """Give the clock the date of the epoch's ZDA, else of a valid RMC (an invalid RMC's date may be stale)."""
    for cls in (nmea.Zda, nmea.Rmc):
        rec = by.get(cls)
        if rec is not None and rec.date is not None and (cls is nmea.Zda or rec.valid):  # type: ignore[attr-defined]
            clock.set_date(rec.date, rec.time_s)  # type: ignore[attr-defined]
            return


def nmea_epoch_time(by: dict[type, object], epoch: list, clock: DayClock, ctx: LogContext) -> int | Reject:
    """UTC ns (offset applied) of an NMEA epoch, updating the clock's date; a Reject when unknown."""
    nmea_update_date(by, clock)
    for rec in epoch:
        t = getattr(rec, "time_s", NAN)
        if t == t:
            resolved = clock.resolve(t)
            if resolved is None:
                return Reject(rec.where, NO_DATE.format(t))
            return resolved
    host = host_time_ns(epoch, ctx)
    if host is None:
        return Reject(epoch[0].where, NO_TIME)
    return host


def nmea_position(by: dict[type, object]) -> nmea.Gga | nmea.Gll | nmea.Rmc | None:
    """The epoch's position record: GGA with a fix, else a valid GLL, else a valid RMC."""
    g = by.get(nmea.Gga)
    if g is not None and g.quality != 0 and g.latitude == g.latitude and g.longitude == g.longitude:  # type: ignore[attr-defined]
        return g  # type: ignore[return-value]
    for cls in (nmea.Gll, nmea.Rmc):
        rec = by.get(cls)
        if rec is not None and rec.valid and rec.latitude == rec.latitude and rec.longitude == rec.longitude:  # type: ignore[attr-defined]
            return rec  # type: ignore[return-value]
    return None


def _covariance(by: dict[type, object], ctx: LogContext) -> tuple[tuple[float, ...] | None, int]:
    gst = by.get(nmea.Gst)
    if gst is not None and gst.lat_std_m == gst.lat_std_m and gst.lon_std_m == gst.lon_std_m:  # type: ignore[attr-defined]
        e, n, u = gst.lon_std_m, gst.lat_std_m, gst.alt_std_m  # type: ignore[attr-defined]
        return (e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, u * u), S.COVARIANCE_DIAGONAL_KNOWN
    g = by.get(nmea.Gga)
    if g is not None and g.hdop == g.hdop and g.quality > 0:  # type: ignore[attr-defined]
        uere = float(ctx.options.get("uere_m", UERE_M.get(g.quality, DEFAULT_UERE_M)))  # type: ignore[attr-defined]
        h = g.hdop * uere  # type: ignore[attr-defined]
        return (h * h / 2, 0.0, 0.0, 0.0, h * h / 2, 0.0, 0.0, 0.0, 4 * h * h), S.COVARIANCE_APPROXIMATED
    return None, S.COVARIANCE_UNKNOWN


def nmea_motion(by: dict[type, object]) -> tuple[float, float, float]:
    """Speed over ground (m/s), course (deg true) and heading (deg true) of an epoch, NaN when absent."""
    vtg, rmc = by.get(nmea.Vtg), by.get(nmea.Rmc)
    speed = course = NAN
    if vtg is not None:
        speed, course = vtg.speed_knots * nmea.KNOT_MPS, vtg.course_true_deg  # type: ignore[attr-defined]
    elif rmc is not None and rmc.valid:  # type: ignore[attr-defined]
        speed, course = rmc.speed_knots * nmea.KNOT_MPS, rmc.course_deg  # type: ignore[attr-defined]
    heading = NAN
    hdt, ths = by.get(nmea.Hdt), by.get(nmea.Ths)
    if hdt is not None:
        heading = hdt.heading_deg  # type: ignore[attr-defined]
    elif ths is not None and ths.mode != "V":  # type: ignore[attr-defined]
        heading = ths.heading_deg  # type: ignore[attr-defined]
    return speed, course, heading


def _nmea_outputs(epoch: list, ctx: LogContext, clock: DayClock) -> Iterator[Output | Reject]:
    by = {type(r): r for r in epoch}
    if len(by) == 1 and nmea.Zda in by:
        nmea_update_date(by, clock)  # a date-only epoch: nothing to emit, but the date counts
        return
    t = nmea_epoch_time(by, epoch, clock, ctx)
    if type(t) is Reject:
        yield t
        return
    pos = nmea_position(by)
    where = pos.where if pos is not None else epoch[0].where
    if pos is not None:
        alt = NAN
        if type(pos) is nmea.Gga:
            sep = pos.geoid_separation_m
            alt = pos.altitude_msl_m + sep if sep == sep else pos.altitude_msl_m
        cov, kind = _covariance(by, ctx)
        fix = S.location_fix(t, ctx.vehicle, pos.latitude, pos.longitude, alt, cov, kind)  # type: ignore[arg-type]
        yield output(ctx, "gps", fix, t, where)  # type: ignore[arg-type]
    g = by.get(nmea.Gga)
    speed, course, heading = nmea_motion(by)
    status = gnss_status(
        t, ctx.vehicle, g.quality if g is not None else -1, g.satellites if g is not None else -1,  # type: ignore[arg-type]
        g.hdop if g is not None else NAN, "nmea:" + ",".join(type(r).__name__.upper() for r in epoch),
        speed, course, heading,
    )
    yield output(ctx, "gps/status", status, t, where)  # type: ignore[arg-type]


def convert_nmea_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`convert_nmea` the obvious way, over `nmea.decode` records: the judge of the fast path in tests."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    for epoch in group_epochs(nmea.decode(data, ctx.prefix), nmea_key):
        if type(epoch) is Reject:
            yield epoch
        else:
            yield from _nmea_outputs(epoch, ctx, clock)  # type: ignore[arg-type]


# ---------------------------------------------------------------- NMEA, fast path
# The same epochs and messages as `convert_nmea_reference`, over `nmea.scan`
# tuples (kind, talker, values, offset, line, host): no record or Where objects
# per sentence, one dict per epoch. Value positions follow the record fields.


def _scan_date(epoch: dict[str, nmea.Scanned], clock: DayClock) -> None:
    """`nmea_update_date` on scanned values: ZDA's date, else a valid RMC's."""
    zda = epoch.get("ZDA")
    if zda is not None and zda[2][1] is not None:
        clock.set_date(zda[2][1], zda[2][0])
        return
    rmc = epoch.get("RMC")
    if rmc is not None and rmc[2][1] and rmc[2][6] is not None:
        clock.set_date(rmc[2][6], rmc[2][0])


def _scan_time(epoch: dict[str, nmea.Scanned], clock: DayClock, ctx: LogContext) -> int | Reject:
    """`nmea_epoch_time` on scanned values (the clock's date already updated)."""
    time_index = nmea.TIME_INDEX
    for item in epoch.values():
        i = time_index.get(item[0])
        if i is not None and item[2][i] == item[2][i]:
            resolved = clock.resolve(item[2][i])
            return Reject(Where(*item[3:]), NO_DATE.format(item[2][i])) if resolved is None else resolved
    for item in epoch.values():
        if item[5] is not None:
            return item[5] + ctx.clock_offset_ns
    return Reject(Where(*next(iter(epoch.values()))[3:]), NO_TIME)


def _scan_position(epoch: dict[str, nmea.Scanned]) -> tuple[nmea.Scanned, float, float, float] | None:
    """`nmea_position` on scanned values: (item, latitude, longitude, altitude)."""
    g = epoch.get("GGA")
    if g is not None:
        v = g[2]
        if v[3] != 0 and v[1] == v[1] and v[2] == v[2]:
            return g, v[1], v[2], (v[6] + v[7] if v[7] == v[7] else v[6])
    ll = epoch.get("GLL")
    if ll is not None and ll[2][3] and ll[2][0] == ll[2][0] and ll[2][1] == ll[2][1]:
        return ll, ll[2][0], ll[2][1], NAN
    rmc = epoch.get("RMC")
    if rmc is not None and rmc[2][1] and rmc[2][2] == rmc[2][2] and rmc[2][3] == rmc[2][3]:
        return rmc, rmc[2][2], rmc[2][3], NAN
    return None


def _scan_covariance(epoch: dict[str, nmea.Scanned], ctx: LogContext) -> tuple[tuple[float, ...] | None, int]:
    """`_covariance` on scanned values."""
    gst = epoch.get("GST")
    if gst is not None and gst[2][5] == gst[2][5] and gst[2][6] == gst[2][6]:
        n, e, u = gst[2][5], gst[2][6], gst[2][7]
        return (e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, u * u), S.COVARIANCE_DIAGONAL_KNOWN
    g = epoch.get("GGA")
    if g is not None and g[2][5] == g[2][5] and g[2][3] > 0:
        h = g[2][5] * float(ctx.options.get("uere_m", UERE_M.get(g[2][3], DEFAULT_UERE_M)))
        return (h * h / 2, 0.0, 0.0, 0.0, h * h / 2, 0.0, 0.0, 0.0, 4 * h * h), S.COVARIANCE_APPROXIMATED
    return None, S.COVARIANCE_UNKNOWN


def _scan_motion(epoch: dict[str, nmea.Scanned]) -> tuple[float, float, float]:
    """`nmea_motion` on scanned values."""
    speed = course = heading = NAN
    vtg, rmc = epoch.get("VTG"), epoch.get("RMC")
    if vtg is not None:
        speed, course = vtg[2][2] * nmea.KNOT_MPS, vtg[2][0]
    elif rmc is not None and rmc[2][1]:
        speed, course = rmc[2][4] * nmea.KNOT_MPS, rmc[2][5]
    hdt, ths = epoch.get("HDT"), epoch.get("THS")
    if hdt is not None:
        heading = hdt[2][0]
    elif ths is not None and ths[2][1] != "V":
        heading = ths[2][0]
    return speed, course, heading


def _scan_outputs(
    epoch: dict[str, nmea.Scanned], ctx: LogContext, clock: DayClock, topics: tuple[str, str],
) -> tuple[Output | Reject, ...]:
    """`_nmea_outputs` on scanned values, as a tuple (a generator per epoch costs more than the epoch)."""
    _scan_date(epoch, clock)
    if len(epoch) == 1 and "ZDA" in epoch:
        return ()  # a date-only epoch: nothing to emit, but the date counts
    t = _scan_time(epoch, clock, ctx)
    if type(t) is Reject:
        return (t,)  # type: ignore[return-value]
    pos = _scan_position(epoch)
    source = pos[0] if pos is not None else next(iter(epoch.values()))
    where = Where(source[3], source[4], source[5])
    publish = t if source[5] is None else source[5] + ctx.clock_offset_ns
    g = epoch.get("GGA")
    status = S.gnss_status(
        t, ctx.vehicle, g[2][3] if g is not None else -1, g[2][4] if g is not None else -1,  # type: ignore[arg-type]
        g[2][5] if g is not None else NAN, "nmea:" + ",".join(epoch), *_scan_motion(epoch),
    )
    status_out = Output(topics[1], status, t, publish, where)  # type: ignore[arg-type]
    if pos is None:
        return (status_out,)
    cov, kind = _scan_covariance(epoch, ctx)
    fix = S.location_fix(t, ctx.vehicle, pos[1], pos[2], pos[3], cov, kind)  # type: ignore[arg-type]
    return Output(topics[0], fix, t, publish, where), status_out  # type: ignore[arg-type]


def convert_nmea(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """NMEA 0183 GNSS sentences (GGA, RMC, GLL, GST, VTG, ZDA, HDT, THS; any talker)."""
    if ctx.prefix in PREFIX_STYLES:  # an unknown style raises in `nmea.scan`, as before
        cols = nmea_columns.decode_columns(data)
        outputs = gps_columns.convert_columns(cols, ctx, NO_DATE) if cols is not None else None
        if outputs is not None:
            yield from outputs  # a clean log of the types `nmea_columns` takes: whole-log columns (gps_columns)
            return
    yield from _convert_nmea_lines(data, ctx)


def _convert_nmea_lines(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`convert_nmea` line by line over `nmea.scan`: any log, damaged ones included."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    topics = (f"/{ctx.vehicle}/gps", f"/{ctx.vehicle}/gps/status")
    # `group_epochs` over `nmea.scan`, inline: epochs as {sentence type: scanned tuple} in arrival order
    time_index = nmea.TIME_INDEX
    epoch: dict[str, nmea.Scanned] = {}
    epoch_time: int | None = None
    last_tod, last_ms = NAN, None  # an epoch's sentences repeat its time: one round() per epoch
    for item in nmea.scan(data, ctx.prefix):
        if type(item) is Reject:
            yield item  # type: ignore[misc]
            continue
        kind = item[0]
        i = time_index.get(kind)  # type: ignore[arg-type]
        t = None
        if i is not None:
            tod = item[2][i]  # type: ignore[index]
            if tod == last_tod:
                t = last_ms
            elif tod == tod:
                t = last_ms = round(tod * 1000)
                last_tod = tod
        if epoch and (kind in epoch or (t is not None and epoch_time is not None and t != epoch_time)):
            yield from _scan_outputs(epoch, ctx, clock, topics)
            epoch, epoch_time = {}, None
        epoch[kind] = item  # type: ignore[index,assignment]
        if epoch_time is None:
            epoch_time = t
    if epoch:
        yield from _scan_outputs(epoch, ctx, clock, topics)


# ---------------------------------------------------------------- NovAtel


def novatel_key(rec: novatel.NovatelRecord) -> tuple[str, tuple[int, int]]:
    """Epoch key of a NovAtel record: its log and GPS time in ms."""
    week, sow = (rec.week, rec.seconds) if isinstance(rec, novatel.InsPva) else (rec.header.week, rec.header.seconds)
    return type(rec).__name__, (week, round(sow * 1000) if math.isfinite(sow) else -1)


def novatel_time(epoch: list, ctx: LogContext) -> int | Reject:
    """UTC ns (offset applied) of a NovAtel epoch from its GPS time, else the host time."""
    t = novatel.record_time_ns(epoch[0])
    if t is not None:
        return t + ctx.clock_offset_ns
    host = host_time_ns(epoch, ctx)
    if host is None:
        return Reject(epoch[0].where, "no time: GPS week 0 or unknown time status, and no host timestamp")
    return host


def _source(rec: novatel.NovatelRecord) -> str:
    h = rec.header
    return h.message + ("B" if h.encoding.startswith("binary") else "A")


def _novatel_outputs(epoch: list, ctx: LogContext) -> Iterator[Output | Reject]:
    t = novatel_time(epoch, ctx)
    if type(t) is Reject:
        yield t
        return
    by = {type(r): r for r in epoch}
    bp: novatel.BestPos | None = by.get(novatel.BestPos)  # type: ignore[assignment]
    bv: novatel.BestVel | None = by.get(novatel.BestVel)  # type: ignore[assignment]
    where = epoch[0].where
    if bp is not None and bp.solution_status == "SOL_COMPUTED" and bp.position_type != "NONE":
        u = bp.undulation_m
        alt = bp.height_msl_m + u if u == u else bp.height_msl_m
        e, n, h = bp.lon_std_m, bp.lat_std_m, bp.height_std_m
        cov = (e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, h * h)
        fix = S.location_fix(t, ctx.vehicle, bp.latitude, bp.longitude, alt, cov, S.COVARIANCE_DIAGONAL_KNOWN)
        yield output(ctx, "gps", fix, t, bp.where)  # type: ignore[arg-type]
        where = bp.where
    speed = course = NAN
    if bv is not None and bv.solution_status == "SOL_COMPUTED":
        speed, course = bv.horizontal_speed_mps, bv.track_deg
    status = gnss_status(
        t, ctx.vehicle, NOVATEL_QUALITY.get(bp.position_type, -1) if bp is not None else -1,  # type: ignore[arg-type]
        bp.satellites_used if bp is not None else -1, NAN, "novatel:" + ",".join(_source(r) for r in epoch),
        speed, course, NAN,
    )
    yield output(ctx, "gps/status", status, t, where)  # type: ignore[arg-type]


def convert_novatel_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`convert_novatel` the obvious way, over `novatel.decode` records: the judge of the fast path in tests."""
    records = (r for r in novatel.decode(data, ctx.prefix) if isinstance(r, (Reject, novatel.BestPos, novatel.BestVel)))
    for epoch in group_epochs(records, novatel_key):
        if type(epoch) is Reject:
            yield epoch
        else:
            yield from _novatel_outputs(epoch, ctx)  # type: ignore[arg-type]


# ---------------------------------------------------------------- NovAtel, fast path
# The same epochs and messages as `convert_novatel_reference`, over scanned
# tuples grouped by `novatel_epochs`: one dict per epoch, no records.


def _novatel_scan_outputs(epoch: dict[str, novatel_scan.Scanned], ctx: LogContext, topics: tuple[str, str]
                          ) -> tuple[Output | Reject, ...]:
    """`_novatel_outputs` on scanned values, as a tuple."""
    t = novatel_scan_time(epoch, ctx)
    if type(t) is Reject:
        return (t,)  # type: ignore[return-value]
    bp, bv = epoch.get("BestPos"), epoch.get("BestVel")
    where_item = next(iter(epoch.values()))
    out: list[Output | Reject] = []
    if bp is not None and bp[4][0] == "SOL_COMPUTED" and bp[4][1] != "NONE":
        v = bp[4]
        alt = v[4] + v[5] if v[5] == v[5] else v[4]
        e, n, h = v[8], v[7], v[9]
        cov = (e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, h * h)
        fix = S.location_fix(t, ctx.vehicle, v[2], v[3], alt, cov, S.COVARIANCE_DIAGONAL_KNOWN)  # type: ignore[arg-type]
        out.append(Output(topics[0], fix, t, t if bp[7] is None else bp[7] + ctx.clock_offset_ns, Where(*bp[5:])))  # type: ignore[arg-type]
        where_item = bp
    speed = course = NAN
    if bv is not None and bv[4][0] == "SOL_COMPUTED":
        speed, course = bv[4][4], bv[4][5]
    status = S.gnss_status(
        t, ctx.vehicle, NOVATEL_QUALITY.get(bp[4][1], -1) if bp is not None else -1,  # type: ignore[arg-type]
        bp[4][14] if bp is not None else -1, NAN, "novatel:" + ",".join([item[1] for item in epoch.values()]),
        speed, course, NAN,
    )
    host = where_item[7]
    out.append(Output(topics[1], status, t, t if host is None else host + ctx.clock_offset_ns, Where(*where_item[5:])))  # type: ignore[arg-type]
    return tuple(out)


_GNSS_KINDS = frozenset(("BestPos", "BestVel"))


def convert_novatel(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """NovAtel BESTPOS/BESTVEL logs, ASCII (long or short header) or binary."""
    topics = (f"/{ctx.vehicle}/gps", f"/{ctx.vehicle}/gps/status")
    for epoch in novatel_scan_epochs(data, ctx, _GNSS_KINDS):
        if type(epoch) is Reject:
            yield epoch  # type: ignore[misc]
        else:
            yield from _novatel_scan_outputs(epoch, ctx, topics)  # type: ignore[arg-type]


CONVERTERS: dict[str, Converter] = {"nmea": convert_nmea, "novatel": convert_novatel}
