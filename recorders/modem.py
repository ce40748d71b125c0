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
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import partial
from typing import Any

import numpy as np

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
    blockwise,
    int64_times,
    output,
)
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
    times = event_times(ctx, where, utc_ns)
    if times is None:
        return Ignored(where, NO_EVENT_TIME)
    t, publish = times
    return Output(f"/{ctx.vehicle}/{EVENTS}", event_message(ctx, t, text), t, publish, where)


NO_EVENT_TIME = "modem event without a time (no host timestamp)"


def event_times(ctx: LogContext, where: Where, utc_ns: int | None = None) -> tuple[int, int] | None:
    """A modem event's (log, publish) times: the modem's own time (offset applied) when it gives one, else the
    line's host time; publish the host time when the line has one. None without either."""
    host = host_time(ctx, where)
    t = utc_ns + ctx.clock_offset_ns if utc_ns is not None else host
    return None if t is None else (t, t if host is None else host)


def event_message(ctx: LogContext, t_ns: int, text: str) -> Log:
    """The foxglove.Log of a modem event at `t_ns`."""
    # no line number in the message: a live capture decodes a log in windows, and the same event must come out
    return Log(timestamp=timestamp(t_ns), level=Log.INFO, name=ctx.vehicle, file=ctx.path, message=text)


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
        row = self.row(v, offset, line, host)
        return row if isinstance(row, Reject) else self.output(*row)

    def output(self, t: int, publish: int, where: Where, name: str, heard: int, measurer: int, owtt: float,
               range_m: float) -> Output:
        """The range Output of a `row`."""
        return Output(self.topic, AM.acoustic_range(t, name, self.ctx.vehicle, heard, measurer, owtt, range_m, self.c,
                                                    "ping", "micromodem"), t, publish, where)

    def row(self, v: tuple, offset: int, line: int | None, host: int | None
            ) -> Reject | tuple[int, int, Where, str, int, int, float, float]:
        """A ping reply's range as (time, publish time, where, heard name, heard and measurer addresses, one-way
        travel time, range), or its Reject."""
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
        return t, t if publish is None else publish, Where(offset, line, host), name, heard, measurer, owtt, \
            owtt * self.c


class _ModemRows:
    """A Micro-Modem log's events and ping ranges gathered as rows in arrival order (Ignored items among them),
    taken as one Batch of two parts whose items one by one are `modem_event`'s and `_ScanPings`' Outputs."""

    def __init__(self, ctx: LogContext, ping: _ScanPings):
        self.ctx, self.ping = ctx, ping
        self.topic = f"/{ctx.vehicle}/{EVENTS}"
        self.items: list[Any] = []  # (0, t, publish, where, text) or (1, *ping row), or an Ignored
        self.messages = 0

    @property
    def full(self) -> bool:
        """Whether the rows should be taken now."""
        return self.messages >= ROWS_PER_BATCH

    def event(self, where: Where, text: str, utc_ns: int | None = None) -> None:
        """`modem_event`, as a row."""
        times = event_times(self.ctx, where, utc_ns)
        if times is None:
            self.items.append(Ignored(where, NO_EVENT_TIME))
        else:
            self.items.append((0, times[0], times[1], where, text))
            self.messages += 1

    def add(self, item: Any) -> None:
        """A ping row (`_ScanPings.row`) or an Ignored."""
        if type(item) is Ignored:
            self.items.append(item)
        else:
            self.items.append((1, *item))
            self.messages += 1

    def take(self) -> Batch | None:
        """The rows so far as one Batch (None without any), and a fresh start."""
        items, ctx, ping, topic = self.items, self.ctx, self.ping, self.topic
        if not items:
            return None
        self.items, self.messages = [], 0

        def outputs() -> Iterator[Output | Ignored]:
            for item in items:
                if type(item) is Ignored:
                    yield item
                elif item[0] == 0:
                    _, t, publish, where, text = item
                    yield Output(topic, event_message(ctx, t, text), t, publish, where)
                else:
                    yield ping.output(*item[1:])

        rows: list[tuple] = [item for item in items if type(item) is not Ignored]
        ignored = Counter(item.reason for item in items if type(item) is Ignored)
        last = items[-1].where if type(items[-1]) is Ignored else items[-1][3]
        times, publish = int64_times([r[1] for r in rows]), int64_times([r[2] for r in rows])
        if rows and (times is None or publish is None or not all(
                -2**31 <= r[k] < 2**31 for r in rows if r[0] == 1 for k in (5, 6))):
            return Batch([], np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), last, outputs, one_by_one=True)
        kinds = np.array([r[0] for r in rows], dtype=np.int64)
        parts: list[Columns] = []
        numbers = np.zeros(2, dtype=np.int64)
        for kind in (0, 1):
            mine = [r for r in rows if r[0] == kind]
            if not mine:
                continue
            numbers[kind] = len(parts)
            at = np.flatnonzero(kinds == kind)
            t, p = times[at], publish[at]  # type: ignore[index]
            if kind == 0:
                columns: dict[str, Any] = {"timestamp": t, "level": Log.INFO, "name": ctx.vehicle, "file": ctx.path,
                                           "message": [r[4] for r in mine]}
                parts.append(Columns(topic, Log, columns, t, p))
            else:
                columns = {"timestamp": t, "source": [r[4] for r in mine], "destination": ctx.vehicle,
                           "source_address": np.array([r[5] for r in mine], dtype=np.int64),
                           "destination_address": np.array([r[6] for r in mine], dtype=np.int64),
                           "travel_time_s": np.array([r[7] for r in mine], dtype=np.float64),
                           "range_m": np.array([r[8] for r in mine], dtype=np.float64), "sound_speed_mps": ping.c,
                           "kind": "ping", "source_format": "micromodem"}
                parts.append(Columns(ping.topic, AcousticRange, columns, t, p))
        return Batch(parts, numbers[kinds], np.array([r[3].offset for r in rows], dtype=np.int64), last, outputs,
                     dict(ignored))


