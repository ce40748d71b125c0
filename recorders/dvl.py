"""DVL logs to `auvreplay.DvlVelocity` on /<vehicle>/dvl, one converter per vendor format.

Every message carries the VEHICLE velocity over ground (m/s) in the frame
the data are in: PD0 from the fixed leader's EX coordinate bits (bottom-track
values negated, RDI ship axes x starboard / y forward / z up turned into
BODY_FRD x forward / y starboard / z down: see `formats.pd0.frames.vehicle_velocity`),
PD4/PD5 from their config byte, PD6 from the line used (BS, BE or BI), Nortek
and Water Linked from the manifest option ``dvl_frame`` (default INSTRUMENT
for Nortek, BODY_FRD for Water Linked, whose axes are the mounted frame).

``beam_range_m`` holds slant ranges per beam (NaN without bottom);
``altitude_m`` is the mean of the valid beams' vertical ranges (slant x cos of
the beam angle: manifest ``beam_angle_deg``, else the PD0 fixed leader, else
30°), or the vendor's own altitude where it reports one (Water Linked, PD6
:BD). ``valid`` is true when every velocity component the format provides is
good (and the vendor's own flag, where there is one, says so).

Times: PD0 RTC (Y2K clock when present); PD4/PD5 time of day dated by
`DayClock`; PD6 :TS; Nortek ping time (Unix); Water Linked time of validity (inside a container, a ROS
string topic, the container's stamp, the time of validity kept as ``device_time``).
Formats or records without a time use the host-timestamp prefix, else the
record is rejected. The manifest clock offset is added to every time; out of
order or repeated times are kept as they come.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

from formats import nortek, pd4, pd6, waterlinked
from formats.log_blocks import LogText
from formats.pd0 import blocks as pd0_blocks
from formats.pd0 import ensembles as pd0
from formats.pd0.frames import vehicle_velocity
from formats.records import FormatError, Reject, Where
from formats.schemas import DvlVelocity, set_timestamp, timestamp
from formats.wire import DVL_VELOCITY

from .base import (
    CONTAINER_TIME,
    Batch,
    BlockConverter,
    Columns,
    Converter,
    LogContext,
    Output,
    blockwise,
    int64_times,
    output,
)
from .clock import DayClock

NAN = math.nan
FRAMES = {"BODY_FRD": DvlVelocity.BODY_FRD, "EARTH_NED": DvlVelocity.EARTH_NED,
          "INSTRUMENT": DvlVelocity.INSTRUMENT}
_ALIASES = {"BODY": "BODY_FRD", "FRD": "BODY_FRD", "SHIP": "BODY_FRD", "EARTH": "EARTH_NED",
            "NED": "EARTH_NED", "XYZ": "INSTRUMENT"}
_EARLIEST_US = 946_684_800 * 1_000_000  # 2000-01-01: a DVL clock before this was never set


def frame_option(ctx: LogContext, default: str) -> str:
    """The manifest's ``dvl_frame`` (case-insensitive, with aliases), else `default`."""
    name = str(ctx.options.get("dvl_frame", default)).strip().upper()
    name = _ALIASES.get(name, name)
    if name not in FRAMES:
        raise FormatError(f"manifest option dvl_frame={name!r} is not one of {sorted(FRAMES)}")
    return name


def beam_angle(ctx: LogContext, vendor: float | None = None) -> float:
    """Beam angle (°) from the manifest, else the vendor's, else 30."""
    if "beam_angle_deg" in ctx.options:
        return float(ctx.options["beam_angle_deg"])
    return vendor if vendor is not None and math.isfinite(vendor) else 30.0


def ranges_from_vertical(vertical: Sequence[float], angle_deg: float) -> tuple[list[float], float]:
    """(slant ranges, altitude) from per-beam vertical ranges; altitude = mean of valid ones."""
    c = math.cos(math.radians(angle_deg))
    good = [v for v in vertical if math.isfinite(v)]
    return [v / c for v in vertical], (sum(good) / len(good) if good else NAN)


def ranges_from_slant(slant: Sequence[float], angle_deg: float) -> tuple[list[float], float]:
    """(slant ranges, altitude) with altitude = mean of valid slant ranges x cos(angle)."""
    good = [s for s in slant if math.isfinite(s)]
    alt = sum(good) / len(good) * math.cos(math.radians(angle_deg)) if good else NAN
    return list(slant), alt


