"""INS logs into ``/<vehicle>/ins`` (auvreplay.InsState), one message per INS epoch.

Conventions of InsState: heading true, clockwise from north; roll positive
starboard side down (= port side up); pitch positive bow up; longitude in
[-180, 180); depth positive down; velocity north/east/down; NaN when absent.

Epochs (see `recorders.epochs.group_epochs`):

- phins: PHINS writes one burst per output epoch, each sentence type once
  ($HEHDT, $PIXSE ATITUD, POSITI, SPEED_, ..., TIME__, STDHRP, ...). An
  epoch ends at the first sentence whose type already occurred in it (a new
  burst starts), or at the end of the file. Its time is the burst's TIME__
  (with the manifest's trial date; midnight rollover), else the host time of
  its first line. Depth = -POSITI altitude; ATITUD pitch is negated (PHINS:
  positive bow down); $PHTRO fills roll/pitch when ATITUD is absent. An
  epoch with only status words is not emitted.
- pashr: every $PASHR is an epoch (attitude, heading and their sigmas).
- novatel: SPAN INSPVA / INSPVAS / INSPVAX, merged when they share a GPS
  time. Altitude is the ellipsoidal height; depth = -(height - undulation)
  when INSPVAX gives the undulation, else NaN.
- nmea: heading sources ($HEHDT, $--THS, e.g. a gyrocompass) and INS that
  speak NMEA ($INGGA, $INVTG...): grouped like GNSS epochs; heading from
  HDT/THS, position from GGA/GLL/RMC, velocity from VTG/RMC; missing -> NaN.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections.abc import Generator, Iterator

import numpy as np

from formats import pashr, phins, phins_columns
from formats import schemas as S
from formats.log_blocks import Block, LogText, blocks_in
from formats.nmea import sentences as nmea
from formats.novatel import columns as novatel_columns
from formats.novatel import scan as novatel_scan
from formats.records import Reject, Where
from formats.units import DAY_NS, NS

from .base import (
    ROWS_PER_BATCH,
    Batch,
    BlockConverter,
    Converter,
    Ignored,
    LogContext,
    Output,
    Rows,
    batched,
    blockwise,
    columns_batch,
    int64_times,
    output,
)
from .clock import DayClock
from .epochs import host_time_ns
from .gnss_velocity import components
from .nmea_epochs import (
    NmeaEpoch,
    gga_altitude,
    nmea_epoch_time,
    nmea_motion,
    nmea_position,
    nmea_update_date,
    record_epochs,
)
from .novatel_epochs import (
    ColumnEpochs,
    chunks,
    novatel_column_path,
    novatel_publish_ns,
    novatel_scan_epochs,
    novatel_scan_time,
)

NAN = float("nan")


def ins_state(t_ns: int, ctx: LogContext, source: str, status: str = "", /, **values: float) -> S.InsState:
    """An InsState with its status words and every float NaN unless given (proto3 would default them to 0)."""
    if not values.keys() <= _INS_VALUES | _INS_OPTIONAL:
        raise ValueError(f"InsState has no field {sorted(values.keys() - _INS_VALUES - _INS_OPTIONAL)[0]!r}")
    g = values.get
    state = S.ins_state(
        t_ns, ctx.vehicle, source, status, g("latitude", NAN), g("longitude", NAN), g("depth_m", NAN),
        g("roll_deg", NAN), g("pitch_deg", NAN), g("heading_deg", NAN), g("velocity_north_mps", NAN),
        g("velocity_east_mps", NAN), g("velocity_down_mps", NAN), g("heading_std_deg", NAN),
        g("position_std_north_m", NAN), g("position_std_east_m", NAN), g("roll_std_deg", NAN),
        g("pitch_std_deg", NAN), g("altitude_m", NAN),
    )
    for key in _INS_OPTIONAL & values.keys():   # present only where the source gives them (body rates, force)
        setattr(state, key, values[key])
    return state


_INS_VALUES = frozenset((
    "latitude", "longitude", "depth_m", "roll_deg", "pitch_deg", "heading_deg", "velocity_north_mps",
    "velocity_east_mps", "velocity_down_mps", "heading_std_deg", "position_std_north_m", "position_std_east_m",
    "roll_std_deg", "pitch_std_deg", "altitude_m",
))
_INS_OPTIONAL = frozenset((
    "angular_velocity_x_radps", "angular_velocity_y_radps", "angular_velocity_z_radps",
    "linear_acceleration_x_mps2", "linear_acceleration_y_mps2", "linear_acceleration_z_mps2",
))


# ---------------------------------------------------------------- PHINS


# ---------------------------------------------------------------- PHINS, fast path
# The same bursts and messages as `convert_phins_reference`, over `phins.scan`
# tuples (key, values, offset, line, host): one dict per burst, no records.

_NAV_KEYS = ("Heading", "Atitud", "Positi", "Speed", "Phtro")


def _phins_scan_fields(burst: dict[str, phins.Scanned]) -> tuple:
    """`_phins_fields` on scanned values, as S.ins_state's arguments from `status` on."""
    lat = lon = depth = roll = pitch = heading = vn = ve = vd = NAN
    hstd = pn = pe = rstd = pstd = alt = NAN
    words = []
    for key, v, _, _, _ in burst.values():  # v: the record's fields after `where`, in order
        if key == "Heading":
            _, heading_deg, mode = v
            if mode != "V":
                heading = heading_deg
        elif key == "Atitud":
            roll, pitch_bow_down = v
            pitch = -pitch_bow_down
        elif key == "Positi":
            lat, lon, alt = v
            depth = 0.0 - alt
        elif key == "Speed":
            ve, vn, up = v
            vd = 0.0 - up
        elif key == "StdHrp":
            hstd, rstd, pstd = v
        elif key == "StdPos":
            pn, pe, _ = v
        elif key in ("ALGSTS", "STATUS", "HT_STS"):
            _, lsb, msb = v
            words.append(f"{key}={lsb:08X}" + ("" if key == "HT_STS" else f",{msb:08X}"))
    ph = burst.get("Phtro")
    if ph is not None and "Atitud" not in burst:
        pitch, roll = ph[1]  # ATITUD wins wherever it stands in the burst
    return " ".join(words), lat, lon, depth, roll, pitch, heading, vn, ve, vd, hstd, pn, pe, rstd, pstd, alt


