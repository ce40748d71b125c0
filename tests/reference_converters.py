"""The slow, obvious converters: record by record over each format's `decode`, the judges of the fast paths.

Each `convert_*_reference` gives the very outputs of the recorder it names
(`recorders.gps.convert_nmea`, ...), built the plain way: records from the
format's record-based decoder, grouped into epochs with
`recorders.epochs.group_epochs`, messages from the protobuf keyword
constructors. The tests compare the fast paths to these on any bytes;
bench/bench_nmea.py and bench/bench_pd0.py time them beside the fast paths.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

from formats import phins
from formats import schemas as S
from formats.evologics import notifications as ev
from formats.micromodem import sentences as mm
from formats.nmea import sentences as nmea
from formats.novatel import logs as novatel
from formats.pd0 import ensembles as pd0
from formats.records import Reject
from formats.units import NS, archivable_ns
from recorders.base import Ignored, LogContext, Output, output
from recorders.clock import DayClock
from recorders.dvl import pd0_items
from recorders.epochs import group_epochs, host_time_ns
from recorders.gnss_covariance import Covariance, fix_covariance, sigma_covariance
from recorders.gnss_velocity import NO_VELOCITY
from recorders.gnss_velocity import SUFFIX as VELOCITY
from recorders.gps import NOVATEL_QUALITY, gnss_status, novatel_velocity
from recorders.ins import ins_state
from recorders.modem import (
    MICROMODEM_UNUSED,
    NO_USBL_TIME,
    MicromodemOptions,
    acoustic_range,
    evologics_problem,
    host_time,
    micromodem_event_text,
    micromodem_options,
    modem_event,
    own_address,
    own_addresses,
    set_modem_date,
    sound_speed,
    toa_range,
    usbl_reception_ns,
)
from recorders.nmea_epochs import (
    NmeaEpoch,
    gga_altitude,
    nmea_epoch_time,
    nmea_motion,
    nmea_position,
    nmea_update_date,
    record_epochs,
)
from recorders.novatel_epochs import implausible_week
from recorders.usbl import (
    IMPLAUSIBLE_FIX,
    MATCH_S,
    UsblOptions,
    bearing_elevation,
    fix_time,
    observation,
    usbl_options,
)
from recorders.usbl import SUFFIX as USBL_SUFFIX

NAN = math.nan
UsblRecord = ev.UsblLong | ev.UsblAngles | ev.UsblPhaseDelays


# ---------------------------------------------------------------- recorders.gps: NMEA


def _nmea_covariance(epoch: NmeaEpoch, ctx: LogContext) -> Covariance:
    gst, gga = epoch.gst, epoch.gga
    return fix_covariance(gst.lat_std_m if gst else NAN, gst.lon_std_m if gst else NAN, gst.alt_std_m if gst else NAN,
                          gga.hdop if gga else NAN, gga.quality if gga else -1, ctx.options)


def _nmea_velocity(t: int, vehicle: str, source: str, speed: float, course: float) -> S.GnssVelocity:
    north, east = speed * math.cos(math.radians(course)), speed * math.sin(math.radians(course))
    return S.GnssVelocity(timestamp=S.timestamp(t), frame_id=vehicle, velocity_north_mps=north, velocity_east_mps=east,
                          velocity_up_mps=NAN, speed_over_ground_mps=speed, course_over_ground_deg=course,
                          speed_std_mps=NAN, source_format=source)


def _nmea_outputs(records: list[nmea.NmeaRecord], ctx: LogContext, clock: DayClock
                  ) -> Iterator[Output | Reject | Ignored]:
    epoch = NmeaEpoch.of(records)
    if epoch.only_zda:
        nmea_update_date(epoch, clock)  # a date-only epoch: nothing to emit, but the date counts
        return
    t = nmea_epoch_time(epoch, clock, ctx)
    if isinstance(t, Reject):
        yield t
        return
    pos = nmea_position(epoch)
    where = pos.where if pos is not None else records[0].where
    if pos is not None:
        alt = gga_altitude(pos) if isinstance(pos, nmea.Gga) else NAN
        cov, kind = _nmea_covariance(epoch, ctx)
        fix = S.location_fix(t, ctx.vehicle, pos.latitude, pos.longitude, alt, cov, kind)
        yield output(ctx, "gps", fix, t, where)
    g = epoch.gga
    speed, course, heading = nmea_motion(epoch)
    status = gnss_status(
        t, ctx.vehicle, g.quality if g is not None else -1, g.satellites if g is not None else -1,
        g.hdop if g is not None else NAN, "nmea:" + ",".join(type(r).__name__.upper() for r in records),
        speed, course, heading,
    )
    yield output(ctx, "gps/status", status, t, where)
    if math.isfinite(speed) and math.isfinite(course):
        yield output(ctx, VELOCITY, _nmea_velocity(t, ctx.vehicle, status.source_format, speed, course), t, where)
    elif epoch.vtg is not None or epoch.rmc is not None:
        yield Ignored(where, NO_VELOCITY)


def convert_nmea_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    """`recorders.gps.convert_nmea` the obvious way, over `nmea.decode` records."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    for epoch in record_epochs(data, ctx.prefix):
        if isinstance(epoch, Reject):
            yield epoch
        else:
            yield from _nmea_outputs(epoch, ctx, clock)


