"""USBL logs to ``/<node>/usbl`` (`auvreplay.UsblObservation`).

The node is the vehicle whose log it is (a buoy or ship carrying the USBL
head); the target comes from the modem address book. Angles are degrees
(bearing true, clockwise from north; elevation up from horizontal), relative
positions ENU metres, travel time one way; missing values are NaN.

EvoLogics: the USBLLONG, USBLANGLES and USBLPHYD lines of one measurement
(same target, modem measurement times within 1 ms) become ONE observation:
position, range and bearing from USBLLONG (bearing = atan2(E, N)), direction
from USBLANGLES when there is no full fix, and phase differences from
USBLPHYD when the manifest gives the carrier frequency ``carrier_hz``
(phase = 2 pi f x element delay; element layout in formats.evologics). A
USBLPHYD without a fix still gives an observation with only its phases.
``bearing_convention`` = "enu" (default) or "compass" says how USBLANGLES
bearings are measured. Time: the line's host time moved back by the modem's
own lag (current - measurement time) and by the one-way travel time, i.e. the
instant the target transmitted (see recorders.modem). USBLPHYP is parsed only.

regex: groups ``target`` (or ``source``), any of ``travel_time_s``, ``range_m``,
``bearing_deg``, ``elevation_deg``, ``east_m``, ``north_m``, ``up_m``,
``phase_x_rad``, ``phase_y_rad``; bearing and elevation are derived from E/N/U
when the line has a position but no angles.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import partial

from formats import acoustic_messages as AM
from formats import regex_lines as rx
from formats.evologics import notifications as ev
from formats.evologics import scan as evs
from formats.log_blocks import LogText
from formats.records import FormatError, Reject, Where
from formats.scanned import positions
from formats.schemas import UsblObservation, timestamp
from formats.units import NS, archivable_ns

from .base import Batch, BlockConverter, Converter, Ignored, LogContext, Output, Rows, batched, blockwise, output
from .modem import (
    NO_USBL_TIME,
    RegexOptions,
    endpoint,
    measurement_ns,
    option_choice,
    option_float,
    regex_options,
    regex_outputs,
    sound_speed,
    travel_and_range,
    usbl_own_time_ns,
)

SUFFIX = "usbl"
NAN = math.nan
MATCH_S = 1e-3  # USBLPHYD's measurement time differs from USBLLONG's by a microsecond or so


def bearing_elevation(east: float, north: float, up: float) -> tuple[float, float]:
    """(bearing, elevation) in degrees of an ENU vector; NaN when it has no direction."""
    horizontal = math.hypot(east, north)
    if not math.isfinite(horizontal) or (horizontal == 0 and up == 0):
        return NAN, NAN
    return math.degrees(math.atan2(east, north)) % 360.0, math.degrees(math.atan2(up, horizontal))


def observation(t_ns: int, node: str, target: str, fmt: str, v: Mapping[str, float]) -> UsblObservation:
    """A UsblObservation from named values (missing ones NaN)."""

    def g(key: str) -> float:
        return float(v.get(key, NAN))

    return UsblObservation(
        timestamp=timestamp(t_ns), node=node, target=target, travel_time_s=g("travel_time_s"),
        range_m=g("range_m"), bearing_deg=g("bearing_deg"), elevation_deg=g("elevation_deg"),
        phase_x_rad=g("phase_x_rad"), phase_y_rad=g("phase_y_rad"), relative_east_m=g("east_m"),
        relative_north_m=g("north_m"), relative_up_m=g("up_m"), source_format=fmt,
        integrity=g("integrity"), rssi_db=g("rssi_db"),
    )


# ---- EvoLogics

@dataclass(frozen=True)
class UsblOptions:
    carrier_hz: float | None
    convention: str
    c: float


def usbl_options(ctx: LogContext) -> UsblOptions:
    return UsblOptions(
        option_float(ctx, "carrier_hz", None),
        option_choice(ctx, "bearing_convention", ("enu", "compass")),
        sound_speed(ctx),
    )


# ---- EvoLogics, fast path: the same groups and messages over `formats.evologics.scan` tuples

_USBL_KEYWORDS = frozenset(("USBLLONG", "USBLANGLES", "USBLPHYD"))
# where each field sits in a scanned line's values; the three USBL lines start alike (times, then address)
LONG, ANGLES, PHASE_DELAYS = positions(ev.UsblLong), positions(ev.UsblAngles), positions(ev.UsblPhaseDelays)


def _scan_values(parts: dict[str, list], opts: UsblOptions) -> tuple[float, ...]:
    """`_values` on scanned values, as usbl_observation's doubles from travel_time_s on."""
    tt = rng = bearing = elevation = px = py = east = north = up = integrity = rssi = NAN
    fix = parts.get("USBLLONG")
    ang = parts.get("USBLANGLES")
    phyd = parts.get("USBLPHYD")
    if fix is not None:
        tt = fix[LONG.propagation_time_us] * 1e-6
        east, north, up = fix[LONG.east_m], fix[LONG.north_m], fix[LONG.up_m]
        rng, integrity, rssi = tt * opts.c, fix[LONG.integrity], fix[LONG.rssi_db]
        bearing, elevation = bearing_elevation(east, north, up)
    elif ang is not None:
        bearing = ev.bearing_from_vendor(ang[ANGLES.bearing_rad], opts.convention)
        elevation, integrity, rssi = math.degrees(ang[ANGLES.elevation_rad]), ang[ANGLES.integrity], ang[ANGLES.rssi_db]
    if phyd is not None and opts.carrier_hz is not None:
        px, py = ev.phases_from_delays(phyd[PHASE_DELAYS.delays_ns:], opts.carrier_hz)
    return tt, rng, bearing, elevation, px, py, east, north, up, integrity, rssi