def message(ctx: LogContext, t_ns: int, frame: str, velocity: Sequence[float], *,
            error: float = NAN, ranges: Sequence[float] = (), altitude: float = NAN,
            valid: bool | None = None, fom: float = NAN, sound_speed: float = NAN,
            temperature: float = NAN, source: str = "") -> Any:
    """A DvlVelocity; `valid` defaults to 'every given component is finite'.

    A negative altitude is a DVL's "no altitude" (Water Linked's -1): the ping is kept, its altitude NaN and
    not valid (no bottom in range), rather than refused by the record-time range check.
    """
    vx, vy, vz = velocity
    if valid is None:
        valid = all(math.isfinite(v) for v in velocity)
    if altitude < 0.0:
        altitude, valid = NAN, False
    return DvlVelocity(
        timestamp=timestamp(t_ns), frame_id=ctx.vehicle, frame=FRAMES[frame],
        velocity_x_mps=vx, velocity_y_mps=vy, velocity_z_mps=vz, error_velocity_mps=error,
        beam_range_m=list(ranges), altitude_m=altitude, valid=bool(valid),
        figure_of_merit=fom, sound_speed_mps=sound_speed, source_format=source,
        temperature_c=temperature,
    )


def _host_time(ctx: LogContext, where: Where) -> int | None:
    return None if where.host_time_ns is None else where.host_time_ns + ctx.clock_offset_ns


# --- Teledyne RDI ------------------------------------------------------------------------


def pd0_items(rec: pd0.Ensemble, fixed: pd0.FixedLeader | None, ctx: LogContext) -> Iterator[Output | Reject]:
    """The message of one ensemble, or why it has none (`fixed`: its own or the last one seen)."""
    bt, var, time_ns = rec.bottom_track, rec.variable, rec.time_ns
    number = var.ensemble_number if var else "?"
    if time_ns is None or var is None:  # no variable leader gives no time either
        yield Reject(rec.where, f"ensemble {number}: no variable leader or invalid RTC time")
    elif bt is None:
        yield Reject(rec.where, f"ensemble {number}: no bottom-track data")
    elif fixed is None:
        yield Reject(rec.where, f"ensemble {number}: no fixed leader yet (coordinates unknown)")
    else:
        yield _pd0_output(ctx, rec.where, time_ns + ctx.clock_offset_ns, bt, var, fixed)


def _pd0_output(ctx: LogContext, where: Where, t: int, bt: pd0.BottomTrack, var: pd0.VariableLeader,
                fixed: pd0.FixedLeader) -> Output:
    angle = beam_angle(ctx, fixed.beam_angle_deg)
    frame, x, y, z, err = vehicle_velocity(fixed.coordinates, bt.velocity_mps, angle, fixed.convex)
    slant, alt = ranges_from_vertical(bt.range_m, angle)
    msg = message(ctx, t, frame, (x, y, z), error=err, ranges=slant, altitude=alt,
                  sound_speed=var.sound_speed_mps, temperature=var.temperature_c, source="pd0")
    return output(ctx, "dvl", msg, t, where)


# ---------------------------------------------------------------- PD0, fast path
# The same messages as tests/reference_converters.py's `convert_pd0_reference`, over `pd0_blocks.scan`: a run
# of like ensembles has its velocities, ranges and altitudes computed as
# arrays (the same IEEE operations in the same order, so the same bits, NaN
# signs included), and each DvlVelocity is parsed from wire bytes packed by `formats.wire`.


def _pd0_motion(block: pd0_blocks.Block, fixed: pd0.FixedLeader, ctx: LogContext) -> tuple:
    """(frame name, columns x, y, z, error, slant ranges, altitude, valid) of a block (`_pd0_output`)."""
    angle = beam_angle(ctx, fixed.beam_angle_deg)
    bt, vertical = block.velocity_mps, block.range_m
    if bt is None or vertical is None:
        raise ValueError("a block without bottom track has no motion")  # the caller rejects those first
    frame, x, y, z, err = vehicle_velocity(fixed.coordinates, tuple(bt.T), angle, fixed.convex)
    good = np.isfinite(vertical)
    # `ranges_from_vertical`'s sum(good) / len(good): adding 0.0 for a bad beam leaves the sum's bits alone
    w = np.where(good, vertical, 0.0)
    count = good.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        alt = np.where(count > 0, (((w[:, 0] + w[:, 1]) + w[:, 2]) + w[:, 3]) / count, NAN)
    slant = vertical / math.cos(math.radians(angle))
    valid = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    return frame, x, y, z, err, slant, alt, valid


