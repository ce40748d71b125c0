"""`recorders.gps.convert_nmea` over `formats.nmea.columns`: epochs, positions and covariances as arrays.

The same messages as the per-line fast path (and so as
tests/reference_converters.py's `convert_nmea_reference`), for clean logs of the types `formats.nmea.columns`
takes: epochs are runs of one time of day (ms; a sentence without a time
joins the run it arrives in), found with numpy; per epoch only the two
protobuf messages and their Outputs are built in Python. Logs where an epoch
would close on a repeated sentence type inside one time of day, or with no
time at all, get None, and the per-line path.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from formats import schemas as S
from formats.nmea.columns import KINDS, NmeaColumns
from formats.nmea.sentences import KNOT_MPS
from formats.records import Reject, Where
from formats.units import DAY_NS, NS

from .base import Batch, Columns, Ignored, LogContext, Output, batched
from .clock import DayClock, date_to_ns
from .gnss_covariance import fix_covariance_columns
from .gnss_velocity import NO_VELOCITY, SUFFIX, components_column
from .nmea_epochs import vtg_valid

NAN = float("nan")


def _epochs(cols: NmeaColumns) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(first sentence, first timed sentence of each epoch; epoch of each sentence), or None.

    None when a type repeats within one time (the sequential rule would split
    there) or when no sentence has a time.
    """
    timed = np.flatnonzero(~np.isnan(cols.tod))
    if not len(timed):
        return None
    # an untimed sentence (VTG, HDT, THS) joins the open epoch: it takes the time before it,
    # or the first time in the log when it comes before any (the epoch's time is then still open)
    every = len(timed) == len(cols.tod)
    if every:
        t_ms = np.rint(cols.tod * 1000.0)
    else:
        fill = np.zeros(len(cols.tod), dtype=np.int64)
        fill[timed] = timed
        np.maximum.accumulate(fill, out=fill)
        fill[: timed[0]] = timed[0]
        t_ms = np.rint(cols.tod[fill] * 1000.0)
    new = np.ones(len(t_ms), dtype=bool)
    new[1:] = t_ms[1:] != t_ms[:-1]
    epoch = np.cumsum(new) - 1
    for rows in cols.rows.values():
        if (np.diff(epoch[rows]) <= 0).any():
            return None  # the type repeats inside an epoch: it would split there (sequential rule)
    starts = np.flatnonzero(new)
    first_timed = starts if every else timed[np.flatnonzero(np.diff(epoch[timed], prepend=-1))]
    return starts, first_timed, epoch


