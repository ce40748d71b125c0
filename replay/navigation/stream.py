"""The navigation review computed while the replay reads, in bounded memory whatever the mission's length.

`NavigationStream` takes one vehicle's rows in time order (GPS fixes, DVL,
INS, depth) and, every few thousand rows, settles the stretch that can no
longer change: the DVL samples and fixes older than the newest row by more
than the heading gap and the DVL hold (plus 1 s). It runs the same rules as
the whole-mission review (`dead_reckoning`, `drift`, `bottom_lock`,
`series`) on that stretch and carries between stretches only what the rules
read across them: the last DVL sample's velocity state and running
integrals, the last usable DVL sample, the unwrapped heading's running
correction, the INS path's running length, the last bottom-lock edge and the
INS solutions of the last few seconds. The running sums are continued in
the same order as the whole-mission cumulative sums, so the figures are the
same to the bit (tests/test_navigation_stream.py holds them to it).

What it keeps grows with what the review outputs, not with the samples: per
fix its time, errors, DR path and carried seconds and the INS path length
(the DR positions at the fixes are not kept: `DeadReckoning.fix_lat_deg`
and `fix_lon_deg` are empty), per bottom-lock gap and per `lock_bin_s` bin a few numbers,
the DR track one point a second (what the views draw of it) and each series,
at most `series_cap` points (every sample while fewer, then every 2nd, 4th,
... one).
"""

from __future__ import annotations

import math
from array import array
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from formats.mcap_blocks import MessageBlock
from formats.units import NS
from replay.stack.model import horizontal_distance_m

from .bottom_lock import BottomLock
from .columns import BODY_FRD, EARTH_NED, INS_MIN_DT_S, ColumnCollector, InsColumns, VehicleColumns
from .dead_reckoning import DeadReckoning, heading_between, ned_velocity, offset_to_latlon
from .drift import dives, fix_table, ins_before
from .review import NavigationConfig, NavigationReview, SensorCounts, notes
from .series import NavigationSeries, Series

__all__ = ["BLOCK_ROWS", "SERIES_CAP", "NavigationStream", "StreamCollector", "stream_columns"]

BLOCK_ROWS = 4096     # rows buffered before a stretch is settled
SERIES_CAP = 20_000   # points kept per series (a day of 5 Hz DVL is 432,000)
TRACK_S = 1.0         # the DR track is kept one point per this many seconds (the views draw no more)
_TWO_PI = 2.0 * np.pi


class _Decimated:
    """A series of at most `cap` points: every `stride`-th finite sample, the stride doubled when it is full."""

    def __init__(self, cap: int) -> None:
        self.cap, self.stride, self.seen = cap, 1, 0
        self.t: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self.size = 0

    def add(self, t: np.ndarray, v: np.ndarray) -> None:
        keep = np.isfinite(t) & np.isfinite(v)
        t, v = t[keep], v[keep]
        kept = (self.seen + np.arange(t.size)) % self.stride == 0
        self.seen += t.size
        self.t.append(t[kept])
        self.v.append(v[kept])
        self.size += int(kept.sum())
        while self.size > self.cap:      # the kept points are samples 0, stride, 2 stride, ...: keep every other
            tt, vv = self.arrays()
            self.t, self.v, self.stride = [tt[::2]], [vv[::2]], 2 * self.stride
            self.size = int(self.t[0].size)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.t:
            return np.empty(0), np.empty(0)
        return np.concatenate(self.t), np.concatenate(self.v)


@dataclass
class _State:
    """The velocity model at DVL samples (arrays, one row per sample; see `dead_reckoning.VelocityModel`)."""

    g: np.ndarray          # global index of the sample among the DVL's velocity samples
    t: np.ndarray
    vel: np.ndarray        # (n, 4)
    integral: np.ndarray   # (n, 4)
    trust_end: np.ndarray
    bb: np.ndarray         # broken intervals before the sample

    def take(self, i: np.ndarray) -> _State:
        return _State(self.g[i], self.t[i], self.vel[i], self.integral[i], self.trust_end[i], self.bb[i])

    @staticmethod
    def pick(first: _State, second: _State, use_second: np.ndarray) -> _State:
        """Row-wise: `second` where `use_second`, else `first`."""
        w, w2 = use_second, use_second[:, None]
        return _State(np.where(w, second.g, first.g), np.where(w, second.t, first.t),
                      np.where(w2, second.vel, first.vel), np.where(w2, second.integral, first.integral),
                      np.where(w, second.trust_end, first.trust_end), np.where(w, second.bb, first.bb))

    @staticmethod
    def cat(*states: _State) -> _State:
        return _State(*(np.concatenate([getattr(s, f) for s in states]) for f in
                        ("g", "t", "vel", "integral", "trust_end", "bb")))