def _phins_scan_outputs(burst: dict[str, phins.Scanned], ctx: LogContext, clock: DayClock, rows: Rows
                        ) -> Reject | None:
    """`_phins_outputs` on scanned values: the burst's InsState added to `rows`, or a Reject."""
    if not any(k in burst for k in _NAV_KEYS):
        return None
    first = next(iter(burst.values()))
    stamp = burst.get("Time")
    if stamp is not None and not math.isnan(stamp[1][0]):  # TIME__'s only value: time_s
        t = clock.resolve(stamp[1][0])
        if t is None:
            return Reject(Where(*stamp[2:]), "no date for PHINS TIME__: set the [trial] date in the manifest")
    else:
        t = next((item[4] + ctx.clock_offset_ns for item in burst.values() if item[4] is not None), None)
        if t is None:
            return Reject(Where(*first[2:]), "no time: PHINS burst without TIME__ and without a host timestamp")
    publish = t if first[4] is None else first[4] + ctx.clock_offset_ns
    rows.add(t, publish, Where(*first[2:]), ("phins", *_phins_scan_fields(burst)))
    return None


# InsState's fields in `S.ins_state`'s order after frame_id: the columns of a Rows of INS messages
INS_FIELDS = ("source_format", "status", "latitude", "longitude", "depth_m", "roll_deg", "pitch_deg", "heading_deg",
              "velocity_north_mps", "velocity_east_mps", "velocity_down_mps", "heading_std_deg",
              "position_std_north_m", "position_std_east_m", "roll_std_deg", "pitch_std_deg", "altitude_m")


def ins_rows(ctx: LogContext) -> Rows:
    """A Rows of the log's InsState messages: rows of `S.ins_state`'s arguments after the time and frame."""
    vehicle = ctx.vehicle
    return Rows(f"/{vehicle}/ins", S.InsState, INS_FIELDS,
                lambda t, *values: S.ins_state(t, vehicle, *values), {"frame_id": vehicle})


