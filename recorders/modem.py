"""Acoustic-modem logs to ``/<vehicle>/modem/range`` (`auvreplay.AcousticRange`).

The vehicle whose log it is measured the range (``destination``); ``source``
is the vehicle heard, from the manifest's modem address book. Travel times in
the archive are ONE WAY; ``range_m`` is the slant range travel time x sound
speed (manifest option ``sound_speed_mps``, else the trial's sound speed).

Time of a range (``log_time``): the middle of the acoustic exchange, i.e. the
instant the heard modem transmitted its reply: the reception time minus the
one-way travel time (two-way pings, EvoLogics propagation times and USBL fixes),
or the reception time minus half the travel time (one-way time of arrival).
Reception times come from the sentence when it has one (MM2 $CACMR, $CACST,
$CATOA), else from the line's host timestamp; neither gives a Reject, never the
wall clock. Records are kept in log order, duplicates and all.

What each record produces (everything else is parsed, validated and counted):

- micromodem: $CAMPR and $CACMR,PNR -> kind "ping". Pings commanded ($CCMPC), echoed ($CAMPC) and heard
  ($CAMPA, $CACMA,PNG), data cycles and frames -> ``/<vehicle>/modem/events`` (foxglove.Log, INFO); every
  other record is counted as ignored with its reason. $CACST and $CATOA -> kind
  "toa" only with manifest option ``owtt_period_s`` (synchronous one-way
  ranging: transmissions on multiples of that period plus ``owtt_offset_s``;
  travel time = time of arrival modulo the period; source = the packet's source,
  for $CATOA the last modem heard). ``campr_travel_time = "round_trip"`` halves
  $CAMPR times written as round trips (default "one_way", see formats.micromodem).
- evologics: AT?T propagation-time replies -> kind "ping" to the modem last
  delivered to or heard from; USBLLONG -> kind "usbl".
- regex: every matched line -> kind "user" (the line's own time is used as is).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import partial
from typing import Any

from formats import acoustic_messages as AM
from formats import regex_lines as rx
from formats.evologics import notifications as ev
from formats.evologics import scan as evs
from formats.log_blocks import LogText
from formats.micromodem import scan as mms
from formats.micromodem import sentences as mm
from formats.records import FormatError, Reject, Where
from formats.scanned import positions
from formats.schemas import AcousticRange, Log, timestamp
from formats.units import DAY_NS, NS

from .base import BlockConverter, Converter, Ignored, LogContext, Output, blockwise, output
from .clock import DayClock

SUFFIX = "modem/range"
EVENTS = "modem/events"
NO_USBL_TIME = "no time: EvoLogics line without host timestamp, and its own time is not Unix time"
LONG = positions(ev.UsblLong)  # where each field sits in a scanned USBLLONG's values


# ---- helpers shared with recorders.usbl

def option_float(ctx: LogContext, key: str, default: float | None, positive: bool = True) -> float | None:
    """A numeric manifest option, validated; FormatError names the option when it is unusable."""
    value = ctx.options.get(key, default)
    if value is None:
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise FormatError(f"{ctx.path}: option {key} must be a number, not {value!r}") from None
    if not math.isfinite(number) or (positive and number <= 0):
        raise FormatError(f"{ctx.path}: option {key} must be a positive number, not {value!r}")
    return number


def option_choice(ctx: LogContext, key: str, choices: tuple[str, ...]) -> str:
    """A manifest option restricted to `choices` (the first is the default)."""
    value = ctx.options.get(key, choices[0])
    if value not in choices:
        raise FormatError(f"{ctx.path}: option {key} must be one of {choices}, not {value!r}")
    return str(value)


def sound_speed(ctx: LogContext) -> float:
    """Sound speed (m/s) for this log: manifest option sound_speed_mps, else the trial's."""
    c = option_float(ctx, "sound_speed_mps", ctx.sound_speed_mps)
    assert c is not None
    return c


def host_time(ctx: LogContext, where: Where) -> int | None:
    """The line's host time with the log's clock offset, or None."""
    return None if where.host_time_ns is None else where.host_time_ns + ctx.clock_offset_ns