# ---------------------------------------------------------------- recorders.gps: NovAtel


def novatel_key(rec: novatel.NovatelRecord) -> tuple[str, tuple[int, int]]:
    """Epoch key of a NovAtel record: its log and GPS time in ms."""
    week, sow = (rec.week, rec.seconds) if isinstance(rec, novatel.InsPva) else (rec.header.week, rec.header.seconds)
    return type(rec).__name__, (week, round(sow * 1000) if math.isfinite(sow) else -1)


def novatel_time(epoch: list[novatel.NovatelRecord], ctx: LogContext) -> int | Reject:
    """UTC ns (offset applied) of a NovAtel epoch from its GPS time, else the host time."""
    try:
        t = novatel.record_time_ns(epoch[0])
    except OverflowError:
        t = -1
    if t is not None:
        t += ctx.clock_offset_ns
        return t if archivable_ns(t) else Reject(epoch[0].where, implausible_week(epoch[0].header.week))
    host = host_time_ns(epoch, ctx)
    if host is None:
        return Reject(epoch[0].where, "no time: GPS week 0 or unknown time status, and no host timestamp")
    return host


def _source(rec: novatel.NovatelRecord) -> str:
    h = rec.header
    return h.message + ("B" if h.encoding.startswith("binary") else "A")


def _novatel_outputs(epoch: list[novatel.NovatelRecord], ctx: LogContext) -> Iterator[Output | Reject]:
    t = novatel_time(epoch, ctx)
    if isinstance(t, Reject):
        yield t
        return
    bp = next((r for r in epoch if isinstance(r, novatel.BestPos)), None)
    bv = next((r for r in epoch if isinstance(r, novatel.BestVel)), None)
    where = epoch[0].where
    if bp is not None and bp.solution_status == "SOL_COMPUTED" and bp.position_type != "NONE":
        u = bp.undulation_m
        alt = bp.height_msl_m if math.isnan(u) else bp.height_msl_m + u
        cov, kind = sigma_covariance(bp.lat_std_m, bp.lon_std_m, bp.height_std_m)
        fix = S.location_fix(t, ctx.vehicle, bp.latitude, bp.longitude, alt, cov, kind)
        yield output(ctx, "gps", fix, t, bp.where)
        where = bp.where
    speed = course = NAN
    source = "novatel:" + ",".join(_source(r) for r in epoch)
    if bv is not None and bv.solution_status == "SOL_COMPUTED":
        speed, course = bv.horizontal_speed_mps, bv.track_deg
    status = gnss_status(
        t, ctx.vehicle, NOVATEL_QUALITY.get(bp.position_type, -1) if bp is not None else -1,
        bp.satellites_used if bp is not None else -1, NAN, source, speed, course, NAN,
    )
    yield output(ctx, "gps/status", status, t, where)
    if bv is not None and bv.solution_status == "SOL_COMPUTED":
        velocity = novatel_velocity(ctx, t, source, speed, course, bv.vertical_speed_mps)
        yield output(ctx, "gps/velocity", velocity, t, bv.where)