def _pd0_block_outputs(block: pd0_blocks.Block, fixed: pd0.FixedLeader | None, ctx: LogContext
                       ) -> Iterator[Output | Reject | Batch]:
    """`convert_pd0_reference`'s items for the ensembles of one block: one Batch when every ensemble has a time."""
    offsets, times, numbers = block.offsets, block.time_ns, block.numbers
    sounds, temps = block.sound_speed_mps, block.temperature_c  # None only with `times` (no variable leader)
    if (times is None or numbers is None or sounds is None or temps is None or block.velocity_mps is None
            or fixed is None):
        for k, off in enumerate(offsets):
            number = numbers[k] if numbers is not None else "?"
            if times is None or times[k] is None:
                yield Reject(Where(off), f"ensemble {number}: no variable leader or invalid RTC time")
            elif block.velocity_mps is None:
                yield Reject(Where(off), f"ensemble {number}: no bottom-track data")
            else:
                yield Reject(Where(off), f"ensemble {number}: no fixed leader yet (coordinates unknown)")
        return
    motion = _pd0_motion(block, fixed, ctx)
    if not ctx.batches:
        yield from _pd0_messages(block, ctx, motion)
        return
    frame, x, y, z, err, slant, alt, valid = motion
    t = int64_times(times, ctx.clock_offset_ns)
    if t is None:
        yield from _pd0_messages(block, ctx, motion)
        return
    columns = {"timestamp": t, "frame_id": ctx.vehicle, "frame": FRAMES[frame], "velocity_x_mps": x,
               "velocity_y_mps": y, "velocity_z_mps": z, "error_velocity_mps": err, "beam_range_m": slant,
               "altitude_m": alt, "valid": valid, "figure_of_merit": NAN,
               "sound_speed_mps": np.asarray(sounds, dtype=np.float64), "source_format": "pd0",
               "temperature_c": np.asarray(temps, dtype=np.float64)}
    yield Batch([Columns(f"/{ctx.vehicle}/dvl", DvlVelocity, columns, t, t)], np.zeros(len(t), dtype=np.int64),
                np.asarray(offsets, dtype=np.int64), Where(int(offsets[-1])),
                lambda: _pd0_messages(block, ctx, motion))


def _pd0_messages(block: pd0_blocks.Block, ctx: LogContext, motion: tuple) -> Iterator[Output | Reject]:
    """A block's DvlVelocity messages one by one (a Reject for an ensemble without a time)."""
    frame, *columns = motion
    xs, ys, zs, errs, slants, alts, valids = (c.tolist() for c in columns)
    head = DvlVelocity(frame_id=ctx.vehicle, frame=FRAMES[frame], figure_of_merit=NAN,
                       source_format="pd0").SerializeToString()
    pack, parse = DVL_VELOCITY.struct.pack, DvlVelocity.FromString
    topic, offset_ns = f"/{ctx.vehicle}/dvl", ctx.clock_offset_ns
    k0, k1, k2, k3, k4, k5, k6, k7, k8 = DVL_VELOCITY.keys
    assert block.time_ns is not None and block.numbers is not None  # as `_pd0_block_outputs` checked
    for off, t, number, x, y, z, err, r, alt, valid, sound, temp in zip(
            block.offsets, block.time_ns, block.numbers, xs, ys, zs, errs, slants, alts, valids,
            block.sound_speed_mps or (), block.temperature_c or ()):
        if t is None:
            yield Reject(Where(off), f"ensemble {number}: no variable leader or invalid RTC time")
            continue
        t += offset_ns
        msg = parse(head + pack(k0, x, k1, y, k2, z, k3, err, k4, *r, k5, alt, k6, valid, k7, sound, k8, temp))
        set_timestamp(msg.timestamp, t)
        yield Output(topic, msg, t, t, Where(off))


def convert_pd0(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Batch]:
    """Teledyne RDI PD0 ensembles (bottom track); frame from the EX coordinate bits."""
    fixed: pd0.FixedLeader | None = None
    for item in pd0_blocks.scan(data):
        if isinstance(item, Reject):
            yield item
        elif isinstance(item, pd0_blocks.Block):
            fixed = item.fixed or fixed
            yield from _pd0_block_outputs(item, fixed, ctx)
        else:  # an ensemble off the block path: the reference's own steps
            fixed = item.fixed or fixed
            yield from pd0_items(item, fixed, ctx)


