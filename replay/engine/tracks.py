"""Bounded position histories for interpolating a vehicle's position at an instant.

The engine streams an archive in time order and keeps only the last few
seconds of each vehicle's positions, so memory does not grow with the trial.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import deque

from replay.events import Fix


class Track:
    """The recent positions of one vehicle from one source (INS or GPS)."""

    def __init__(self, keep_s: float = 30.0):
        self.keep_s = keep_s
        self._t: deque[float] = deque()
        self._fix: deque[Fix] = deque()

    def add(self, fix: Fix) -> None:
        """Append a fix; out-of-order fixes older than the newest are dropped (counted by caller)."""
        if not math.isfinite(fix.t_s + fix.lat_rad + fix.lon_rad):   # a NaN or inf anywhere
            return
        if self._t and fix.t_s <= self._t[-1]:
            return
        self._t.append(fix.t_s)
        self._fix.append(fix)
        while self._t and self._t[0] < fix.t_s - self.keep_s:
            self._t.popleft()
            self._fix.popleft()

    @property
    def latest_s(self) -> float:
        """Time of the newest fix (-inf when empty)."""
        return self._t[-1] if self._t else -math.inf

    def at(self, t_s: float, max_gap_s: float) -> Fix | None:
        """Linear interpolation at t between fixes at most max_gap_s apart; None if not covered.

        A time within max_gap_s/2 beyond the last (or before the first) fix takes that fix.
        """
        if not self._t or not math.isfinite(t_s):
            return None
        i = bisect_left(self._t, t_s)
        if i < len(self._t) and self._t[i] == t_s:
            return self._fix[i]
        if i == 0:
            f = self._fix[0]
            return f if f.t_s - t_s <= max_gap_s / 2 else None
        if i == len(self._t):
            f = self._fix[-1]
            return f if t_s - f.t_s <= max_gap_s / 2 else None
        a, b = self._fix[i - 1], self._fix[i]
        if b.t_s - a.t_s > max_gap_s:
            return None
        w = (t_s - a.t_s) / (b.t_s - a.t_s)
        dlon = math.remainder(b.lon_rad - a.lon_rad, 2 * math.pi)  # across the antimeridian too
        return Fix(t_s, a.lat_rad + w * (b.lat_rad - a.lat_rad), math.remainder(a.lon_rad + w * dlon, 2 * math.pi),
                   a.depth_m + w * (b.depth_m - a.depth_m))