def convert_novatel_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`recorders.gps.convert_novatel` the obvious way, over `novatel.decode` records."""
    records = (r for r in novatel.decode(data, ctx.prefix) if isinstance(r, (Reject, novatel.BestPos, novatel.BestVel)))
    epochs: Iterator[list[novatel.NovatelRecord] | Reject] = group_epochs(records, novatel_key)
    for epoch in epochs:
        if isinstance(epoch, Reject):
            yield epoch
        else:
            yield from _novatel_outputs(epoch, ctx)


# ---------------------------------------------------------------- recorders.ins


NAV = (phins.Heading, phins.Atitud, phins.Positi, phins.Speed, phins.Phtro)


def phins_key(rec: phins.PhinsRecord) -> tuple[str, None]:
    """Epoch key of a PHINS record: its sentence kind (bursts are delimited by repetition)."""
    return (rec.kind if isinstance(rec, phins.StatusWords) else type(rec).__name__), None


def _phins_fields(epoch: list[phins.PhinsRecord]) -> tuple[str, dict[str, float]]:
    f: dict[str, float] = {}
    words = []
    for r in epoch:
        if isinstance(r, phins.Heading):
            if r.mode != "V":
                f["heading_deg"] = r.heading_deg
        elif isinstance(r, phins.Atitud):
            f["roll_deg"], f["pitch_deg"] = r.roll_port_up_deg, -r.pitch_bow_down_deg
        elif isinstance(r, phins.Phtro):
            if "roll_deg" not in f:
                f["roll_deg"], f["pitch_deg"] = r.roll_port_up_deg, r.pitch_bow_up_deg
        elif isinstance(r, phins.Positi):
            f["latitude"], f["longitude"] = r.latitude, r.longitude
            f["altitude_m"], f["depth_m"] = r.altitude_m, 0.0 - r.altitude_m
        elif isinstance(r, phins.Speed):
            f["velocity_north_mps"], f["velocity_east_mps"], f["velocity_down_mps"] = r.north_mps, r.east_mps, 0.0 - r.up_mps
        elif isinstance(r, phins.StdHrp):
            f["heading_std_deg"], f["roll_std_deg"], f["pitch_std_deg"] = r.heading_std_deg, r.roll_std_deg, r.pitch_std_deg
        elif isinstance(r, phins.StdPos):
            f["position_std_north_m"], f["position_std_east_m"] = r.lat_std_m, r.lon_std_m
        elif isinstance(r, phins.StatusWords):
            words.append(f"{r.kind}={r.lsb:08X}" + ("" if r.kind == "HT_STS" else f",{r.msb:08X}"))
    return " ".join(words), f


def _phins_outputs(epoch: list[phins.PhinsRecord], ctx: LogContext, clock: DayClock) -> Iterator[Output | Reject]:
    if not any(isinstance(r, NAV) for r in epoch):
        return
    stamp = next((r for r in epoch if isinstance(r, phins.Time) and not math.isnan(r.time_s)), None)
    if stamp is not None:
        t = clock.resolve(stamp.time_s)
        if t is None:
            yield Reject(stamp.where, "no date for PHINS TIME__: set the [trial] date in the manifest")
            return
    else:
        t = host_time_ns(epoch, ctx)
        if t is None:
            yield Reject(epoch[0].where, "no time: PHINS burst without TIME__ and without a host timestamp")
            return
    status, values = _phins_fields(epoch)
    yield output(ctx, "ins", ins_state(t, ctx, "phins", status, **values), t, epoch[0].where)


def convert_phins_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`recorders.ins.convert_phins` the obvious way, over `phins.decode` records."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    epochs: Iterator[list[phins.PhinsRecord] | Reject] = group_epochs(phins.decode(data, ctx.prefix), phins_key)
    for epoch in epochs:
        if isinstance(epoch, Reject):
            yield epoch
        else:
            yield from _phins_outputs(epoch, ctx, clock)


def _span_fields(epoch: list[novatel.InsPva | novatel.InsPvax]) -> tuple[str, dict[str, float]]:
    f: dict[str, float] = {}
    status = []
    for r in epoch:
        f.update(
            latitude=r.latitude, longitude=r.longitude, altitude_m=r.height_m,
            velocity_north_mps=r.north_mps, velocity_east_mps=r.east_mps, velocity_down_mps=0.0 - r.up_mps,
            roll_deg=r.roll_deg, pitch_deg=r.pitch_deg, heading_deg=r.azimuth_deg,
        )
        status.append(r.status)
        if isinstance(r, novatel.InsPvax):
            u = r.undulation_m
            f.update(
                depth_m=NAN if math.isnan(u) else -(r.height_m - u), heading_std_deg=r.azimuth_std_deg,
                roll_std_deg=r.roll_std_deg, pitch_std_deg=r.pitch_std_deg,
                position_std_north_m=r.lat_std_m, position_std_east_m=r.lon_std_m,
            )
            status.append(r.position_type)
    return " ".join(dict.fromkeys(status)), f


def convert_span_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`recorders.ins.convert_span` the obvious way, over `novatel.decode` records."""
    records = (r for r in novatel.decode(data, ctx.prefix) if isinstance(r, (Reject, novatel.InsPva, novatel.InsPvax)))
    epochs: Iterator[list[novatel.InsPva | novatel.InsPvax] | Reject] = group_epochs(records, novatel_key)
    for epoch in epochs:
        if isinstance(epoch, Reject):
            yield epoch
            continue
        t = novatel_time(list(epoch), ctx)
        if isinstance(t, Reject):
            yield t
            continue
        source = "novatel:" + ",".join(_source(r) for r in epoch)
        status, values = _span_fields(epoch)
        yield output(ctx, "ins", ins_state(t, ctx, source, status, **values), t, epoch[0].where)


