"""Page's two-sided CUSUM with restart after alarm, and the calibration of its alarm level to a false-alarm rate.

With drift allowance k and alarm level h on a residual x_n:

    S+_n = max(0, S+_{n-1} + x_n - k),   S-_n = max(0, S-_{n-1} - x_n - k)
    alarm when max(S+_n, S-_n) > h; both sums restart at 0 after an alarm

Used by the ``drift_cusum_m`` feature (replay.stack.features) and the
``cusum_drift`` detector (replay.stack.detectors.cusum).
"""

from __future__ import annotations

import math

import numpy as np


class Cusum:
    """A two-sided CUSUM with restart after alarm; `step` returns the statistic and whether it alarmed."""

    def __init__(self, k: float, h: float) -> None:
        """Allowance k and alarm level h, in the residual's unit."""
        self.k = float(k)
        self.h = float(h)
        self.up = 0.0
        self.down = 0.0

    def step(self, x: float, restart: bool = True) -> tuple[float, float, bool]:
        """Add one residual: (S+, S-) after it and whether max exceeds h; a non-finite x leaves the sums as they are.

        With ``restart`` (the default) the sums go back to 0 after an alarm;
        the ``cusum_drift`` detector restarts through `reset` instead, when
        the runner acts on its alarm.
        """
        if math.isfinite(x):
            self.up = max(0.0, self.up + x - self.k)
            self.down = max(0.0, self.down - x - self.k)
        up, down = self.up, self.down
        alarm = max(up, down) > self.h
        if alarm and restart:
            self.reset()
        return up, down, alarm

    def reset(self) -> None:
        """Restart both sums at 0."""
        self.up = 0.0
        self.down = 0.0


def alarm_rate(x: np.ndarray, k: float, h: float) -> float:
    """Fraction of the samples of a residual series at which a restarting CUSUM(k, h) alarms (NaN for none)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return float("nan")
    c = Cusum(k, h)
    return sum(c.step(float(v))[2] for v in x) / x.size


def calibrate_h(series: list[np.ndarray], k: float, target: float, floor: float) -> float:
    """The smallest h >= floor whose alarm rate over the series (normal epochs, in order) is <= target.

    Bisection on h: the alarm rate of a restarting CUSUM falls as h grows
    (not strictly monotone sample by sample, so the result is the bisection's
    upper end, whose rate is checked to be <= target).
    """
    parts = [np.asarray(s, dtype=float) for s in series if np.isfinite(np.asarray(s, dtype=float)).any()]
    if not parts:
        return floor

    def rate(h: float) -> float:
        counts = [alarm_rate(p, k, h) * np.isfinite(p).sum() for p in parts]
        return float(sum(counts) / sum(np.isfinite(p).sum() for p in parts))

    lo, hi = floor, max(floor, 1.0)
    if rate(lo) <= target:
        return lo
    while rate(hi) > target:
        hi *= 2.0
        if hi > 1e6:
            return hi
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if rate(mid) <= target:
            hi = mid
        else:
            lo = mid
    return hi