def own_addresses(ctx: LogContext) -> frozenset[int]:
    """The modem addresses the address book gives this log's vehicle."""
    return frozenset(a for a, v in ctx.address_book.items() if v == ctx.vehicle)


def own_address(ctx: LogContext) -> int:
    """This vehicle's modem address when it has exactly one, else -1."""
    own = own_addresses(ctx)
    return next(iter(own)) if len(own) == 1 else -1


def endpoint(ctx: LogContext, text: str) -> tuple[str, int]:
    """(vehicle name, address) from a regex group holding an address or a vehicle name."""
    text = text.strip()
    if text.isdigit() and len(text) <= 9:  # an address an int32 holds; longer digits are a name
        return ctx.vehicle_for_address(int(text)), int(text)
    addresses = [a for a, v in ctx.address_book.items() if v == text]
    return text, addresses[0] if len(addresses) == 1 else -1


def measurement_ns(host_ns: int, current_s: float, measured_s: float) -> int:
    """An EvoLogics USBL line's host time (offset applied) moved back by the modem's own lag to its measurement."""
    lag = current_s - measured_s
    # the modem clock is its own; trust its lag only when it is plausible
    return host_ns - round(lag * NS) if 0.0 <= lag < 60.0 else host_ns


# current EvoLogics firmware writes USBL times as Unix seconds (1464207778.381274), older as seconds since
# power-on (603.24): only a time in these years is a clock to measure by
_MODEM_EPOCH_S = (946_684_800.0, 4_102_444_800.0)  # 2000-01-01, 2100-01-01


def usbl_own_time_ns(ctx: LogContext, measured_s: float) -> int | None:
    """An EvoLogics USBL line's own measurement time (offset applied) when the modem writes Unix time, else None."""
    if _MODEM_EPOCH_S[0] <= measured_s < _MODEM_EPOCH_S[1]:
        return round(measured_s * 1e6) * 1000 + ctx.clock_offset_ns
    return None


def usbl_reception_ns(ctx: LogContext, where: Where, current_s: float, measured_s: float) -> int | None:
    """Host time of an EvoLogics USBL line moved back to the modem's measurement time (`measurement_ns`);
    without a host timestamp, the modem's own time when it is Unix time (`usbl_own_time_ns`)."""
    host = host_time(ctx, where)
    return usbl_own_time_ns(ctx, measured_s) if host is None else measurement_ns(host, current_s, measured_s)


def acoustic_range(
    ctx: LogContext, t_ns: int, where: Where, heard: tuple[str, int], measurer: tuple[str, int],
    travel_s: float, kind: str, fmt: str, c: float,
) -> Output:
    """An AcousticRange Output on /<vehicle>/modem/range."""
    msg = AcousticRange(
        timestamp=timestamp(t_ns), source=heard[0], destination=measurer[0],
        source_address=heard[1], destination_address=measurer[1], travel_time_s=travel_s,
        range_m=travel_s * c, sound_speed_mps=c, kind=kind, source_format=fmt,
    )
    return output(ctx, SUFFIX, msg, t_ns, where)


# ---- Micro-Modem

@dataclass(frozen=True)
class MicromodemOptions:
    round_trip: bool
    period_s: float | None
    offset_s: float
    c: float


def micromodem_options(ctx: LogContext) -> MicromodemOptions:
    round_trip = option_choice(ctx, "campr_travel_time", ("one_way", "round_trip")) == "round_trip"
    offset = option_float(ctx, "owtt_offset_s", 0.0, positive=False)
    return MicromodemOptions(round_trip, option_float(ctx, "owtt_period_s", None), offset or 0.0, sound_speed(ctx))


def toa_range(ctx: LogContext, where: Where, arrival: int | None, src: int | None,
              opts: MicromodemOptions) -> Output | Reject:
    if arrival is None:
        return Reject(where, "no date: time of arrival without a trial date or a modem date")
    if src is None:
        return Reject(where, "time of arrival before any packet says which modem sent it")
    assert opts.period_s is not None
    tod_s = ((arrival - ctx.clock_offset_ns) % DAY_NS) / NS
    travel = (tod_s - opts.offset_s) % opts.period_s
    t = arrival - round(travel * NS / 2)
    heard = (ctx.vehicle_for_address(src), src)
    return acoustic_range(ctx, t, where, heard, (ctx.vehicle, own_address(ctx)), travel, "toa", "micromodem", opts.c)