def _micromodem_scan(data: LogText, ctx: LogContext, opts: MicromodemOptions
                     ) -> Iterator[Output | Reject | Ignored | Batch]:
    """The log's items; for a consumer of batches (`LogContext.batches`) its events, ping ranges and Ignored items
    gathered as rows (`_ModemRows`), taken before anything else (a Reject, a TOA range) and when full."""
    for item in _micromodem_items(data, ctx, opts):
        if isinstance(item, _ModemRows):
            yield from batched(ctx, item.take())
        else:
            yield item


def _micromodem_items(data: LogText, ctx: LogContext, opts: MicromodemOptions
                      ) -> Iterator[Output | Reject | Ignored | _ModemRows]:
    """The log's items one by one; or, for a consumer of batches, its rows whenever they are to be taken."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    ping = _ScanPings(ctx, opts.c)
    own = ping.own
    rows = _ModemRows(ctx, ping) if ctx.batches else None
    last_src: int | None = None
    for item in mms.scan(data, ctx.prefix, opts.round_trip):
        if isinstance(item, Reject):
            if rows is not None:
                yield rows
            yield item
            continue
        kind, v, offset, line, host = item
        if rows is not None and rows.full:
            yield rows
        if kind == "reply":
            if rows is None:
                yield ping(v, offset, line, host)
                continue
            row = ping.row(v, offset, line, host)
            if isinstance(row, Reject):
                yield rows
                yield row
            else:
                rows.add(row)
        elif kind == "heard" or kind == "sent":
            if kind == "heard":
                src, dest, what, heard_utc = v
                if src not in own:
                    last_src = src
            else:
                (src, dest, what), heard_utc = v, None
            text = micromodem_event_text(kind, src, dest, what)
            if rows is None:
                yield modem_event(ctx, Where(offset, line, host), text, heard_utc)
            else:
                rows.event(Where(offset, line, host), text, heard_utc)
        elif kind == "other":
            ignored = Ignored(Where(offset, line, host), f"${v[0]}: nothing archived")
            if rows is None:
                yield ignored
            else:
                rows.add(ignored)
        elif kind == "date" or kind == "clock":
            if kind == "date":
                day, tod_s = v
                clock.set_date(day, tod_s)
            else:
                (utc_ns,) = v
                set_modem_date(clock, mm.Clock(Where(offset, line, host), utc_ns))
            ignored = Ignored(Where(offset, line, host), MICROMODEM_UNUSED[kind])
            if rows is None:
                yield ignored
            else:
                rows.add(ignored)
        elif kind == "rxstats" or kind == "toa":
            if kind == "rxstats":
                src, tod_s = v
                last_src = src
                arrival = clock.resolve(tod_s) if opts.period_s is not None else None
                heard_src: int | None = src
            else:
                tod_s, utc_ns = v
                arrival = (clock.resolve(tod_s) if tod_s is not None else utc_ns + ctx.clock_offset_ns) \
                    if opts.period_s is not None else None
                heard_src = last_src
            if opts.period_s is not None:
                if rows is not None:
                    yield rows
                yield toa_range(ctx, Where(offset, line, host), arrival, heard_src, opts)
            elif rows is None:
                yield Ignored(Where(offset, line, host), MICROMODEM_UNUSED[kind])
            else:
                rows.add(Ignored(Where(offset, line, host), MICROMODEM_UNUSED[kind]))
    if rows is not None:
        yield rows


def convert_micromodem(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
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