# ---------------------------------------------------------------- recorders.dvl


def convert_pd0_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`recorders.dvl.convert_pd0` the obvious way, over `pd0.decode` records."""
    fixed: pd0.FixedLeader | None = None
    for rec in pd0.decode(data):
        if isinstance(rec, Reject):
            yield rec
            continue
        fixed = rec.fixed or fixed  # an ensemble without a fixed leader uses the last one
        yield from pd0_items(rec, fixed, ctx)


# ---------------------------------------------------------------- recorders.modem

def _ping(ctx: LogContext, rec: mm.PingReply, own: frozenset[int], c: float) -> Output | Reject:
    heard, measurer = rec.src, rec.dest
    if own and heard in own and measurer not in own:
        heard, measurer = measurer, heard  # firmware that writes the pinger first
    elif own and measurer not in own:
        return Reject(rec.where, f"ping reply between modems {heard} and {measurer}: neither is {ctx.vehicle}'s")
    arrival = rec.utc_ns + ctx.clock_offset_ns if rec.utc_ns is not None else host_time(ctx, rec.where)
    if arrival is None:
        return Reject(rec.where, "no time: the ping reply carries none and the line has no host timestamp")
    t = arrival - round(rec.one_way_travel_time_s * NS)
    return acoustic_range(
        ctx, t, rec.where, (ctx.vehicle_for_address(heard), heard), (ctx.vehicle, measurer),
        rec.one_way_travel_time_s, "ping", "micromodem", c,
    )


def _utc(rec: mm.TimeOfArrival) -> int:
    """A time of arrival's UTC time, for one without a time of day (the decoder gives it one or the other)."""
    if rec.utc_ns is None:
        raise ValueError("a time of arrival with neither a time of day nor a UTC time")
    return rec.utc_ns