def _none(n: int) -> _State:
    """States of no sample (global index -1), for fixes before the first DVL sample."""
    return _State(np.full(n, -1), np.full(n, np.nan), np.full((n, 4), np.nan), np.full((n, 4), np.nan),
                  np.full(n, -np.inf), np.zeros(n, dtype=np.int64))


def _integrate(a: _State, b: _State, t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    """∫ from `t_from` (in a's interval) to `t_to` (in b's), NaN where unknown: `VelocityModel.integrate`'s rule."""
    out = np.full(t_from.shape + (4,), np.nan)
    with np.errstate(invalid="ignore"):
        ok = (a.g >= 0) & (b.g >= a.g) & (t_to >= t_from) & (b.bb == a.bb) & np.isfinite(b.vel[:, 0])
        ok &= (t_to <= b.trust_end) & (t_from <= a.trust_end)
    p_to = b.integral[ok] + b.vel[ok] * (t_to[ok] - b.t[ok])[:, None]
    p_from = a.integral[ok] + a.vel[ok] * (t_from[ok] - a.t[ok])[:, None]
    out[ok] = p_to - p_from
    return out


class NavigationStream:
    """One vehicle's navigation review fed row by row in time order (`add`), settled by stretches (`settle`)."""

    def __init__(self, vehicle: str, start_ns: int, config: NavigationConfig | None = None,
                 series_cap: int = SERIES_CAP, block_rows: int = BLOCK_ROWS) -> None:
        """A stream for `vehicle`, times in mission seconds from `start_ns`."""
        self.vehicle, self.start_ns = vehicle, start_ns
        c = self.config = config or NavigationConfig()
        self.block_rows = block_rows
        self._lag = max(c.heading_max_gap_s, c.dvl_hold_s) + 1.0      # how far behind the newest row is settled
        self._keep_s = max(c.heading_max_gap_s, c.ins_max_age_s) + 1.0  # INS kept behind what is settled
        self._rows: dict[str, list[tuple[float, ...]]] = {"gps": [], "dvl": [], "ins": [], "depth": []}
        self.pending = 0
        # fixes: the time of each (the review outputs a row per fix), figures filled as they settle; the
        # positions only of those not settled yet and of the last settled one (the next one's DR starts there)
        self._fix_t = array("d")
        self._fix_ll: list[tuple[float, float]] = []
        self._anchor_ll = (math.nan, math.nan)
        self._fix_bad = 0
        self._out = {k: array("d") for k in ("err", "path", "held", "ins_err")}
        self._path_at = array("d")
        self._path_queue = 0        # first fix whose INS path length is not known yet
        self._anchor: _State | None = None   # the last settled fix's DVL state (its interval)
        # the DVL model carried across stretches
        self._prev: _State | None = None     # the last settled velocity sample
        self._prev_usable = (-1, math.nan, math.nan, 0, math.nan)    # (g, x, y, frame, t) of the last usable one
        self._n_vel = 0
        self._track = (_Decimated(series_cap), _Decimated(series_cap))   # DR latitude and longitude
        self._track_second = -math.inf
        self._settled_fixes = 0
        self._dr_from = -1     # the first settled fix whose DR figures are stored (before any DVL sample: NaN)
        # INS carried: unwrapped heading's last value and running correction, path length, the recent rows
        self._h_last: float | None = None
        self._h_corr: float | None = None
        self._p_last: tuple[float, float, float, float] | None = None   # (t, lat rad, lon rad, running length)
        self._p_first_t = math.nan
        self._p_count = 0
        self._ins = np.empty((0, 9))   # t, lat, lon, heading deg, depth, vn, ve, unwrapped heading, running length
        self._ins_lat_any = False
        # bottom lock
        self._lock_first = math.nan
        self._lock_last = math.nan
        self._edge = (math.nan, 0)     # last edge time and the unlocked samples before it
        self._unlocked = self._locked = self._lock_samples = 0
        self._gaps: list[np.ndarray] = []
        self._bin_total = np.zeros(0, dtype=np.int64)
        self._bin_good = np.zeros(0)
        # counts and series
        self._counts = Counter[str]()
        self._series = {k: _Decimated(series_cap) for k in
                        ("depth_sensor", "depth_ins", "altitude", "heading", "speed_dvl", "speed_ins")}

    # -- feeding ------------------------------------------------------------------------------------------------
    def add(self, kind: str, row: tuple[float, ...]) -> None:
        """One row of `kind` ("gps", "dvl", "ins" or "depth"), in `ColumnCollector`'s layout, in time order."""
        self._rows[kind].append(row)
        self.pending += 1

    def add_rows(self, kind: str, rows: list[tuple[float, ...]]) -> None:
        """Several rows of one kind, in time order (a block's)."""
        self._rows[kind].extend(rows)
        self.pending += len(rows)

    def settle(self, final_until: float) -> None:
        """Settle what no later row can change, knowing that every row before `final_until` (s) has been added."""
        self._step(final_until - self._lag)
        self.pending = sum(len(r) for r in self._rows.values())

    # -- one stretch ----------------------------------------------------------------------------------------------
    def _take(self, kind: str, ncols: int, before: float) -> np.ndarray:
        rows = self._rows[kind]
        n = len(rows)
        if before < math.inf:
            n = next((i for i, r in enumerate(rows) if not r[0] < before), n)
        out = np.array(rows[:n], dtype=np.float64).reshape(-1, ncols)
        del rows[:n]
        return out

    def _step(self, settled: float) -> None:
        final = settled == math.inf
        fixes = self._take("gps", 3, math.inf)
        keep = np.isfinite(fixes).all(axis=1)
        self._fix_bad += int((~keep).sum())
        self._fix_t.extend(fixes[keep, 0].tolist())
        self._fix_ll.extend(zip(fixes[keep, 1].tolist(), fixes[keep, 2].tolist(), strict=True))
        self._path_at.extend([math.nan] * int(keep.sum()))
        depth = self._take("depth", 2, math.inf)
        self._series["depth_sensor"].add(depth[:, 0], depth[:, 1])
        self._ins_rows(self._take("ins", 7, math.inf))
        dvl = self._take("dvl", 6, settled)
        self._dvl_rows(dvl, settled)
        if final:
            self._finish_path()
        else:
            self._trim_ins(settled - self._keep_s)

    def _ins_rows(self, ins: np.ndarray) -> None:
        """New INS rows: heading unwrapped, running path length, the paths at waiting fixes, series."""
        n = ins.shape[0]
        if n == 0:
            return
        t, lat, lon, hdg, depth, vn, ve = ins.T
        self._ins_lat_any |= bool(np.isfinite(lat).any())
        s = self._series
        s["depth_ins"].add(t, depth)
        s["heading"].add(t, np.mod(hdg, 360.0))
        s["speed_ins"].add(t, np.hypot(vn, ve))
        up = np.full(n, np.nan)
        fh = np.isfinite(t) & np.isfinite(hdg)
        if fh.any():   # np.unwrap's steps, its running correction continued from the rows before
            p = np.radians(hdg[fh])
            first = self._h_last is None
            dd = np.diff(p) if first else np.diff(np.concatenate([[self._h_last], p]))
            ddmod = np.mod(dd + np.pi, _TWO_PI) - np.pi
            np.copyto(ddmod, np.pi, where=(ddmod == -np.pi) & (dd > 0))
            correct = ddmod - dd
            np.copyto(correct, 0, where=abs(dd) < np.pi)
            u = p.copy()
            if first:
                run = np.cumsum(correct)
                u[1:] = p[1:] + run
            else:
                run = np.cumsum(np.concatenate([[self._h_corr], correct]))[1:]
                u = p + run
            if run.size:
                self._h_corr = float(run[-1])
            elif first:
                self._h_corr = 0.0
            self._h_last = float(p[-1])
            up[fh] = u
        cum = np.full(n, np.nan)
        fp = np.isfinite(lat) & np.isfinite(lon)
        if fp.any():   # `drift._path_at`'s running length, continued
            tp, la, lo = t[fp], np.radians(lat[fp]), np.radians(lon[fp])
            if self._p_last is None:
                c = np.concatenate([[0.0], np.cumsum(horizontal_distance_m(la[1:], lo[1:], la[:-1], lo[:-1]))])
                self._p_first_t = float(tp[0])
                ext_t, ext_c = tp, c
            else:
                pt, pla, plo, pc = self._p_last
                la2, lo2 = np.concatenate([[pla], la]), np.concatenate([[plo], lo])
                c = np.cumsum(np.concatenate([[pc], horizontal_distance_m(la2[1:], lo2[1:], la2[:-1], lo2[:-1])]))
                ext_t, ext_c = np.concatenate([[pt], tp]), c
                c = c[1:]
            cum[fp] = c
            self._p_count += int(fp.sum())
            self._p_last = (float(tp[-1]), float(la[-1]), float(lo[-1]), float(c[-1]))
            # fixes waiting for an INS solution after them: np.interp between the two around them
            ft = np.frombuffer(self._fix_t, dtype=np.float64)
            q = self._path_queue
            done = q + int(np.searchsorted(ft[q:], ext_t[-1], side="left"))
            if done > q:
                at = ft[q:done]
                out = np.interp(at, ext_t, ext_c)
                out[at < self._p_first_t] = np.nan
                self._path_at[q:done] = array("d", out.tolist())
                self._path_queue = done
            del ft
        self._ins = np.concatenate([self._ins, np.column_stack([ins, up, cum])])

    def _finish_path(self) -> None:
        """The fixes no INS solution came after: the path at the last one (np.interp's end), else unknown."""
        ft = np.frombuffer(self._fix_t, dtype=np.float64)
        q = self._path_queue
        if self._p_last is not None and q < ft.size:
            pt, _, _, pc = self._p_last
            at = ft[q:]
            out = np.where(at == pt, pc, np.nan)
            out[at < self._p_first_t] = np.nan
            self._path_at[q:] = array("d", out.tolist())
        del ft
        self._path_queue = len(self._fix_t)

    def _trim_ins(self, cutoff: float) -> None:
        """Keep the INS rows from `cutoff` on, and before it the last with a heading and the last two with a
        position (all the rules ever look back to)."""
        w = self._ins
        if w.shape[0] == 0:
            return
        keep = w[:, 0] >= cutoff
        old = ~keep
        keep[np.flatnonzero(old & np.isfinite(w[:, 3]))[-1:]] = True
        keep[np.flatnonzero(old & np.isfinite(w[:, 1]) & np.isfinite(w[:, 2]))[-2:]] = True
        self._ins = w[keep]

    def _heading(self, t: np.ndarray) -> np.ndarray:
        w = self._ins
        fh = np.isfinite(w[:, 0]) & np.isfinite(w[:, 3])
        return heading_between(t, w[fh, 0], w[fh, 7], self.config.heading_max_gap_s)

    def _dvl_rows(self, dvl: np.ndarray, settled: float) -> None:
        """Settled DVL rows: series, counts, bottom lock, the velocity model, then the fixes settled with them."""
        t, vx, vy, alt = dvl[:, 0], dvl[:, 1], dvl[:, 2], dvl[:, 3]
        valid, frame = dvl[:, 4] != 0, dvl[:, 5].astype(np.int64)
        fin = np.isfinite(vx) & np.isfinite(vy)
        usable = valid & fin & ((frame == BODY_FRD) | (frame == EARTH_NED))
        ranging = ~np.isfinite(vx) & ~np.isfinite(vy) & np.isfinite(alt)
        lock = (valid & fin) | ranging
        self._series["altitude"].add(t[lock], alt[lock])
        self._series["speed_dvl"].add(t[usable], np.hypot(vx[usable], vy[usable]))
        vel = ~ranging
        self._counts["ranging"] += int(ranging.sum())
        self._counts["velocity"] += int(vel.sum())
        self._counts["unusable"] += int((vel & ~usable).sum())
        t, vx, vy, frame, usable, locked = t[vel], vx[vel], vy[vel], frame[vel], usable[vel], (valid & fin)[vel]
        self._bottom_lock(t, locked)
        g0 = self._n_vel
        ext = self._model(t, vx, vy, frame, usable)
        self._fixes_and_track(ext, g0, settled)

    def _bottom_lock(self, t: np.ndarray, lock: np.ndarray) -> None:
        """`bottom_lock.bottom_lock`'s edges, gaps and bins, continued from the stretch before."""
        if t.size == 0:
            return
        c = self.config
        if math.isnan(self._lock_first):
            self._lock_first = float(t[0])
            self._edge = (float(t[0]), 0)
        unl = np.concatenate([[0], np.cumsum(~lock)]) + self._unlocked
        tl = t[lock]
        lo = unl[np.searchsorted(t, tl, side="left")]
        hi = unl[np.searchsorted(t, tl, side="right")]
        edges = np.concatenate([[self._edge[0]], tl])
        edge_lo = np.concatenate([[self._edge[1]], lo])
        long = (edges[1:] - edges[:-1]) > c.lock_min_gap_s
        if long.any():
            self._gaps.append(np.column_stack([edges[:-1][long], edges[1:][long], (hi - edge_lo[:-1])[long]]))
        if tl.size:
            self._edge = (float(tl[-1]), int(lo[-1]))
        self._unlocked = int(unl[-1])
        self._locked += int(lock.sum())
        self._lock_samples += int(t.size)
        self._lock_last = float(t[-1])
        raw = ((t - self._lock_first) // c.lock_bin_s).astype(np.int64)
        n = int(raw.max()) + 1
        if n > self._bin_total.size:
            self._bin_total = np.concatenate([self._bin_total, np.zeros(n - self._bin_total.size, dtype=np.int64)])
            self._bin_good = np.concatenate([self._bin_good, np.zeros(n - self._bin_good.size)])
        self._bin_total[:n] += np.bincount(raw, minlength=n)
        self._bin_good[:n] += np.bincount(raw, weights=lock.astype(np.float64), minlength=n)

    def _model(self, t: np.ndarray, vx: np.ndarray, vy: np.ndarray, frame: np.ndarray, usable: np.ndarray
               ) -> _State:
        """`dead_reckoning.velocity_model` on settled samples, its running sums continued: the samples' states
        with the last settled sample's before them (when there is one)."""
        c = self.config
        n = t.size
        g0 = self._n_vel
        prev = self._prev
        if n == 0:
            return prev if prev is not None else _none(0)
        pg, px, py, pf, pt = self._prev_usable
        idx = np.where(usable, g0 + np.arange(n), -1)
        last = np.maximum.accumulate(np.concatenate([[pg], idx]))[1:]
        has = last >= 0
        src = np.where(last >= g0, last - g0 + 1, 0)      # 0: the usable sample carried from before
        ext = lambda a, v: np.concatenate([[v], a])  # noqa: E731
        x, y, fr, ts = ext(vx, px)[src], ext(vy, py)[src], ext(frame, pf)[src], ext(t, pt)[src]
        heading = self._heading(t)
        vn, ve = ned_velocity(x, y, fr, heading)
        vn[~has], ve[~has] = np.nan, np.nan
        speed = np.hypot(vn, ve)
        carried = np.where(np.isfinite(vn), (~usable).astype(np.float64), np.nan)
        vel = np.stack([vn, ve, speed, carried], axis=-1)
        trust_end = np.where(has, ts + c.dvl_hold_s, -np.inf)
        if prev is None:   # as the whole-mission cumulative sums: zero at the first sample
            tt, vv, te = t, vel, trust_end
            start_i, start_b = np.zeros((1, 4)), np.zeros(1, dtype=np.int64)
        else:
            tt, vv, te = ext(t, prev.t[-1]), np.concatenate([prev.vel[-1:], vel]), ext(trust_end, prev.trust_end[-1])
            start_i, start_b = prev.integral[-1:], prev.bb[-1:]
        broken = ~np.isfinite(vv[:-1, 0]) | (tt[1:] > te[:-1])
        steps = np.where(broken[:, None], 0.0, vv[:-1] * np.diff(tt)[:, None])
        if prev is None:
            integral = np.concatenate([start_i, np.cumsum(steps, axis=0)])
            bb = np.concatenate([start_b, np.cumsum(broken, dtype=np.int64)])
        else:
            integral = np.cumsum(np.concatenate([start_i, steps]), axis=0)[1:]
            bb = np.cumsum(np.concatenate([start_b, broken.astype(np.int64)]))[1:]
        block = _State(g0 + np.arange(n), t, vel, integral, trust_end, bb)
        if usable.any():
            k = int(np.flatnonzero(usable)[-1])
            self._prev_usable = (g0 + k, float(vx[k]), float(vy[k]), int(frame[k]), float(t[k]))
        self._n_vel += n
        self._prev = block.take(np.array([n - 1]))
        return _State.cat(prev, block) if prev is not None else block

    def _fixes_and_track(self, ext: _State, g0: int, settled: float) -> None:
        """DR and INS errors at the fixes settled now, and the DR track (one point a second) of the new samples."""
        ft_all = np.frombuffer(self._fix_t, dtype=np.float64)
        i0 = self._settled_fixes
        i1 = int(np.searchsorted(ft_all, settled, side="left"))
        ft = ft_all[i0:i1].copy()
        del ft_all
        ll = np.array(self._fix_ll[: i1 - i0], dtype=np.float64).reshape(-1, 2)
        del self._fix_ll[: i1 - i0]
        flat, flon = np.radians(ll[:, 0]), np.radians(ll[:, 1])
        m = ft.size
        n_prev = int(ext.g.size)
        # each fix's interval: the last sample at or before it (a); the last one before it (b)
        ka = np.searchsorted(ext.t, ft, side="right") - 1
        kb = np.searchsorted(ext.t, ft, side="left") - 1
        none = _none(m)
        a = _State.pick(none, ext.take(np.maximum(ka, 0)), ka >= 0) if n_prev else none
        b_lt = _State.pick(none, ext.take(np.maximum(kb, 0)), kb >= 0) if n_prev else none
        if i0 > 0 and self._anchor is not None:
            anchor_prev = self._anchor
            prev_t = np.array([self._fix_t[i0 - 1]])
            prev_lat, prev_lon = np.radians([self._anchor_ll[0]]), np.radians([self._anchor_ll[1]])
        else:
            anchor_prev = _none(1)      # before the first fix: no anchor (a time before any sample)
            prev_t, prev_lat, prev_lon = np.full(1, -np.inf), np.full(1, np.nan), np.full(1, np.nan)
        if m:
            a_from = _State.cat(anchor_prev, a.take(np.arange(m - 1)))
            b = _State.pick(a_from, b_lt, b_lt.g >= a_from.g)
            t_from = np.concatenate([prev_t, ft[:-1]])
            d = _integrate(a_from, b, t_from, ft)
            la, lo = offset_to_latlon(d[:, 0], d[:, 1], np.concatenate([prev_lat, flat[:-1]]),
                                      np.concatenate([prev_lon, flon[:-1]]))
            err = horizontal_distance_m(la, lo, flat, flon)
            path, held = d[:, 2].copy(), d[:, 3].copy()
            if i0 == 0:    # the first fix: nothing ran to it
                err[0] = path[0] = held[0] = np.nan
            w = self._ins
            ins = InsColumns(*(w[:, j] for j in range(7)))
            ilat, ilon = ins_before(ins, ft, self.config.ins_max_age_s)
            ins_err = horizontal_distance_m(np.radians(ilat), np.radians(ilon), flat, flon)
            self._out["ins_err"].extend(ins_err.tolist())
            self._settled_fixes = i1
            if self._n_vel:       # no DVL sample yet: every DR figure is unknown, none is stored
                if self._dr_from < 0:
                    self._dr_from = i0
                for key, values in (("err", err), ("path", path), ("held", held)):
                    self._out[key].extend(values.tolist())
        # the track of the new samples: each anchored at the last fix at or before it
        new = ext.take(np.flatnonzero(ext.g >= g0))
        anchors = _State.cat(anchor_prev, a) if m else anchor_prev
        at = np.concatenate([prev_t, ft])
        alat, alon = np.concatenate([prev_lat, flat]), np.concatenate([prev_lon, flon])
        if m:
            self._anchor = a.take(np.array([m - 1]))
            self._anchor_ll = (float(ll[-1, 0]), float(ll[-1, 1]))
        if new.g.size:
            k = np.searchsorted(at, new.t, side="right") - 1
            on = (k >= 0) & (anchors.g[np.maximum(k, 0)] >= 0)
            if on.any():
                sel = k[on]
                fa = anchors.take(sel)
                ta = new.take(np.flatnonzero(on))
                kb_t = np.searchsorted(ext.t, ta.t, side="left") - 1
                b_t = _State.pick(fa, ext.take(np.maximum(kb_t, 0)), (kb_t >= 0) & (ext.g[np.maximum(kb_t, 0)] >= fa.g))
                d = _integrate(fa, b_t, at[sel], ta.t)
                la, lo = offset_to_latlon(d[:, 0], d[:, 1], alat[sel], alon[sel])
                la, lo, tt = np.degrees(la), np.degrees(lo), ta.t
                ok = np.isfinite(la) & np.isfinite(lo)
                la, lo, tt = la[ok], lo[ok], tt[ok]
                sec = np.floor(tt / TRACK_S)
                first = np.diff(sec, prepend=self._track_second) > 0
                if tt.size:
                    self._track_second = float(sec[-1])
                self._track[0].add(tt[first], la[first])
                self._track[1].add(tt[first], lo[first])

    # -- the end ----------------------------------------------------------------------------------------------------
    def finish(self, dropped: dict[str, int] | None = None) -> NavigationReview:
        """Settle everything and return the review (the same figures as `review_vehicle` on the whole columns)."""
        self._step(math.inf)
        c = self.config
        # views of the stored figures, not copies (a day of fixes every second is 86,400 rows)
        ft = np.frombuffer(self._fix_t, dtype=np.float64)
        o = {k: np.frombuffer(v, dtype=np.float64) for k, v in self._out.items()}
        if self._dr_from != 0:        # the fixes before the first DVL sample: NaN
            before = self._dr_from if self._dr_from > 0 else ft.size
            for k in ("err", "path", "held"):
                o[k] = np.concatenate([np.full(before, np.nan), o[k]])
        path_at = np.frombuffer(self._path_at, dtype=np.float64)
        if self._p_count < 2:
            path_at = np.full(ft.shape, np.nan)
        (track_t, lat), (_, lon) = self._track[0].arrays(), self._track[1].arrays()
        dr = DeadReckoning(track_t, lat, lon, ft, np.empty(0), np.empty(0), o["err"], o["path"],
                           o["held"], c.dvl_hold_s)
        errors = fix_table(ft, o["err"], o["path"], o["held"], o["ins_err"], path_at, c.dive_gap_s)
        dv = dives(errors)
        counts = SensorCounts(self._counts["velocity"], self._counts["unusable"], self._counts["ranging"],
                              self._ins_lat_any)
        drops = Counter(dropped or {})
        if self._fix_bad:
            drops[f"/{self.vehicle}/gps: fixes without a finite position"] += self._fix_bad
        s = self._series
        depth_src = "depth_sensor" if s["depth_sensor"].seen else "depth_ins"
        series = NavigationSeries(
            depth=Series("depth", "m", "depth sensor" if depth_src == "depth_sensor" else "ins",
                         *s[depth_src].arrays()),
            altitude=Series("altitude", "m", "dvl", *s["altitude"].arrays()),
            heading=Series("heading", "deg", "ins", *s["heading"].arrays()),
            speed_dvl=Series("speed over ground", "m/s", "dvl", *s["speed_dvl"].arrays()),
            speed_ins=Series("speed", "m/s", "ins", *s["speed_ins"].arrays()))
        return NavigationReview(
            vehicle=self.vehicle, start_ns=self.start_ns, config=c, columns=None, counts=counts,
            dead_reckoning=dr, fix_errors=errors, dives=dv, bottom_lock=self._lock_figures(), series=series,
            notes=notes(counts, dict(drops), errors, dv, c))

    def _lock_figures(self) -> BottomLock:
        c = self.config
        n, k = self._lock_samples, self._locked
        if n == 0:
            empty = np.empty(0)
            return BottomLock(0, 0, math.nan, math.nan, 0.0, empty, empty, empty, np.empty(0, dtype=np.int64),
                              empty, empty, c.lock_min_gap_s)
        gaps = list(self._gaps)
        edge_t, edge_lo = self._edge
        if self._lock_last - edge_t > c.lock_min_gap_s:   # the last edge: the DVL's last sample
            gaps.append(np.array([[edge_t, self._lock_last, self._unlocked - edge_lo]]))
        g = np.concatenate(gaps) if gaps else np.empty((0, 3))
        gs, ge = g[:, 0].copy(), g[:, 1].copy()
        span = self._lock_last - self._lock_first
        if k == 0:
            time_share = 0.0
        else:
            time_share = 1.0 - float((ge - gs).sum()) / span if span > 0 else 1.0
        nbins = max(1, int(np.ceil(span / c.lock_bin_s))) if span > 0 else 1
        total = np.zeros(nbins, dtype=np.int64)
        good = np.zeros(nbins)
        m = min(nbins, self._bin_total.size)
        total[:m], good[:m] = self._bin_total[:m], self._bin_good[:m]
        total[nbins - 1] += self._bin_total[nbins:].sum()
        good[nbins - 1] += self._bin_good[nbins:].sum()
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(total > 0, good / total, np.nan)
        return BottomLock(n, k, k / n, time_share, span, gs, ge, ge - gs, g[:, 2].astype(np.int64),
                          self._lock_first + c.lock_bin_s * np.arange(nbins), share, c.lock_min_gap_s)


class StreamCollector(ColumnCollector):
    """`ColumnCollector`'s rows (the same messages kept) fed to one `NavigationStream` per vehicle as they pass."""

    def __init__(self, vehicles: list[str], start_ns: int, ins_min_dt_s: float = INS_MIN_DT_S,
                 config: NavigationConfig | None = None, block_rows: int = BLOCK_ROWS,
                 series_cap: int = SERIES_CAP) -> None:
        """Streams for `vehicles`, in seconds from `start_ns`."""
        super().__init__([], start_ns, ins_min_dt_s)
        self.vehicles = list(vehicles)
        self.topics = {f"/{v}/{name}": (v, name) for v in vehicles for name in ("gps", "dvl", "ins", "depth")}
        self._last_ins = dict.fromkeys(vehicles, -math.inf)
        self._held = {v: [] for v in vehicles}
        self.dropped = {v: Counter() for v in vehicles}
        self.streams = {v: NavigationStream(v, start_ns, config, series_cap, block_rows) for v in vehicles}

    def add(self, topic: str, log_time_ns: int, msg: Any) -> None:
        """One message; every `block_rows` rows of a vehicle, what can no longer change is settled."""
        super().add(topic, log_time_ns, msg)
        where = self.topics.get(topic)
        if where is None:
            return
        stream = self.streams[where[0]]
        if stream.pending >= stream.block_rows:
            held = self._held[where[0]]
            until = min(log_time_ns, held[0][0]) if held else log_time_ns   # an INS held back may still come
            stream.settle((until - self.start_ns) / NS)

    def add_block(self, block: MessageBlock) -> None:
        """A block of messages (the replay's block path): its rows as `add` would keep them, then what every row
        up to the block's last message settles."""
        super().add_block(block)
        if len(block.log_ns) == 0:
            return
        last_ns = int(block.log_ns[-1])
        for vehicle, stream in self.streams.items():
            if stream.pending >= stream.block_rows:
                held = self._held[vehicle]
                until = min(last_ns, held[0][0]) if held else last_ns   # an INS held back may still come
                stream.settle((until - self.start_ns) / NS)

    def _store(self, vehicle: str, kind: str, row: tuple[float, ...]) -> None:
        self.streams[vehicle].add(kind, row)

    def _store_dvl_block(self, vehicle: str, cols: tuple[np.ndarray, ...]) -> None:
        self.streams[vehicle].add_rows("dvl", list(zip(*(c.tolist() for c in cols))))

    def review(self, vehicle: str) -> NavigationReview:
        """The review of one vehicle, once: its stream is let go of."""
        return self.streams.pop(vehicle).finish(dict(self.dropped[vehicle]))

    def columns(self, vehicle: str) -> VehicleColumns:
        raise TypeError("StreamCollector keeps no columns: use review()")


def stream_columns(cols: VehicleColumns, vehicle: str, config: NavigationConfig | None = None,
                   block_rows: int = BLOCK_ROWS, series_cap: int = SERIES_CAP) -> NavigationReview:
    """The streamed review of whole-mission columns, fed in time order (to hold it against `review_vehicle`)."""
    s = NavigationStream(vehicle, cols.start_ns, config, series_cap, block_rows)
    d, i = cols.dvl, cols.ins
    parts = [("gps", np.column_stack([cols.fixes.t_s, cols.fixes.lat_deg, cols.fixes.lon_deg])),
             ("dvl", np.column_stack([d.t_s, d.vx_mps, d.vy_mps, d.altitude_m, d.valid, d.frame])),
             ("ins", np.column_stack([i.t_s, i.lat_deg, i.lon_deg, i.heading_deg, i.depth_m, i.vn_mps, i.ve_mps]))]
    if cols.depth is not None:
        parts.append(("depth", np.column_stack([cols.depth.t_s, cols.depth.values])))
    rows = [(float(r[0]), kind, tuple(r.tolist())) for kind, a in parts for r in a]
    rows.sort(key=lambda r: r[0])    # stable: each kind keeps its order
    for t, kind, row in rows:
        s.add(kind, row)
        if s.pending >= block_rows:
            s.settle(t)
    return s.finish(cols.dropped)
