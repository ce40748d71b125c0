"""`recorders.gps.convert_nmea` over `formats.nmea_columns`: epochs, positions and covariances as arrays.

The same messages as the per-line fast path (and so as
`convert_nmea_reference`), for clean GGA/GST/RMC logs: epochs are runs of
one time of day (ms), found with numpy; per epoch only the two protobuf
messages and their Outputs are built in Python. Logs where an epoch would
close on a repeated sentence type inside one time of day get None, and the
per-line path.
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from formats import schemas as S
from formats.nmea import KNOT_MPS
from formats.nmea_columns import KINDS, NmeaColumns
from formats.records import Reject, Where

from .base import Output, LogContext
from .clock import DAY_NS, NS, DayClock, date_to_ns

NAN = float("nan")


def _epochs(cols: NmeaColumns) -> tuple[np.ndarray, np.ndarray] | None:
    """(first sentence of each epoch, epoch of each sentence); None when a type repeats within one time."""
    t_ms = np.rint(cols.tod * 1000.0)
    new = np.ones(len(t_ms), dtype=bool)
    new[1:] = t_ms[1:] != t_ms[:-1]
    epoch = np.cumsum(new) - 1
    for rows in cols.rows.values():
        if (np.diff(epoch[rows]) <= 0).any():
            return None  # the type repeats inside an epoch: it would split there (sequential rule)
    return np.flatnonzero(new), epoch


def _member(n: int, epoch: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """For each epoch, the index of its sentence of one type among that type's sentences, else -1."""
    out = np.full(n, -1, dtype=np.int64)
    out[epoch[rows]] = np.arange(len(rows))
    return out


def _times(first_tod: list[float], dates: list, date_tods: list[float], clock: DayClock) -> list[int | None]:
    """`DayClock.set_date` (where an epoch has a date) then `resolve` of each epoch's first time, inline."""
    day, last, offset, half = clock.day_ns, clock._last_tod_ns, clock.offset_ns, DAY_NS // 2
    out: list[int | None] = []
    for tod, d, dtod in zip(first_tod, dates, date_tods):
        if d is not None:
            day, last = date_to_ns(d), round(dtod * NS)
        if day is None:
            out.append(None)
            continue
        tod_ns = round(tod * NS)
        if last is not None and tod_ns < last - half:
            day += DAY_NS
        elif last is not None and tod_ns > last + half:
            day -= DAY_NS
        last = tod_ns
        out.append(day + tod_ns + offset)
    return out


def _sources(kind: np.ndarray, starts: np.ndarray) -> list[str]:
    """'nmea:GGA,GST,RMC' per epoch: the types in arrival order."""
    sig = np.zeros(len(starts), dtype=np.int64)
    ends = np.append(starts[1:], len(kind))
    for p in range(int((ends - starts).max())):
        at = starts + p
        inside = at < ends
        sig += np.where(inside, kind[np.minimum(at, len(kind) - 1)] + 1, 0) << (2 * p)
    names = {}
    for s in np.unique(sig).tolist():
        parts, v = [], s
        while v:
            parts.append(KINDS[(v & 3) - 1])
            v >>= 2
        names[s] = "nmea:" + ",".join(parts)
    return [names[s] for s in sig.tolist()]


def _pick(values: list | np.ndarray, member: np.ndarray, empty: object) -> np.ndarray:
    """values[member] per epoch, `empty` where the epoch has no sentence of that type (member -1)."""
    return np.append(np.asarray(values), empty)[member]