IMPLAUSIBLE_FIX = "travel time puts the measurement outside 1970-2200"


def fix_time(arrival: int, travel_s: float) -> int:
    """When the signal left: the arrival less the travel time (the arrival itself when that is not finite)."""
    return arrival - round(travel_s * NS) if math.isfinite(travel_s) else arrival


# UsblObservation's fields in `AM.usbl_observation`'s order after the node: the columns of a Rows of observations
USBL_FIELDS = ("target", "source_format", "travel_time_s", "range_m", "bearing_deg", "elevation_deg", "phase_x_rad",
               "phase_y_rad", "relative_east_m", "relative_north_m", "relative_up_m", "integrity", "rssi_db")


class _ScanEmitter:
    """`_emit` on scanned values, with what is the same for every observation of a log worked out once: each
    observation added to `rows` (as the arguments of `AM.usbl_observation`), or its Reject."""

    def __init__(self, ctx: LogContext, opts: UsblOptions) -> None:
        self.ctx, self.opts = ctx, opts
        self.topic, self.offset_ns = f"/{ctx.vehicle}/{SUFFIX}", ctx.clock_offset_ns
        self.targets: dict[int, str] = {}
        vehicle = ctx.vehicle
        self.rows = Rows(self.topic, UsblObservation, USBL_FIELDS,
                         lambda t, *values: AM.usbl_observation(t, vehicle, *values), {"node": vehicle})

    def __call__(self, first: evs.Scanned, parts: dict[str, list]) -> Reject | None:
        _, v, offset, line, host = first
        if host is None:
            own = usbl_own_time_ns(self.ctx, v[LONG.measurement_time_s])
            if own is None:
                return Reject(Where(offset, line, host), NO_USBL_TIME)
            arrival = own
        else:
            publish = host + self.offset_ns
            arrival = measurement_ns(publish, v[LONG.current_time_s], v[LONG.measurement_time_s])
        values = _scan_values(parts, self.opts)
        t = fix_time(arrival, values[0])
        if not archivable_ns(t):
            return Reject(Where(offset, line, host), IMPLAUSIBLE_FIX)
        if host is None:
            publish = t  # as `output` publishes a record without host time
        address = v[LONG.address]
        target = self.targets.get(address)
        if target is None:
            target = self.targets[address] = self.ctx.vehicle_for_address(address)
        self.rows.add(t, publish, Where(offset, line, host), (target, "evologics", *values))
        return None