def modem_event(ctx: LogContext, where: Where, text: str, utc_ns: int | None = None) -> Output | Ignored:
    """An event of a modem log (a ping sent or heard, a data cycle) on ``/<vehicle>/modem/events``, a
    foxglove.Log at the modem's own time when it gives one, else the line's host time; Ignored, saying so,
    when the line has neither (an event is worth its time)."""
    host = host_time(ctx, where)
    t = utc_ns + ctx.clock_offset_ns if utc_ns is not None else host
    if t is None:
        return Ignored(where, "modem event without a time (no host timestamp)")
    # no line number in the message: a live capture decodes a log in windows, and the same event must come out
    msg = Log(timestamp=timestamp(t), level=Log.INFO, name=ctx.vehicle, file=ctx.path, message=text)
    return Output(f"/{ctx.vehicle}/{EVENTS}", msg, t, t if host is None else host, where)


def micromodem_event_text(kind: str, src: int, dest: int, detail: object) -> str:
    """The words of a Micro-Modem event: kind "sent" (detail: the modem's echo or not) or "heard" (detail: what)."""
    if kind == "sent":
        return f"ping {src} -> {dest} " + ("echoed by the modem" if detail else "commanded by the host")
    what = {"ping": "ping", "cycle": "data cycle", "data": "data frame"}.get(str(detail), str(detail))
    return f"{what} {src} -> {dest} heard"


MICROMODEM_UNUSED = {  # records that time others or carry nothing archived: counted with these reasons
    "date": "$CAXST: sets the modem's date",
    "clock": "$CACLK: sets the modem's date",
    "rxstats": "$CACST without owtt_period_s: no one-way range",
    "toa": "$CATOA without owtt_period_s: no one-way range",
}