def _micromodem(data: bytes, ctx: LogContext, opts: MicromodemOptions) -> Iterator[Output | Reject | Ignored]:
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    own = own_addresses(ctx)
    last_src: int | None = None
    heard = {mm.PingHeard: "ping", mm.CycleInit: "cycle", mm.ReceivedData: "data"}
    for rec in mm.decode(data, ctx.prefix, opts.round_trip):
        if isinstance(rec, Reject):
            yield rec
        elif isinstance(rec, mm.PingReply):
            yield _ping(ctx, rec, own, opts.c)
        elif isinstance(rec, mm.TransmitStats):
            set_modem_date(clock, rec)
            yield Ignored(rec.where, MICROMODEM_UNUSED["date"])
        elif isinstance(rec, mm.Clock):
            set_modem_date(clock, rec)
            yield Ignored(rec.where, MICROMODEM_UNUSED["clock"])
        elif isinstance(rec, (mm.CycleInit, mm.ReceivedData, mm.PingHeard)):
            if rec.src not in own:
                last_src = rec.src
            utc = rec.utc_ns if isinstance(rec, mm.PingHeard) else None
            text = micromodem_event_text("heard", rec.src, rec.dest, heard[type(rec)])
            yield modem_event(ctx, rec.where, text, utc)
        elif isinstance(rec, mm.PingCommand):
            yield modem_event(ctx, rec.where, micromodem_event_text("sent", rec.src, rec.dest, rec.echo))
        elif isinstance(rec, mm.OtherSentence):
            yield Ignored(rec.where, f"${rec.address}: nothing archived")
        elif isinstance(rec, mm.ReceiveStats):
            last_src = rec.src
            if opts.period_s is not None:
                yield toa_range(ctx, rec.where, clock.resolve(rec.tod_s), rec.src, opts)
            else:
                yield Ignored(rec.where, MICROMODEM_UNUSED["rxstats"])
        elif isinstance(rec, mm.TimeOfArrival):
            if opts.period_s is not None:
                arrival = clock.resolve(rec.tod_s) if rec.tod_s is not None else _utc(rec) + ctx.clock_offset_ns
                yield toa_range(ctx, rec.where, arrival, last_src, opts)
            else:
                yield Ignored(rec.where, MICROMODEM_UNUSED["toa"])


def convert_micromodem_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    """`recorders.modem.convert_micromodem` the obvious way, over `micromodem.decode` records."""
    return _micromodem(data, ctx, micromodem_options(ctx))


def _modem_evologics(data: bytes, ctx: LogContext, c: float) -> Iterator[Output | Reject]:
    me = (ctx.vehicle, own_address(ctx))
    for rec in ev.decode(data, ctx.prefix):
        if isinstance(rec, Reject):
            yield rec
        elif isinstance(rec, ev.PropagationTime):
            host = host_time(ctx, rec.where)
            if rec.peer is None:
                yield Reject(rec.where, "propagation time before any delivery or reception names the peer")
            elif host is None:
                yield Reject(rec.where, "no time: EvoLogics line without host timestamp")
            elif (why := evologics_problem(rec.propagation_time_us, rec.peer)) is not None:
                yield Reject(rec.where, why)
            else:
                tt = rec.propagation_time_us * 1e-6
                heard = (ctx.vehicle_for_address(rec.peer), rec.peer)
                yield acoustic_range(ctx, host - round(tt * NS), rec.where, heard, me, tt, "ping", "evologics", c)
        elif isinstance(rec, ev.UsblLong):
            arrival = usbl_reception_ns(ctx, rec.where, rec.current_time_s, rec.measurement_time_s)
            if arrival is None:
                yield Reject(rec.where, NO_USBL_TIME)
                continue
            why = evologics_problem(rec.propagation_time_us, rec.address)
            if why is not None:
                yield Reject(rec.where, why)
                continue
            tt = rec.propagation_time_us * 1e-6
            heard = (ctx.vehicle_for_address(rec.address), rec.address)
            yield acoustic_range(ctx, arrival - round(tt * NS), rec.where, heard, me, tt, "usbl", "evologics", c)