def _evologics_scan(data: LogText, ctx: LogContext, opts: UsblOptions) -> Iterator[Output | Reject | Ignored | Batch]:
    emit = _ScanEmitter(ctx, opts)
    rows = emit.rows
    first: evs.Scanned | None = None
    parts: dict[str, list] = {}
    for item in evs.scan(data, ctx.prefix):
        if isinstance(item, Reject):
            yield from batched(ctx, rows.take())
            yield item
            continue
        keyword, v = item[0], item[1]
        if keyword not in _USBL_KEYWORDS:
            continue
        if first is not None:
            # `_Group.accepts`: same target, a kind not yet in the group, measured within MATCH_S
            head = first[1]
            if (v[LONG.address] == head[LONG.address] and keyword not in parts
                    and abs(v[LONG.measurement_time_s] - head[LONG.measurement_time_s]) <= MATCH_S):
                parts[keyword] = v
                continue
            reject = emit(first, parts)
            if reject is not None or rows.full:
                yield from batched(ctx, rows.take())
                if reject is not None:
                    yield reject
        first, parts = item, {keyword: v}
    if first is not None:
        reject = emit(first, parts)
        yield from batched(ctx, rows.take())
        if reject is not None:
            yield reject
    else:
        yield from batched(ctx, rows.take())


def convert_evologics(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
    """EvoLogics USBL log -> one UsblObservation per measurement."""
    return _evologics_scan(data, ctx, usbl_options(ctx))


# ---- user-defined lines

_USBL_VALUES = ("travel_time_s", "range_m", "bearing_deg", "elevation_deg", "east_m", "north_m", "up_m",
                "phase_x_rad", "phase_y_rad")


def _regex_values(values: Mapping[str, float], c: float) -> dict[str, float]:
    v = dict(values)
    if "travel_time_s" in v or "range_m" in v:
        v["travel_time_s"], v["range_m"] = travel_and_range(values, c)
    if "bearing_deg" not in v and {"east_m", "north_m"} <= v.keys():
        v["bearing_deg"], elevation = bearing_elevation(v["east_m"], v["north_m"], v.get("up_m", 0.0))
        if "up_m" in v:
            v.setdefault("elevation_deg", elevation)
    return v


def _regex_observation(ctx: LogContext, opts: RegexOptions, rec: rx.RegexRecord, t: int) -> Output | Reject:
    if not rec.source:
        return Reject(rec.where, "no target: the pattern's 'target' group did not match")
    msg = observation(t, ctx.vehicle, endpoint(ctx, rec.source)[0], "regex", _regex_values(rec.values, opts.c))
    return output(ctx, SUFFIX, msg, t, rec.where)


def convert_regex(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """User-pattern USBL log -> observations; a bad pattern raises FormatError at once."""
    opts = regex_options(ctx, require_range=False)
    names = set(opts.pattern.groupindex)
    if not names & {"target", "source"}:
        raise FormatError(f"{ctx.path}: regex format: a USBL pattern needs a named group 'target'")
    if not names & set(_USBL_VALUES):
        raise FormatError(f"{ctx.path}: regex format: a USBL pattern needs a measurement group, one of {_USBL_VALUES}")
    return regex_outputs(data, ctx, opts, partial(_regex_observation, ctx, opts))


CONVERTERS: dict[str, Converter] = {
    "evologics": convert_evologics,
    "regex": convert_regex,
}
# the formats whose logs are converted block by block, in bounded memory (`recorders.base.blockwise`)
BLOCK_CONVERTERS: dict[str, BlockConverter] = {
    "evologics": blockwise(convert_evologics), "regex": blockwise(convert_regex),
}