def _member(n: int, epoch: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """For each epoch, the index of its sentence of one type among that type's sentences, else -1."""
    out = np.full(n, -1, dtype=np.int64)
    out[epoch[rows]] = np.arange(len(rows))
    return out


def _times(first_tod: list[float], dates: list, date_tods: list[float], silent: list[bool], clock: DayClock
           ) -> list[int | None]:
    """`DayClock.set_date` (where an epoch has a date) then `resolve` of each epoch's first time, inline.

    A silent epoch (a ZDA alone) sets the date and resolves nothing, as `gps._scan_outputs` does. The clock
    is left as those calls would leave it, for the next block of the log.
    """
    day, last, offset, half = clock.day_ns, clock._last_tod_ns, clock.offset_ns, DAY_NS // 2
    out: list[int | None] = []
    for tod, d, dtod, quiet in zip(first_tod, dates, date_tods, silent):
        if d is not None:
            day, last = date_to_ns(d), round(dtod * NS)
        if day is None or quiet:
            out.append(None)
            continue
        tod_ns = round(tod * NS)
        if last is not None and tod_ns < last - half:
            day += DAY_NS
        elif last is not None and tod_ns > last + half:
            day -= DAY_NS
        last = tod_ns
        out.append(day + tod_ns + offset)
    clock.day_ns, clock._last_tod_ns = day, last
    return out


def _sources(kind: np.ndarray, starts: np.ndarray) -> list[str]:
    """'nmea:RMC,VTG,GGA' per epoch: the types in arrival order."""
    sig = np.zeros(len(starts), dtype=np.int64)
    ends = np.append(starts[1:], len(kind))
    # 4 bits a sentence: codes 1..8; an epoch holds each type at most once, so 32 bits at most
    for p in range(int((ends - starts).max())):
        at = starts + p
        inside = at < ends
        sig += np.where(inside, kind[np.minimum(at, len(kind) - 1)] + 1, 0) << (4 * p)
    names = {}
    for s in np.unique(sig).tolist():
        parts, v = [], s
        while v:
            parts.append(KINDS[(v & 15) - 1])
            v >>= 4
        names[s] = "nmea:" + ",".join(parts)
    return [names[s] for s in sig.tolist()]


def _pick(values: list | np.ndarray, member: np.ndarray, empty: float | str) -> np.ndarray:
    """values[member] per epoch, `empty` where the epoch has no sentence of that type (member -1)."""
    return np.append(np.asarray(values), empty)[member]


def _present(values: list | np.ndarray, member: np.ndarray) -> np.ndarray:
    """values[member] per epoch (a bool column), False where the epoch has no sentence of that type."""
    return _pick(values, member, False).astype(bool)


def last_epoch_start(cols: NmeaColumns) -> int | None:
    """The first sentence of the last epoch of a clean block's columns, or None when the per-line path must run."""
    found = _epochs(cols)
    return None if found is None else int(found[0][-1])


def convert_columns(cols: NmeaColumns, ctx: LogContext, no_date: str, clock: DayClock | None = None,
                    base: int = 0, lines: int = 0) -> Iterator[Output | Reject | Ignored | Batch] | None:
    """The outputs of `convert_nmea` for a clean log's columns; None when the per-line path must run.

    `clock` carries the date from earlier blocks of the log (default: a new one) and is left for the next;
    `base` and `lines` place a block in its log (`formats.log_blocks.Block`).
    """
    found = _epochs(cols)
    if found is None:
        return None
    starts, first_timed, epoch = found
    n = len(starts)
    m = {name: _member(n, epoch, cols.rows[name]) for name in KINDS}
    v = cols.values
    g, r, ll, z = m["GGA"], m["RMC"], m["GLL"], m["ZDA"]
    gv, rv = v["GGA"], v["RMC"]
    has_g = g >= 0
    quality = np.where(has_g, _pick(gv["quality"], g, 0), -1).astype(np.int64)
    glat, glon = _pick(gv["lat"], g, NAN), _pick(gv["lon"], g, NAN)
    gga_pos = has_g & (quality != 0) & ~np.isnan(glat) & ~np.isnan(glon)
    llat, llon = _pick(v["GLL"]["lat"], ll, NAN), _pick(v["GLL"]["lon"], ll, NAN)
    gll_pos = ~gga_pos & _present(v["GLL"]["valid"], ll) & ~np.isnan(llat) & ~np.isnan(llon)
    valid = _present(rv["valid"], r)
    rlat, rlon = _pick(rv["lat"], r, NAN), _pick(rv["lon"], r, NAN)
    rmc_pos = ~gga_pos & ~gll_pos & valid & ~np.isnan(rlat) & ~np.isnan(rlon)
    msl, sep = _pick(gv["alt"], g, NAN), _pick(gv["sep"], g, NAN)
    alt = np.where(gga_pos, np.where(np.isnan(sep), msl, msl + sep), NAN)
    lat = np.where(gga_pos, glat, np.where(gll_pos, llat, rlat))
    lon = np.where(gga_pos, glon, np.where(gll_pos, llon, rlon))
    source = np.where(gga_pos, _pick(cols.rows["GGA"], g, 0), np.where(
        gll_pos, _pick(cols.rows["GLL"], ll, 0), np.where(rmc_pos, _pick(cols.rows["RMC"], r, 0), starts)))
    hdop = _pick(gv["hdop"], g, NAN)
    cov_rows, cov_kind, cov_known = _covariance(v["GST"], m["GST"], hdop, quality, ctx)
    dates, date_tods = _dates(cols, z, r, valid)
    alone = np.diff(np.append(starts, len(cols.kind))) == 1
    silent = (alone & (z >= 0)).tolist() if len(cols.rows["ZDA"]) else [False] * n
    times = _times(cols.tod[first_timed].tolist(), dates, date_tods, silent, clock or _clock(ctx))
    speed, course, heading = _motion(v, m, valid)
    satellites = np.where(has_g, _pick(gv["satellites"], g, 0), -1).astype(np.int64)
    sources = _sources(cols.kind, starts)
    has_pos = gga_pos | gll_pos | rmc_pos
    north, east, moving = _velocity(speed, course, (m["VTG"] >= 0) | (r >= 0))
    offsets, numbers = (cols.offsets + base, cols.numbers + lines) if base or lines else (cols.offsets, cols.numbers)

    def outputs() -> Iterator[Output | Reject | Ignored]:
        status = zip(quality.tolist(), satellites.tolist(), hdop.tolist(),
                     sources, speed.tolist(), course.tolist(), heading.tolist())
        velocity = zip(moving, north.tolist(), east.tolist())
        cov = [tuple(row) if known else None for row, known in zip(cov_rows.tolist(), cov_known.tolist())]
        fix = zip(has_pos.tolist(), lat.tolist(), lon.tolist(), alt.tolist(), cov, cov_kind.tolist())
        where = zip(offsets[source].tolist(), numbers[source].tolist())
        first = zip(offsets[first_timed].tolist(), numbers[first_timed].tolist(), cols.tod[first_timed].tolist())
        return _emit(ctx, times, silent, fix, status, velocity, where, first, no_date)

    if not ctx.batches or any(t is None and not quiet for t, quiet in zip(times, silent)):
        return outputs()  # a Reject among them: message by message
    columns = {"frame_id": ctx.vehicle, "fix_quality": quality, "satellites": satellites, "hdop": hdop,
               "speed_over_ground_mps": speed, "course_over_ground_deg": course, "heading_deg": heading}
    batch = _batch(ctx, times, silent, has_pos, moving, columns, sources, (lat, lon, alt, cov_rows, cov_kind),
                   (north, east), offsets[source], outputs)
    return batched(ctx, batch)


def _batch(ctx: LogContext, times: list, silent: list[bool], has_pos: np.ndarray, moving: list, status: dict,
           sources: list[str], fix: tuple, velocity: tuple, keys: np.ndarray,
           outputs: Callable[[], Iterator[Output | Reject | Ignored]]) -> Batch:
    """The epochs' messages as one Batch: per emitted epoch its fix (with a position), status and velocity (when
    moving), in that order, as `_emit` yields them."""
    rows = ~np.asarray(silent, dtype=bool)
    t = np.array([x for x, quiet in zip(times, silent) if not quiet], dtype=np.int64)
    moves = np.array([x is True for x in moving], dtype=bool)[rows]
    pos = has_pos[rows]
    given = np.stack([pos, np.ones(len(t), dtype=bool), moves], axis=1)
    order = np.broadcast_to(np.arange(3), given.shape)[given]
    keys = np.broadcast_to(keys[rows][:, None], given.shape)[given]
    src = [s for s, quiet in zip(sources, silent) if not quiet]
    lat, lon, alt, cov, kind = fix
    vehicle = ctx.vehicle
    fix_cols = {"timestamp": t[pos], "frame_id": vehicle, "latitude": lat[rows][pos], "longitude": lon[rows][pos],
                "altitude": alt[rows][pos],
                "position_covariance": cov[rows][pos], "position_covariance_type": kind[rows][pos]}
    status_cols = {k: (v[rows] if isinstance(v, np.ndarray) else v) for k, v in status.items()}
    status_cols.update(timestamp=t, source_format=src)
    north, east = velocity
    velocity_cols = {"timestamp": t[moves], "frame_id": vehicle, "velocity_north_mps": north[rows][moves],
                     "velocity_east_mps": east[rows][moves], "velocity_up_mps": NAN,
                     "speed_over_ground_mps": status_cols["speed_over_ground_mps"][moves],
                     "course_over_ground_deg": status_cols["course_over_ground_deg"][moves], "speed_std_mps": NAN,
                     "source_format": [s for s, mv in zip(src, moves.tolist()) if mv]}
    parts = [Columns(topic, cls, cols, cols["timestamp"], cols["timestamp"]) for topic, cls, cols in (
        (f"/{vehicle}/gps", S.LocationFix, fix_cols), (f"/{vehicle}/gps/status", S.GnssStatus, status_cols),
        (f"/{vehicle}/{SUFFIX}", S.GnssVelocity, velocity_cols))]
    no_velocity = sum(1 for x, quiet in zip(moving, silent) if x is False and not quiet)
    last = Where(int(keys[-1])) if len(keys) else Where(0)
    return Batch(parts, order, keys, last, outputs, {NO_VELOCITY: no_velocity} if no_velocity else {})


def _dates(cols: NmeaColumns, z: np.ndarray, r: np.ndarray, valid: np.ndarray) -> tuple[list, list[float]]:
    """`gps._scan_date` per epoch: (date or None, its sentence's time of day): ZDA's, else a valid RMC's."""
    zd, rd = cols.values["ZDA"]["date"], cols.values["RMC"]["date"]
    rtod = _pick(cols.tod[cols.rows["RMC"]], r, NAN).tolist()
    if not len(zd):  # the common log: RMC dates only, one comprehension
        return [rd[i] if ok else None for ok, i in zip(valid.tolist(), r.tolist())], rtod
    ztod = _pick(cols.tod[cols.rows["ZDA"]], z, NAN).tolist()
    dates, tods = [], []
    for zi, ri, ok, zt, rt in zip(z.tolist(), r.tolist(), valid.tolist(), ztod, rtod):
        d = zd[zi] if zi >= 0 else None
        if d is not None:
            dates.append(d)
            tods.append(zt)
        else:
            dates.append(rd[ri] if ok else None)
            tods.append(rt)
    return dates, tods


def _motion(v: dict, m: dict, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`gps._scan_motion` per epoch: speed (m/s) and course from a valid VTG, else a valid RMC; heading from HDT,
    else THS."""
    vt, r = m["VTG"], m["RMC"]
    vv = v["VTG"]
    has_v = vt >= 0
    if len(vv["mode"]):  # `nmea_epochs.vtg_valid` and `vtg_speed`, on the distinct modes and in numpy
        ok = {mode: vtg_valid(mode) for mode in set(vv["mode"])}
        has_v &= _present([ok[mode] for mode in vv["mode"]], vt)
        knots, kmh = np.asarray(vv["speed"], dtype=np.float64), np.asarray(vv["kmh"], dtype=np.float64)
        vtg_mps = np.where(np.isnan(knots), kmh / 3.6, knots * KNOT_MPS)
    else:
        vtg_mps = np.zeros(0)
    speed = np.where(has_v, _pick(vtg_mps, vt, NAN),
                     np.where(valid, _pick(v["RMC"]["speed"], r, NAN) * KNOT_MPS, NAN))
    course = np.where(has_v, _pick(vv["course"], vt, NAN),
                      np.where(valid, _pick(v["RMC"]["course"], r, NAN), NAN))
    h, th = m["HDT"], m["THS"]
    if not len(v["HDT"]["heading"]) and not len(v["THS"]["heading"]):
        return speed, course, np.full(len(h), NAN)
    ths_ok = (th >= 0) & (_pick(np.array(v["THS"]["mode"], dtype=object), th, "V") != "V")
    heading = np.where(h >= 0, _pick(v["HDT"]["heading"], h, NAN),
                       np.where(ths_ok, _pick(v["THS"]["heading"], th, NAN), NAN))
    return speed, course, heading


def _velocity(speed: np.ndarray, course: np.ndarray, motion: np.ndarray) -> tuple[np.ndarray, np.ndarray, list]:
    """Per epoch: its north and east components (NaN where none); whether it has a velocity (True), gives none
    though it has a VTG/RMC (False) or has neither (None)."""
    finite = np.isfinite(speed) & np.isfinite(course)
    north, east = np.full(len(speed), NAN), np.full(len(speed), NAN)
    at = np.flatnonzero(finite)
    north[at], east[at] = components_column(speed[at], course[at].tolist())
    given = np.where(finite, 1, np.where(motion, 0, -1)).tolist()
    return north, east, [(None, False, True)[g + 1] for g in given]


def _clock(ctx: LogContext) -> DayClock:
    return DayClock(ctx.trial_date, ctx.clock_offset_ns)


def _covariance(sv: dict, s: np.ndarray, hdop: np.ndarray, quality: np.ndarray, ctx: LogContext
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`fix_covariance` per epoch (`fix_covariance_columns`): GST's sigmas (NaN where the epoch has no GST), else
    GGA's HDOP, else none."""
    lat_std, lon_std, alt_std = (_pick(sv[k], s, NAN).astype(np.float64) for k in ("lat_std", "lon_std", "alt_std"))
    return fix_covariance_columns(lat_std, lon_std, alt_std, hdop.astype(np.float64), quality, ctx.options)


def _emit(ctx: LogContext, times: list, silent: list[bool], fix: zip, status: zip, velocity: zip, where: zip,
          first: zip, no_date: str) -> Iterator[Output | Reject | Ignored]:
    vehicle = ctx.vehicle
    fix_topic, status_topic, velocity_topic = f"/{vehicle}/gps", f"/{vehicle}/gps/status", f"/{vehicle}/{SUFFIX}"
    location_fix, gnss_status, gnss_velocity = S.location_fix, S.gnss_status, S.gnss_velocity
    for t, quiet, (has_pos, lat, lon, alt, cov, kind), (q, sats, hdop, src, speed, course, heading), \
            (moving, north, east), w, f in zip(times, silent, fix, status, velocity, where, first):
        if quiet:
            continue  # a ZDA alone: its date counted, nothing to emit
        if t is None:
            yield Reject(Where(f[0], f[1]), no_date.format(f[2]))
            continue
        here = Where(w[0], w[1], None)
        message = gnss_status(t, vehicle, q, sats, hdop, src, speed, course, heading)
        if has_pos:
            yield Output(fix_topic, location_fix(t, vehicle, lat, lon, alt, cov, kind), t, t, here)
        yield Output(status_topic, message, t, t, here)
        if moving:
            velocity = gnss_velocity(t, vehicle, north, east, NAN, speed, course, NAN, src)
            yield Output(velocity_topic, velocity, t, t, here)
        elif moving is not None:
            yield Ignored(here, NO_VELOCITY)