def convert_modem_evologics_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`recorders.modem.convert_evologics` the obvious way, over `evologics.decode` records."""
    return _modem_evologics(data, ctx, sound_speed(ctx))


# ---------------------------------------------------------------- recorders.usbl

@dataclass
class _Group:
    """The USBL lines of one measurement, in the order they were logged."""

    first: UsblRecord
    parts: dict[type, UsblRecord] = field(default_factory=dict)

    def accepts(self, rec: UsblRecord) -> bool:
        return (
            rec.address == self.first.address and type(rec) not in self.parts
            and abs(rec.measurement_time_s - self.first.measurement_time_s) <= MATCH_S
        )


def _values(group: _Group, opts: UsblOptions) -> dict[str, float]:
    v: dict[str, float] = {}
    fix = group.parts.get(ev.UsblLong)
    ang = group.parts.get(ev.UsblAngles)
    phyd = group.parts.get(ev.UsblPhaseDelays)
    if isinstance(fix, ev.UsblLong):
        tt = fix.propagation_time_us * 1e-6
        v.update(travel_time_s=tt, range_m=tt * opts.c, east_m=fix.east_m, north_m=fix.north_m, up_m=fix.up_m)
        v["bearing_deg"], v["elevation_deg"] = bearing_elevation(fix.east_m, fix.north_m, fix.up_m)
        v.update(integrity=fix.integrity, rssi_db=fix.rssi_db)
    elif isinstance(ang, ev.UsblAngles):
        v["bearing_deg"] = ev.bearing_from_vendor(ang.bearing_rad, opts.convention)
        v["elevation_deg"] = math.degrees(ang.elevation_rad)
        v.update(integrity=ang.integrity, rssi_db=ang.rssi_db)
    if isinstance(phyd, ev.UsblPhaseDelays) and opts.carrier_hz is not None:
        v["phase_x_rad"], v["phase_y_rad"] = ev.phases_from_delays(phyd.delays_ns, opts.carrier_hz)
    return v


def _emit(ctx: LogContext, group: _Group, opts: UsblOptions) -> Output | Reject:
    first = group.first
    arrival = usbl_reception_ns(ctx, first.where, first.current_time_s, first.measurement_time_s)
    if arrival is None:
        return Reject(first.where, NO_USBL_TIME)
    v = _values(group, opts)
    t = fix_time(arrival, v.get("travel_time_s", 0.0))
    if not archivable_ns(t):
        return Reject(first.where, IMPLAUSIBLE_FIX)
    msg = observation(t, ctx.vehicle, ctx.vehicle_for_address(first.address), "evologics", v)
    return output(ctx, USBL_SUFFIX, msg, t, first.where)


def _usbl_evologics(data: bytes, ctx: LogContext, opts: UsblOptions) -> Iterator[Output | Reject]:
    group: _Group | None = None
    for rec in ev.decode(data, ctx.prefix):
        if isinstance(rec, Reject):
            yield rec
        elif isinstance(rec, (ev.UsblLong, ev.UsblAngles, ev.UsblPhaseDelays)):
            if group is not None and group.accepts(rec):
                group.parts[type(rec)] = rec
                continue
            if group is not None:
                yield _emit(ctx, group, opts)
            group = _Group(rec, {type(rec): rec})
    if group is not None:
        yield _emit(ctx, group, opts)


def convert_usbl_evologics_reference(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """`recorders.usbl.convert_evologics` the obvious way, over `evologics.decode` records."""
    return _usbl_evologics(data, ctx, usbl_options(ctx))