def convert_phins(data: LogText, ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
    """iXblue/Exail PHINS standard ASCII ($HEHDT, $PIXSE ..., $PHTRO), one InsState per burst.

    A clean block takes the block columns (`formats.phins_columns`), any other the per-line path; the burst
    that may go on in the next block is held open (as scanned sentences), so the bursts are the whole log's
    wherever the blocks are cut.
    """
    phins.check_prefix(ctx.prefix)
    state = _PhinsState(ctx)
    blocks = iter(blocks_in(data))
    block = next(blocks, None)
    while block is not None:
        following = next(blocks, None)
        yield from _phins_block(block, following is None, ctx, state)
        block = following
    reject = _phins_scan_outputs(state.burst, ctx, state.clock, state.rows) if state.burst else None
    yield from _taken(state.rows, ctx, reject)


class _PhinsState:
    """What goes on from one block of a PHINS log to the next: the day clock, the burst still open, the rows."""

    __slots__ = ("clock", "burst", "rows")

    def __init__(self, ctx: LogContext):
        self.clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
        self.burst: dict[str, phins.Scanned] = {}  # {epoch key: scanned tuple} in arrival order
        self.rows = ins_rows(ctx)


def _phins_block(block: Block, last: bool, ctx: LogContext, state: _PhinsState
                 ) -> Iterator[Output | Reject | Ignored | Batch]:
    """One block's outputs; the burst still open at its end (unless `last`) is left in `state`."""
    if state.burst:  # the previous block's last burst: line by line until a sentence closes it
        closed = yield from _phins_lines(phins.scan_block(block, ctx.prefix), ctx, state, until_closed=True)
        if closed is None:
            return
        offset, line = closed
        block = Block(block.data[offset - block.offset:], offset, line - 1)
    cols = phins_columns.decode_columns(block.data)
    if cols is not None:
        taken = _phins_columns_outputs(cols, block, last, ctx, state)
        if taken is not None:
            batches, tail = taken
            yield from _taken(state.rows, ctx)  # rows of an earlier block's lines go first
            for batch in batches:
                yield from batched(ctx, batch)
            if tail is None:
                return
            at, line = tail  # the last burst, which the next block may go on: line by line
            block = Block(block.data[at:], block.offset + at, block.lines + line - 1)
    yield from _phins_lines(phins.scan_block(block, ctx.prefix), ctx, state)


def _bursts(key: np.ndarray) -> list[int]:
    """The first sentence of each burst, for sentences of epoch keys `key` in file order: a burst ends before
    the first sentence whose key it already holds (`convert_phins`' rule, found without a loop over lines)."""
    n = len(key)
    order = np.argsort(key, kind="stable")
    same = key[order[1:]] == key[order[:-1]]
    before = np.full(n, -1, dtype=np.int64)  # the sentence's key seen last at: -1 for its first
    before[order[1:][same]] = order[:-1][same]
    # the burst from s ends at the first i > s with before[i] >= s, which is the first with reach[i] >= s
    # (every j with before[j] >= s lies after s): one bisection per burst on the running maximum
    reach = np.maximum.accumulate(before).tolist()
    starts, s = [], 0
    while s < n:
        starts.append(s)
        s = bisect_left(reach, s, s + 1)
    return starts


def _phins_columns_outputs(cols: phins_columns.PhinsColumns, block: Block, last: bool, ctx: LogContext,
                           state: _PhinsState) -> tuple[list[Batch], tuple[int, int] | None] | None:
    """The Batches of a clean block's bursts and where its last burst starts (offset, line in the block) when
    that is left to the next block (unless `last`); None when the per-line path must run (a burst without
    TIME__ or no date: it words the reject; a time beyond int64)."""
    n = len(cols.key)
    if not n:
        return [], None
    starts = _bursts(cols.key)
    tail = None
    if not last:
        k = starts.pop()
        tail = int(cols.offsets[k]), int(cols.numbers[k])
        n = k
    if not starts:
        return [], tail
    count = len(starts)
    burst = np.repeat(np.arange(count), np.diff(np.append(starts, n)))
    member = {}  # key -> per burst, its sentence's index among that key's sentences, -1 without one
    for name, pos in cols.rows.items():
        pos = pos[:int(np.searchsorted(pos, n))]
        m = member[name] = np.full(count, -1, dtype=np.int64)
        m[burst[pos]] = np.arange(len(pos))
    absent = np.full(count, -1, dtype=np.int64)
    nav = np.zeros(count, dtype=bool)
    for name in _NAV_KEYS:
        nav |= member.get(name, absent) >= 0
    out = np.flatnonzero(nav)
    if not len(out):
        return [], tail
    clock = state.clock
    stamp = member.get("Time", absent)[out]
    if (stamp < 0).any():
        return None  # a burst without TIME__: the per-line path takes the host time or words the reject
    tod = cols.values["Time"]["time_s"][stamp]
    tod_ns = np.rint(tod * NS).astype(np.int64)  # round(tod_s * NS) of `DayClock.resolve`, half to even alike
    last_tod = clock._last_tod_ns
    steps = np.diff(tod_ns) if last_tod is None else np.diff(tod_ns, prepend=last_tod)
    day = clock.day_ns
    if day is None:
        return None  # the per-line path words the reject (no date)
    times: list[int | None]
    if (np.abs(steps) > DAY_NS // 2).any():  # a midnight (or a record from before it): the clock's own steps
        times = [clock.resolve(x) for x in tod.tolist()]
    else:
        base = day + clock.offset_ns
        times = [base + x for x in tod_ns.tolist()]
        clock._last_tod_ns = int(tod_ns[-1])
    t_ns = int64_times(times)
    if t_ns is None:
        return None  # a time beyond int64: the per-line path gives such messages one by one

    def pick(name: str, field: str) -> np.ndarray:
        m = member.get(name)
        if m is None:
            return np.full(len(out), NAN)
        return np.append(np.asarray(cols.values[name][field], dtype=np.float64), NAN)[m[out]]

    def has(name: str) -> np.ndarray:
        return member.get(name, absent)[out] >= 0

    heading = pick("Heading", "heading_deg")
    if "Heading" in member:
        invalid = np.append(np.array(cols.values["Heading"]["mode"]) == "V", False)[member["Heading"][out]]
        heading = np.where(invalid, NAN, heading)
    atitud = has("Atitud")
    roll = pick("Atitud", "roll_port_up_deg")
    pitch = np.where(atitud, -pick("Atitud", "pitch_bow_down_deg"), NAN)
    if "Phtro" in member:  # $PHTRO only where the burst has no ATITUD
        phtro = has("Phtro") & ~atitud
        pitch = np.where(phtro, pick("Phtro", "pitch_bow_up_deg"), pitch)
        roll = np.where(phtro, pick("Phtro", "roll_port_up_deg"), roll)
    alt = pick("Positi", "altitude_m")
    depth = np.where(has("Positi"), 0.0 - alt, NAN)
    up = pick("Speed", "up_mps")
    down = np.where(has("Speed"), 0.0 - up, NAN)
    columns: list[list[str] | np.ndarray] = [
        ["phins"] * len(out), _phins_status(cols, burst, n, count, out), pick("Positi", "latitude"),
        pick("Positi", "longitude"), depth, roll, pitch, heading, pick("Speed", "north_mps"), pick("Speed", "east_mps"),
        down, pick("StdHrp", "heading_std_deg"), pick("StdPos", "lat_std_m"), pick("StdPos", "lon_std_m"),
        pick("StdHrp", "roll_std_deg"), pick("StdHrp", "pitch_std_deg"), alt,
    ]
    first = np.asarray(starts)[out]
    offsets = cols.offsets[first] + block.offset
    lines = cols.numbers[first] + block.lines
    rows, batches = state.rows, []
    for a in range(0, len(out), ROWS_PER_BATCH):
        b = a + ROWS_PER_BATCH
        batches.append(columns_batch(rows.topic, rows.message_class, rows.build, rows.constants, rows.names,
                                     [c[a:b] for c in columns], t_ns[a:b], t_ns[a:b], offsets[a:b], lines[a:b]))
    return batches, tail


def _phins_status(cols: phins_columns.PhinsColumns, burst: np.ndarray, n: int, count: int, out: np.ndarray
                  ) -> list[str]:
    """The status text of each burst in `out`: its status words in arrival order, as `_phins_scan_fields` writes
    them."""
    at, texts = [], []
    for kind in ("ALGSTS", "STATUS", "HT_STS"):
        pos = cols.rows.get(kind)
        if pos is None:
            continue
        pos = pos[:int(np.searchsorted(pos, n))]
        v = cols.values[kind]
        pairs = list(zip(v["lsb"], v["msb"]))[:len(pos)]
        text = {pair: f"{kind}={pair[0]:08X}" + ("" if kind == "HT_STS" else f",{pair[1]:08X}") for pair in set(pairs)}
        at.append(pos)
        texts += [text[pair] for pair in pairs]
    status = np.full(count, "", dtype=object)
    if not at:
        return status[out].tolist()
    where = np.concatenate(at)
    order = np.argsort(where, kind="stable")
    owner = burst[where[order]]
    ordered = np.array(texts, dtype=object)[order]
    if (np.diff(owner) > 0).all():  # at most one status sentence a burst: its text
        status[owner] = ordered
    else:  # several: joined in arrival order
        for b, text in zip(owner.tolist(), ordered.tolist()):
            status[b] = f"{status[b]} {text}" if status[b] else text
    return status[out].tolist()


def _phins_lines(items: Iterator[phins.Scanned | Reject], ctx: LogContext, state: _PhinsState,
                 until_closed: bool = False
                 ) -> Generator[Output | Reject | Ignored | Batch, None, tuple[int, int] | None]:
    """`convert_phins` line by line over `phins.scan` items: any log, damaged ones included.

    The burst still open at the end is left in `state`. With `until_closed`, it stops at the sentence that
    closes the burst open at the start and returns that sentence's (offset, line), not taken: the caller
    goes on from there (unless the sentence shares its line with an item before it: then to the end).
    """
    burst, rows, clock = state.burst, state.rows, state.clock
    previous = -1  # the byte offset of the item before: a line of glued sentences gives several
    for item in items:
        if isinstance(item, Reject):
            previous = item.where.offset
            yield from _taken(rows, ctx, item)
            continue
        if item[0] in burst:  # a repeated sentence starts the next burst (`group_epochs` with no times)
            reject = _phins_scan_outputs(burst, ctx, clock, rows)
            if reject is not None or rows.full:
                yield from _taken(rows, ctx, reject)
            burst = state.burst = {}
            if until_closed and item[2] != previous:
                return item[2], item[3]
        burst[item[0]] = item
        previous = item[2]
    state.burst = burst
    return None


def _taken(rows: Rows, ctx: LogContext, then: Reject | None = None) -> Iterator[Output | Reject | Ignored | Batch]:
    """The rows gathered so far (a Batch, or its Outputs: `batched`), then `then`: the log's items in order."""
    yield from batched(ctx, rows.take())
    if then is not None:
        yield then


# ---------------------------------------------------------------- $PASHR


def convert_pashr(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """$PASHR attitude/heading sentences, one InsState each."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    for r in pashr.decode(data, ctx.prefix):
        if isinstance(r, Reject):
            yield r
            continue
        if not math.isnan(r.time_s):
            t = clock.resolve(r.time_s)
            if t is None:
                yield Reject(r.where, "no date for $PASHR time of day: set the [trial] date in the manifest")
                continue
        else:
            t = host_time_ns([r], ctx)
            if t is None:
                yield Reject(r.where, "no time: $PASHR without time of day or host timestamp")
                continue
        state = ins_state(
            t, ctx, "pashr", f"gnss_quality={r.gnss_quality} ins_status={r.ins_status}",
            heading_deg=r.heading_deg if r.heading_true else NAN, roll_deg=r.roll_deg, pitch_deg=r.pitch_deg,
            roll_std_deg=r.roll_std_deg, pitch_std_deg=r.pitch_std_deg, heading_std_deg=r.heading_std_deg,
        )
        yield output(ctx, "ins", state, t, r.where)


# ---------------------------------------------------------------- NovAtel SPAN


# ---------------------------------------------------------------- NovAtel SPAN, fast path
# The same epochs and messages as `convert_span_reference`, over scanned tuples
# grouped by `novatel_epochs` (values at the record fields' positions).

_SPAN_KINDS = frozenset(("InsPva", "InsPvax"))


def _span_scan_fields(epoch: dict[str, novatel_scan.Scanned]) -> tuple:
    """`_span_fields` on scanned values, as S.ins_state's arguments from `status` on."""
    lat = lon = depth = roll = pitch = heading = vn = ve = vd = hstd = pn = pe = rstd = pstd = alt = NAN
    status = []
    for kind, item in epoch.items():  # in arrival order: a later log overrides, as f.update does
        if kind == "InsPva":
            p = novatel_scan.INS_PVA._make(item[4])
            lat, lon, alt, vn, ve, vd = p.latitude, p.longitude, p.height_m, p.north_mps, p.east_mps, 0.0 - p.up_mps
            roll, pitch, heading = p.roll_deg, p.pitch_deg, p.azimuth_deg
            status.append(p.status)
        else:
            x = novatel_scan.INS_PVAX._make(item[4])
            lat, lon, alt, vn, ve, vd = x.latitude, x.longitude, x.height_m, x.north_mps, x.east_mps, 0.0 - x.up_mps
            roll, pitch, heading = x.roll_deg, x.pitch_deg, x.azimuth_deg
            u = x.undulation_m
            depth = NAN if math.isnan(u) else -(x.height_m - u)
            hstd, rstd, pstd, pn, pe = x.azimuth_std_deg, x.roll_std_deg, x.pitch_std_deg, x.lat_std_m, x.lon_std_m
            status += (x.status, x.position_type)
    return (" ".join(dict.fromkeys(status)), lat, lon, depth, roll, pitch, heading, vn, ve, vd,
            hstd, pn, pe, rstd, pstd, alt)


def convert_span(data: bytes, ctx: LogContext) -> Iterator[Output | Reject | Ignored | Batch]:
    """NovAtel SPAN INSPVA / INSPVAS / INSPVAX logs (ASCII or binary), merged per GPS time.

    For a consumer of batches a clean file takes the column path (`_span_column_batches`), any other the
    per-line one."""
    resume = yield from novatel_column_path(data, ctx, _SPAN_KINDS, _span_column_batches)
    if resume is None:
        return
    rows = ins_rows(ctx)
    for epoch in novatel_scan_epochs(data, ctx, _SPAN_KINDS, resume):
        if isinstance(epoch, Reject):
            yield from _taken(rows, ctx, epoch)
            continue
        t = novatel_scan_time(epoch, ctx)
        if isinstance(t, Reject):
            yield from _taken(rows, ctx, t)
            continue
        items = list(epoch.values())
        source = "novatel:" + ",".join([item[1] for item in items])
        first = items[0]
        rows.add(t, novatel_publish_ns(first, t, ctx), novatel_scan.where_of(first),
                 (source, *_span_scan_fields(epoch)))
        if rows.full:
            yield from _taken(rows, ctx)
    yield from _taken(rows, ctx)


def _span_column_batches(cols: novatel_columns.NovatelColumns, epochs: ColumnEpochs, ctx: LogContext
                         ) -> list[tuple[int, Batch]]:
    """The Batches `convert_span`'s rows would take of a clean block, made from its columns at once, each with its
    first epoch; none where an epoch merges two logs (INSPVA and INSPVAX of one time: `_span_scan_fields` merges
    them, the per-line path does)."""
    if len(epochs.starts) != len(epochs.logs):
        return []
    n = len(epochs.logs)
    out = {name: np.full(n, NAN) for name in INS_FIELDS[2:]}
    status: list[str] = [""] * n
    source: list[str] = [""] * n
    for name in ("INSPVA", "INSPVAS", "INSPVAX"):
        values = cols.values.get(name)
        if values is None:
            continue
        e = np.searchsorted(epochs.logs, cols.rows[name])  # one log an epoch: its position is its epoch
        if name == "INSPVAX":
            lat, lon, height, und, north, east, up, roll, pitch, azimuth = values[2:12]
            stds = dict(zip(("position_std_north_m", "position_std_east_m", "heading_std_deg", "roll_std_deg",
                             "pitch_std_deg"), (values[12], values[13], values[20], values[18], values[19])))
            for k, v in stds.items():
                out[k][e] = v
            out["depth_m"][e] = np.where(np.isnan(und), NAN, -(height - und))  # type: ignore[operator]
            words = [s if s == p else s + " " + p for s, p in zip(values[0], values[1])]
        else:
            lat, lon, height, north, east, up, roll, pitch, azimuth = values[2:11]
            words = values[11]  # type: ignore[assignment]
        for k, v in (("latitude", lat), ("longitude", lon), ("altitude_m", height), ("velocity_north_mps", north),
                     ("velocity_east_mps", east), ("roll_deg", roll), ("pitch_deg", pitch), ("heading_deg", azimuth)):
            out[k][e] = v
        out["velocity_down_mps"][e] = 0.0 - up  # type: ignore[operator]
        for i, w in zip(e.tolist(), words):
            status[i] = w
            source[i] = "novatel:" + name + "A"
    vehicle, t = ctx.vehicle, epochs.t_ns
    logs = epochs.logs
    batches = []
    for a, b in chunks(np.ones(n, dtype=np.int64), ROWS_PER_BATCH):
        columns = [source[a:b], status[a:b], *(out[k][a:b] for k in INS_FIELDS[2:])]
        batches.append((a, columns_batch(
            f"/{vehicle}/ins", S.InsState, lambda t_ns, *v: S.ins_state(t_ns, vehicle, *v), {"frame_id": vehicle},
            INS_FIELDS, columns, t[a:b], t[a:b], cols.offsets[logs[a:b]], cols.numbers[logs[a:b]])))
    return batches


# ---------------------------------------------------------------- NMEA heading / INS-as-NMEA


def _nmea_ins(records: list[nmea.NmeaRecord], ctx: LogContext, clock: DayClock) -> Iterator[Output | Reject]:
    epoch = NmeaEpoch.of(records)
    speed, course, heading = nmea_motion(epoch)
    pos = nmea_position(epoch)
    if math.isnan(heading) and pos is None:
        nmea_update_date(epoch, clock)  # says nothing about the INS, but its date counts
        return
    t = nmea_epoch_time(epoch, clock, ctx)
    if isinstance(t, Reject):
        yield t
        return
    f: dict[str, float] = {"heading_deg": heading}
    if pos is not None:
        f["latitude"], f["longitude"] = pos.latitude, pos.longitude
        if isinstance(pos, nmea.Gga):
            f["altitude_m"] = gga_altitude(pos)
    if math.isfinite(speed) and math.isfinite(course):  # cos(inf) raises
        f["velocity_north_mps"], f["velocity_east_mps"] = components(speed, course)
    source = "nmea:" + ",".join(type(r).__name__.upper() for r in records)
    yield output(ctx, "ins", ins_state(t, ctx, source, **f), t, records[0].where)


def convert_nmea(data: LogText, ctx: LogContext) -> Iterator[Output | Reject]:
    """NMEA heading ($--HDT, $--THS) and position/velocity sentences from an INS or gyrocompass."""
    clock = DayClock(ctx.trial_date, ctx.clock_offset_ns)
    for epoch in record_epochs(data, ctx.prefix):
        if isinstance(epoch, Reject):
            yield epoch
        else:
            yield from _nmea_ins(epoch, ctx, clock)


CONVERTERS: dict[str, Converter] = {
    "phins": convert_phins, "pashr": convert_pashr, "novatel": convert_span, "nmea": convert_nmea,
}
# the formats whose logs are (or may be) binary: read as bytes, never cut into lines (`recorders.registry`)
BINARY_FORMATS = frozenset({"novatel"})  # SPAN binary logs, or their ASCII form
# the formats whose logs are converted block by block, in bounded memory (`recorders.base.blockwise`)
BLOCK_CONVERTERS: dict[str, BlockConverter] = {
    "phins": blockwise(convert_phins), "pashr": blockwise(convert_pashr), "nmea": blockwise(convert_nmea),
}
