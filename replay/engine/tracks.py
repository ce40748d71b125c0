"""Bounded position histories for interpolating a vehicle's position at an instant.

The engine streams an archive in time order and keeps only the last few
seconds of each vehicle's positions, so memory does not grow with the trial.
Positions arrive one at a time (`Track.add`) or as a block's columns
(`Track.extend`, each row tagged with the engine's message number): then a
lookup sees only the rows of the messages the engine has reached
(`Track.horizon`), so a block gives what the messages one by one gave.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left, bisect_right

import numpy as np

from replay.events import Fix


class Horizon:
    """The engine's message number: rows of a block tagged with a later number are not yet visible."""

    __slots__ = ("seq",)

    def __init__(self) -> None:
        self.seq = math.inf


class Track:
    """The recent positions of one vehicle from one source (INS or GPS)."""

    def __init__(self, keep_s: float = 30.0, horizon: Horizon | None = None):
        self.keep_s = keep_s
        self.horizon = horizon
        self._t, self._lat, self._lon, self._depth = array("d"), array("d"), array("d"), array("d")
        self._seq = array("d")     # the engine message number from which each row is visible (non-decreasing)
        self._lo = 0               # rows before _lo are pruned (older than keep_s before the newest)

    def add(self, fix: Fix) -> None:
        """Append a fix; out-of-order fixes older than the newest are dropped (counted by caller)."""
        if not math.isfinite(fix.t_s + fix.lat_rad + fix.lon_rad):   # a NaN or inf anywhere
            return
        if len(self._t) > self._lo and fix.t_s <= self._t[-1]:
            return
        self._t.append(fix.t_s)
        self._lat.append(fix.lat_rad)
        self._lon.append(fix.lon_rad)
        self._depth.append(fix.depth_m)
        self._seq.append(self._seq[-1] if len(self._seq) else 0.0)    # visible now: sorted after any block's
        self._prune(fix.t_s)

    def extend(self, t_s: np.ndarray, lat_rad: np.ndarray, lon_rad: np.ndarray, depth_m: np.ndarray,
               seq: np.ndarray) -> None:
        """Append a block's fixes as `add` would one by one (the same drops), row i visible from message seq[i]."""
        ok = np.isfinite(t_s + lat_rad + lon_rad)
        if not ok.all():
            t_s, lat_rad, lon_rad, depth_m, seq = t_s[ok], lat_rad[ok], lon_rad[ok], depth_m[ok], seq[ok]
        if not t_s.size:
            return
        # a fix is kept when later than every fix before it (kept or not: a dropped one is below a kept one)
        last = self._t[-1] if len(self._t) > self._lo else -math.inf
        if last > -math.inf:
            self._prune(last)      # the rows before this block are all visible by now
        before = np.maximum.accumulate(np.concatenate(([last], t_s[:-1])))
        keep = t_s > before
        if not keep.all():
            t_s, lat_rad, lon_rad, depth_m, seq = t_s[keep], lat_rad[keep], lon_rad[keep], depth_m[keep], seq[keep]
        self._t.frombytes(t_s.astype(float).tobytes())
        self._lat.frombytes(lat_rad.astype(float).tobytes())
        self._lon.frombytes(lon_rad.astype(float).tobytes())
        self._depth.frombytes(depth_m.astype(float).tobytes())
        self._seq.frombytes(seq.astype(float).tobytes())

    def _visible(self) -> int:
        """The end of the rows the engine has reached."""
        h = self.horizon
        n = len(self._t)
        if h is None or h.seq == math.inf or n == self._lo or self._seq[-1] <= h.seq:
            return n
        return bisect_right(self._seq, h.seq, self._lo, n)

    def _prune(self, newest: float) -> None:
        """Forget rows older than keep_s before `newest` (the rows `add` would have dropped by now)."""
        lo = self._lo
        if self._t[lo] < newest - self.keep_s:     # times increase: the first row to keep by bisection
            lo = bisect_left(self._t, newest - self.keep_s, lo, len(self._t))
        self._lo = lo
        if lo > 4096 and lo * 2 > len(self._t):
            for col in (self._t, self._lat, self._lon, self._depth, self._seq):
                del col[:lo]
            self._lo = 0

    @property
    def latest_s(self) -> float:
        """Time of the newest visible fix (-inf when empty)."""
        hi = self._visible()
        return self._t[hi - 1] if hi > self._lo else -math.inf

    def _fix(self, i: int) -> Fix:
        return Fix(self._t[i], self._lat[i], self._lon[i], self._depth[i])

    def at(self, t_s: float, max_gap_s: float) -> Fix | None:
        """Linear interpolation at t between fixes at most max_gap_s apart; None if not covered.

        A time within max_gap_s/2 beyond the last (or before the first) fix takes that fix.
        """
        hi = self._visible()
        if hi == self._lo or not math.isfinite(t_s):
            return None
        self._prune(self._t[hi - 1])
        hi = self._visible()       # the prune may have moved the rows down
        lo = self._lo
        i = bisect_left(self._t, t_s, lo, hi)
        if i < hi and self._t[i] == t_s:
            return self._fix(i)
        if i == lo:
            return self._fix(lo) if self._t[lo] - t_s <= max_gap_s / 2 else None
        if i == hi:
            return self._fix(hi - 1) if t_s - self._t[hi - 1] <= max_gap_s / 2 else None
        ta, tb = self._t[i - 1], self._t[i]
        if tb - ta > max_gap_s:
            return None
        w = (t_s - ta) / (tb - ta)
        la, lb = self._lat[i - 1], self._lat[i]
        oa, ob = self._lon[i - 1], self._lon[i]
        da, db = self._depth[i - 1], self._depth[i]
        dlon = math.remainder(ob - oa, 2 * math.pi)  # across the antimeridian too
        return Fix(t_s, la + w * (lb - la), math.remainder(oa + w * dlon, 2 * math.pi), da + w * (db - da))