def convert_columns(cols: NmeaColumns, ctx: LogContext, no_date: str) -> Iterator[Output | Reject] | None:
    """The outputs of `convert_nmea` for a clean log's columns; None when the per-line path must run."""
    found = _epochs(cols)
    if found is None:
        return None
    starts, epoch = found
    n = len(starts)
    member = {name: _member(n, epoch, cols.rows[name]) for name in KINDS}
    g, r, s = member["GGA"], member["RMC"], member["GST"]
    gv, rv, sv = cols.values["GGA"], cols.values["RMC"], cols.values["GST"]
    has_g, has_r = g >= 0, r >= 0
    quality = np.where(has_g, _pick(gv["quality"], g, 0), -1).astype(np.int64)
    glat, glon = _pick(gv["lat"], g, NAN), _pick(gv["lon"], g, NAN)
    gga_pos = has_g & (quality != 0) & ~np.isnan(glat) & ~np.isnan(glon)
    valid = has_r & _pick(rv["valid"], r, False)
    rlat, rlon = _pick(rv["lat"], r, NAN), _pick(rv["lon"], r, NAN)
    rmc_pos = ~gga_pos & valid & ~np.isnan(rlat) & ~np.isnan(rlon)
    msl, sep = _pick(gv["alt"], g, NAN), _pick(gv["sep"], g, NAN)
    alt = np.where(gga_pos, np.where(np.isnan(sep), msl, msl + sep), NAN)
    source = np.where(gga_pos, _pick(cols.rows["GGA"], g, 0), np.where(rmc_pos, _pick(cols.rows["RMC"], r, 0), starts))
    hdop = _pick(gv["hdop"], g, NAN)
    cov, cov_kind = _covariance(sv, s, hdop, quality, has_g, ctx)
    dates = [rv["date"][i] if ok else None for ok, i in zip(valid.tolist(), r.tolist())]
    times = _times(cols.tod[starts].tolist(), dates, _pick(cols.tod[cols.rows["RMC"]], r, NAN).tolist(), _clock(ctx))
    speed = np.where(valid, _pick(rv["speed"], r, NAN) * KNOT_MPS, NAN)
    course = np.where(valid, _pick(rv["course"], r, NAN), NAN)
    status = zip(quality.tolist(), np.where(has_g, _pick(gv["satellites"], g, 0), -1).astype(np.int64).tolist(), hdop.tolist(),
                 _sources(cols.kind, starts), speed.tolist(), course.tolist())
    fix = zip((gga_pos | rmc_pos).tolist(), np.where(gga_pos, glat, rlat).tolist(), np.where(gga_pos, glon, rlon).tolist(),
              alt.tolist(), cov, cov_kind)
    where = zip(cols.offsets[source].tolist(), cols.numbers[source].tolist())
    first = zip(cols.offsets[starts].tolist(), cols.numbers[starts].tolist(), cols.tod[starts].tolist())
    return _emit(ctx, times, fix, status, where, first, no_date)


def _clock(ctx: LogContext) -> DayClock:
    return DayClock(ctx.trial_date, ctx.clock_offset_ns)


def _covariance(sv: dict, s: np.ndarray, hdop: np.ndarray, quality: np.ndarray, has_g: np.ndarray, ctx: LogContext
                ) -> tuple[list, list[int]]:
    """`gps._scan_covariance` per epoch: GST's sigmas, else GGA's HDOP times the UERE, else None."""
    from .gps import DEFAULT_UERE_M, UERE_M

    lat_std, lon_std, alt_std = _pick(sv["lat_std"], s, NAN), _pick(sv["lon_std"], s, NAN), _pick(sv["alt_std"], s, NAN)
    known = (s >= 0) & ~np.isnan(lat_std) & ~np.isnan(lon_std)
    approx = ~known & has_g & ~np.isnan(hdop) & (quality > 0)
    m = np.zeros((len(s), 9))
    e, n_, u = lon_std[known], lat_std[known], alt_std[known]
    m[known, 0], m[known, 4], m[known, 8] = e * e, n_ * n_, u * u
    if approx.any():
        uere = {q: float(ctx.options.get("uere_m", UERE_M.get(q, DEFAULT_UERE_M))) for q in np.unique(quality[approx]).tolist()}
        h = hdop[approx] * np.array([uere[q] for q in quality[approx].tolist()])
        m[approx, 0] = m[approx, 4] = h * h / 2
        m[approx, 8] = 4 * h * h
    kind = np.where(known, S.COVARIANCE_DIAGONAL_KNOWN, np.where(approx, S.COVARIANCE_APPROXIMATED, S.COVARIANCE_UNKNOWN))
    rows = m.tolist()
    return [row if k != S.COVARIANCE_UNKNOWN else None for row, k in zip(rows, kind.tolist())], kind.tolist()


def _emit(ctx: LogContext, times: list, fix: zip, status: zip, where: zip, first: zip, no_date: str
          ) -> Iterator[Output | Reject]:
    vehicle = ctx.vehicle
    fix_topic, status_topic = f"/{vehicle}/gps", f"/{vehicle}/gps/status"
    location_fix, gnss_status = S.location_fix, S.gnss_status
    for t, (has_pos, lat, lon, alt, cov, kind), (q, sats, hdop, src, speed, course), w, f in zip(
            times, fix, status, where, first):
        if t is None:
            yield Reject(Where(f[0], f[1]), no_date.format(f[2]))
            continue
        here = Where(w[0], w[1], None)
        message = gnss_status(t, vehicle, q, sats, hdop, src, speed, course, NAN)
        if has_pos:
            yield Output(fix_topic, location_fix(t, vehicle, lat, lon, alt, cov, kind), t, t, here)
        yield Output(status_topic, message, t, t, here)