def set_modem_date(clock: DayClock, rec: mm.TransmitStats | mm.Clock) -> None:
    if isinstance(rec, mm.TransmitStats):
        clock.set_date(rec.date, rec.tod_s)
        return
    dt = datetime.fromtimestamp(rec.utc_ns // NS, tz=UTC)
    clock.set_date(dt.date(), (rec.utc_ns % DAY_NS) / NS)


# ---- Micro-Modem, fast path: the same ranges over `formats.micromodem.scan` tuples

class _ScanPings:
    """`_ping` on scanned values, with what is the same for every range of a log worked out once."""

    def __init__(self, ctx: LogContext, c: float) -> None:
        self.ctx, self.c, self.own = ctx, c, own_addresses(ctx)
        self.topic, self.offset_ns = f"/{ctx.vehicle}/{SUFFIX}", ctx.clock_offset_ns
        self.names: dict[int, str] = {}

    def __call__(self, v: tuple, offset: int, line: int | None, host: int | None) -> Output | Reject:
        heard, measurer, owtt, utc = v
        own = self.own
        if own and heard in own and measurer not in own:
            heard, measurer = measurer, heard  # firmware that writes the pinger first
        elif own and measurer not in own:
            return Reject(Where(offset, line, host),
                          f"ping reply between modems {heard} and {measurer}: neither is {self.ctx.vehicle}'s")
        publish = None if host is None else host + self.offset_ns
        arrival = utc + self.offset_ns if utc is not None else publish
        if arrival is None:
            return Reject(Where(offset, line, host),
                          "no time: the ping reply carries none and the line has no host timestamp")
        t = arrival - round(owtt * NS)
        name = self.names.get(heard)
        if name is None:
            name = self.names[heard] = self.ctx.vehicle_for_address(heard)
        msg = AM.acoustic_range(t, name, self.ctx.vehicle, heard, measurer, owtt, owtt * self.c, self.c, "ping",
                                "micromodem")
        return Output(self.topic, msg, t, t if publish is None else publish, Where(offset, line, host))


def _micromodem_scan(data: LogText, ctx: LogContext, opts: MicromodemOptions) -> Iterator[Output | Reject | Ignored]:
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    ping = _ScanPings(ctx, opts.c)
    own = ping.own
    last_src: int | None = None
    for item in mms.scan(data, ctx.prefix, opts.round_trip):
        if isinstance(item, Reject):
            yield item
            continue
        kind, v, offset, line, host = item
        if kind == "reply":
            yield ping(v, offset, line, host)
        elif kind == "heard":
            src, dest, what, heard_utc = v
            if src not in own:
                last_src = src
            yield modem_event(ctx, Where(offset, line, host), micromodem_event_text(kind, src, dest, what), heard_utc)
        elif kind == "sent":
            src, dest, echo = v
            yield modem_event(ctx, Where(offset, line, host), micromodem_event_text(kind, src, dest, echo))
        elif kind == "other":
            yield Ignored(Where(offset, line, host), f"${v[0]}: nothing archived")
        elif kind == "date":
            day, tod_s = v
            clock.set_date(day, tod_s)
            yield Ignored(Where(offset, line, host), MICROMODEM_UNUSED[kind])
        elif kind == "clock":
            (utc_ns,) = v
            set_modem_date(clock, mm.Clock(Where(offset, line, host), utc_ns))
            yield Ignored(Where(offset, line, host), MICROMODEM_UNUSED[kind])
        elif kind == "rxstats":
            src, tod_s = v
            last_src = src
            if opts.period_s is not None:
                yield toa_range(ctx, Where(offset, line, host), clock.resolve(tod_s), src, opts)
            else:
                yield Ignored(Where(offset, line, host), MICROMODEM_UNUSED[kind])
        elif kind == "toa":
            tod_s, utc_ns = v
            if opts.period_s is not None:
                arrival = clock.resolve(tod_s) if tod_s is not None else utc_ns + ctx.clock_offset_ns
                yield toa_range(ctx, Where(offset, line, host), arrival, last_src, opts)
            else:
                yield Ignored(Where(offset, line, host), MICROMODEM_UNUSED[kind])


def convert_micromodem(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored]:
    """WHOI Micro-Modem log -> ranges (options are checked before the first record)."""
    return _micromodem_scan(data, ctx, micromodem_options(ctx))


# ---- EvoLogics S2C

MAX_PROPAGATION_US = 1e8  # 100 s one way: far past any acoustic range; more is a parse of garbage


def evologics_problem(us: float, address: int) -> str | None:
    """Why a propagation time or peer address cannot be a measurement (a 400-digit field), or None."""
    if not 0.0 <= us < MAX_PROPAGATION_US:
        return f"propagation time {us:g} us out of range"
    if not -2**31 <= address < 2**31:
        return f"peer address {str(address)[:20]}... out of range"
    return None


def _evologics_scan(data: LogText, ctx: LogContext, c: float) -> Iterator[Output | Reject]:
    """`_evologics` over `formats.evologics.scan` tuples, messages from packed wire bytes."""
    me, address, offset_ns = ctx.vehicle, own_address(ctx), ctx.clock_offset_ns
    topic, names = f"/{me}/{SUFFIX}", dict[int, str]()
    for item in evs.scan(data, ctx.prefix):
        if isinstance(item, Reject):
            yield item
            continue
        keyword, v, offset, line, host = item
        if keyword == "AT?T":
            us, heard = v
            if heard is None:
                yield Reject(Where(offset, line, host),
                             "propagation time before any delivery or reception names the peer")
                continue
            kind = "ping"
        elif keyword == "USBLLONG":
            us, heard, kind = v[LONG.propagation_time_us], v[LONG.address], "usbl"
        else:
            continue
        why = evologics_problem(us, heard)
        if why is not None:
            yield Reject(Where(offset, line, host), why)
            continue
        tt = us * 1e-6
        if host is not None:
            publish = arrival = host + offset_ns
            if kind == "usbl":
                arrival = measurement_ns(publish, v[LONG.current_time_s], v[LONG.measurement_time_s])
            t = arrival - round(tt * NS)
        else:
            own = usbl_own_time_ns(ctx, v[LONG.measurement_time_s]) if kind == "usbl" else None
            if own is None:
                yield Reject(Where(offset, line, host), NO_USBL_TIME if kind == "usbl" else
                             "no time: EvoLogics line without host timestamp")
                continue
            t = publish = own - round(tt * NS)  # the modem's own time; published then, as `output` would
        name = names.get(heard)
        if name is None:
            name = names[heard] = ctx.vehicle_for_address(heard)
        msg = AM.acoustic_range(t, name, me, heard, address, tt, tt * c, c, kind, "evologics")
        yield Output(topic, msg, t, publish, Where(offset, line, host))


def convert_evologics(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """EvoLogics S2C log -> ranges from propagation times and USBL fixes."""
    return _evologics_scan(data, ctx, sound_speed(ctx))


# ---- user-defined lines

@dataclass(frozen=True)
class RegexOptions:
    """A regex log's compiled pattern and reading options, checked up front."""

    pattern: Any
    time_format: str
    scale: float
    c: float


def regex_options(ctx: LogContext, require_range: bool = True) -> RegexOptions:
    """Compile and check the manifest's regex options (FormatError with a clear message)."""
    pattern = rx.compile_pattern(ctx.options.get("pattern"), require_range)
    time_format = option_choice(ctx, "time_format", rx.TIME_FORMATS)
    scale = option_float(ctx, "travel_time_scale", 1.0)
    assert scale is not None
    return RegexOptions(pattern, time_format, scale, sound_speed(ctx))


def regex_time(ctx: LogContext, rec: rx.RegexRecord, clock: DayClock) -> int | Reject:
    """Absolute time (clock offset applied) of a regex record, or a Reject saying why not."""
    if rec.time_ns is not None:
        return rec.time_ns + ctx.clock_offset_ns
    if rec.tod_s is not None:
        if rec.date is not None:
            clock.set_date(rec.date)
        t = clock.resolve(rec.tod_s)
        return t if t is not None else Reject(rec.where, "no date: time of day without a trial date")
    host = host_time(ctx, rec.where)
    return host if host is not None else Reject(rec.where, "no time: no time group and no host timestamp")


def travel_and_range(values: Mapping[str, float], c: float) -> tuple[float, float]:
    """(one-way travel time, slant range) from a line's travel time or, failing that, its range."""
    tt = values.get("travel_time_s", math.nan)
    if math.isfinite(tt):
        return tt, tt * c
    r = values.get("range_m", math.nan)
    return r / c, r


def regex_outputs(data: LogText, ctx: LogContext, opts: RegexOptions,
                  build: Callable[[rx.RegexRecord, int], Output | Reject]) -> Iterator[Output | Reject]:
    """`build(record, time)` for each matched line of a regex log, or a Reject (the line's own or its time's)."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    for rec in rx.decode(data, opts.pattern, opts.time_format, ctx.prefix, opts.scale):
        if isinstance(rec, Reject):
            yield rec
            continue
        t = regex_time(ctx, rec, clock)
        yield t if isinstance(t, Reject) else build(rec, t)


def _regex_range(ctx: LogContext, opts: RegexOptions, rec: rx.RegexRecord, t: int) -> Output | Reject:
    tt, _ = travel_and_range(rec.values, opts.c)
    if not math.isfinite(tt):
        return Reject(rec.where, "no travel time or range on the line")
    if not rec.source:
        return Reject(rec.where, "no source: the pattern's 'source' group did not match")
    measurer = endpoint(ctx, rec.destination) if rec.destination else (ctx.vehicle, own_address(ctx))
    return acoustic_range(ctx, t, rec.where, endpoint(ctx, rec.source), measurer, tt, "user", "regex", opts.c)


def convert_regex(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """User-pattern log -> ranges; a bad pattern raises FormatError at once."""
    opts = regex_options(ctx)
    if "source" not in opts.pattern.groupindex:
        raise FormatError(f"{ctx.path}: regex format: a modem pattern needs a named group 'source'")
    return regex_outputs(data, ctx, opts, partial(_regex_range, ctx, opts))


CONVERTERS: dict[str, Converter] = {
    "micromodem": convert_micromodem,
    "evologics": convert_evologics,
    "regex": convert_regex,
}
# the formats whose logs are converted block by block, in bounded memory (`recorders.base.blockwise`)
BLOCK_CONVERTERS: dict[str, BlockConverter] = {
    "micromodem": blockwise(convert_micromodem), "evologics": blockwise(convert_evologics),
    "regex": blockwise(convert_regex),
}