def convert_pd4(data: bytes, ctx: LogContext) -> Iterator[Output | Reject]:
    """Teledyne RDI PD4/PD5 binary; time of day dated with the trial date."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    angle = beam_angle(ctx)
    for rec in pd4.decode(data):
        if isinstance(rec, Reject):
            yield rec
            continue
        t = clock.resolve(rec.tod_s)
        if t is None:
            yield Reject(rec.where, "PD4/PD5 carry only a time of day: the manifest needs a trial date")
            continue
        frame, x, y, z, err = pd4.vehicle_velocity(rec.coordinates, rec.velocity_mps, angle)
        slant, alt = ranges_from_vertical(rec.range_m, angle)
        msg = message(ctx, t, frame, (x, y, z), error=err, ranges=slant, altitude=alt,
                      sound_speed=rec.sound_speed_mps, temperature=rec.temperature_c,
                      source="pd5" if rec.structure == 1 else "pd4")
        yield output(ctx, "dvl", msg, t, rec.where)


def convert_pd6(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """Teledyne RDI PD6/PD13 ASCII; BS (BODY_FRD) preferred, dvl_frame picks BS/BE/BI."""
    choice = frame_option(ctx, "") if "dvl_frame" in ctx.options else None
    angle = beam_angle(ctx)
    for ens in pd6.ensembles(data, ctx.prefix):
        if isinstance(ens, Reject):
            yield ens
            continue
        vel = pd6.vehicle_velocity(ens, choice)
        t = ens.time_ns
        if vel is None:
            yield Reject(ens.where, "PD6 ensemble without bottom-track velocity (:BI/:BS/:BE)")
        elif t is None:
            yield Reject(ens.where, "PD6 ensemble without a valid :TS time or host timestamp")
        else:
            yield output(ctx, "dvl", _pd6_message(ctx, ens, vel, t + ctx.clock_offset_ns, angle),
                         t + ctx.clock_offset_ns, ens.where)


def _pd6_message(ctx: LogContext, ens: pd6.Pd6Ensemble, vel: tuple, t: int, angle: float) -> Any:
    frame, x, y, z, err, good = vel
    ranges, alt = ranges_from_vertical(ens.ranges.range_m, angle) if ens.ranges else ([], NAN)
    bd = ens.distances.get("BD")
    if bd is not None and bd.range_m > 0:
        alt = bd.range_m
    ts = ens.timescale
    return message(ctx, t, frame, (x, y, z), error=err, ranges=ranges, altitude=alt,
                   valid=good and all(math.isfinite(v) for v in (x, y, z)),
                   sound_speed=ts.sound_speed_mps if ts else NAN,
                   temperature=ts.temperature_c if ts else NAN, source="pd6")


# --- Nortek -------------------------------------------------------------------------------


def convert_nortek(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """Nortek $PNORBT family; XYZ velocities in dvl_frame (default INSTRUMENT)."""
    frame = frame_option(ctx, "INSTRUMENT")
    angle = beam_angle(ctx)
    beams: list[nortek.BeamReport] = []
    for rec in nortek.decode(data, ctx.prefix):
        if beams and (not isinstance(rec, nortek.BeamReport) or rec.time_ns != beams[0].time_ns):
            yield from _nortek_beams(ctx, beams, angle)
            beams = []
        if isinstance(rec, Reject):
            yield rec
        elif isinstance(rec, nortek.BeamReport):
            beams.append(rec)
        elif isinstance(rec, nortek.SpeedReport):
            yield _nortek_speed(ctx, rec)
        else:
            yield _nortek_velocity(ctx, rec, frame, angle)
    if beams:
        yield from _nortek_beams(ctx, beams, angle)


def _nortek_velocity(ctx: LogContext, rec: nortek.VelocityReport, frame: str, angle: float
                     ) -> Output | Reject:
    t = rec.time_ns + ctx.clock_offset_ns if rec.time_ns is not None else _host_time(ctx, rec.where)
    if t is None:
        return Reject(rec.where, f"{rec.sentence}: invalid ping time and no host timestamp")
    slant, alt = ranges_from_vertical(rec.distance_m, angle)
    msg = message(ctx, t, frame, rec.velocity_mps, ranges=slant, altitude=alt,
                  fom=rec.figure_of_merit, sound_speed=rec.sound_speed_mps,
                  temperature=rec.temperature_c, source=f"nortek:{rec.sentence}")
    return output(ctx, "dvl", msg, t, rec.where)


def _nortek_speed(ctx: LogContext, rec: nortek.SpeedReport) -> Output | Reject:
    t = _host_time(ctx, rec.where)
    if t is None:
        return Reject(rec.where, f"{rec.sentence} carries no time and the line has no host timestamp")
    d = math.radians(rec.direction_deg)
    vel = (rec.speed_mps * math.cos(d), rec.speed_mps * math.sin(d), NAN)
    msg = message(ctx, t, "EARTH_NED", vel, altitude=rec.distance_m,
                  valid=math.isfinite(vel[0]) and math.isfinite(vel[1]),
                  fom=rec.figure_of_merit, source=f"nortek:{rec.sentence}")
    return output(ctx, "dvl", msg, t, rec.where)


def _nortek_beams(ctx: LogContext, beams: list[nortek.BeamReport], angle: float
                  ) -> Iterator[Output | Reject]:
    """Per-beam sentences of one ping: ranges and altitude only (beam velocities not rotated)."""
    first = beams[0]
    t = first.time_ns + ctx.clock_offset_ns if first.time_ns is not None else _host_time(ctx, first.where)
    if t is None:
        yield Reject(first.where, f"{first.sentence}: invalid date/time and no host timestamp")
        return
    vertical = [NAN] * 4
    for b in beams:
        if 1 <= b.beam <= 4:
            vertical[b.beam - 1] = b.distance_m
    slant, alt = ranges_from_vertical(vertical, angle)
    msg = message(ctx, t, frame_option(ctx, "INSTRUMENT"), (NAN, NAN, NAN), ranges=slant,
                  altitude=alt, valid=False, source=f"nortek:{first.sentence}")
    yield output(ctx, "dvl", msg, t, first.where)


# --- Water Linked -------------------------------------------------------------------------


def convert_waterlinked(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """Water Linked wrz/wru (and wrx/wrt) serial or TCP JSON; dvl_frame default BODY_FRD."""
    frame = frame_option(ctx, "BODY_FRD")
    angle = beam_angle(ctx)
    pending: waterlinked.VelocityReport | None = None
    beams: dict[int, float] = {}
    for rec in waterlinked.decode(data, ctx.prefix):
        if isinstance(rec, Reject):
            yield rec
        elif isinstance(rec, waterlinked.VelocityReport):
            if pending is not None:
                yield _wl_output(ctx, pending, beams, frame, angle)
            pending, beams = rec, {t.id: t.distance_m for t in rec.transducers}
        elif isinstance(rec, waterlinked.TransducerReport):
            beams[rec.id] = rec.distance_m  # serial wru lines follow their wrz
        elif isinstance(rec, waterlinked.LegacyDistances):
            beams.update(enumerate(rec.distance_m))
    if pending is not None:
        yield _wl_output(ctx, pending, beams, frame, angle)


def _wl_output(ctx: LogContext, rec: waterlinked.VelocityReport, beams: dict[int, float],
               frame: str, angle: float) -> Output | Reject:
    tov = rec.time_of_validity_us
    device = tov * 1000 if tov is not None and tov >= _EARLIEST_US else None
    in_container = bool(ctx.options.get(CONTAINER_TIME))
    t = _host_time(ctx, rec.where)
    if device is not None and not (in_container and t is not None):
        t = device + ctx.clock_offset_ns
    if t is None:
        return Reject(rec.where, f"{rec.source}: no time of validity (clock unset?) and no host timestamp")
    slant = [beams.get(i, NAN) for i in range(max(4, len(beams)))] if beams else []
    slant, alt = ranges_from_slant(slant, angle)
    if math.isfinite(rec.altitude_m):
        alt = rec.altitude_m
    # an altitude of -1 and no beam giving one: no bottom in range (message()'s rule for a negative altitude)
    good = rec.valid and all(math.isfinite(v) for v in rec.velocity_mps) and math.isfinite(alt)
    msg = message(ctx, t, frame, rec.velocity_mps, ranges=slant, altitude=alt, valid=good,
                  fom=rec.figure_of_merit, source=f"waterlinked:{rec.source}")
    if in_container and device is not None:   # the message is on the container's clock: the DVL's kept beside
        set_timestamp(msg.device_time, device + ctx.clock_offset_ns)
    return output(ctx, "dvl", msg, t, rec.where)


CONVERTERS: dict[str, Converter] = {
    "pd0": convert_pd0,
    "pd4": convert_pd4,
    "pd5": convert_pd4,
    "pd6": convert_pd6,
    "nortek": convert_nortek,
    "waterlinked": convert_waterlinked,
}
# the formats whose logs are (or may be) binary: read as bytes, never cut into lines (`recorders.registry`)
BINARY_FORMATS = frozenset({"pd0", "pd4", "pd5"})
# the formats whose logs are converted block by block, in bounded memory (`recorders.base.blockwise`)
BLOCK_CONVERTERS: dict[str, BlockConverter] = {
    "pd6": blockwise(convert_pd6), "nortek": blockwise(convert_nortek), "waterlinked": blockwise(convert_waterlinked),
}
