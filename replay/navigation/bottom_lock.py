"""Bottom-lock availability of one DVL and the gaps in it.

A sample has lock when the DVL flags it valid with finite x/y velocity.
A gap is a stretch between two locked samples (or the DVL's first/last
sample) longer than `min_gap_s`: it runs from the last locked sample before
it to the first one after, so a DVL that fell silent counts as a gap too,
and ordinary spacing between pings does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .columns import DvlColumns

__all__ = ["BottomLock", "bottom_lock"]


@dataclass(frozen=True)
class BottomLock:
    """Availability figures, the gaps, and the share of locked samples per time bin (for plotting).

    `sample_share`: locked samples / samples; `time_share`: 1 - gap time /
    the DVL's span (NaN without samples). Gap arrays are in mission seconds;
    `gap_samples` counts the unlocked samples inside each gap. `bin_start_s`
    and `bin_share` give the locked share per `bin_s` bin (NaN in a bin
    without samples).
    """

    samples: int
    locked: int
    sample_share: float
    time_share: float
    span_s: float
    gap_start_s: np.ndarray
    gap_end_s: np.ndarray
    gap_duration_s: np.ndarray
    gap_samples: np.ndarray
    bin_start_s: np.ndarray
    bin_share: np.ndarray
    min_gap_s: float


def bottom_lock(dvl: DvlColumns, min_gap_s: float = 5.0, bin_s: float = 60.0) -> BottomLock:
    """Share of DVL samples with bottom lock, the lock gaps of at least `min_gap_s`, and the share per bin."""
    t = dvl.t_s
    lock = dvl.valid & np.isfinite(dvl.vx_mps) & np.isfinite(dvl.vy_mps)
    n, k = int(t.size), int(lock.sum())
    if n == 0:
        empty = np.empty(0)
        return BottomLock(0, 0, float("nan"), float("nan"), 0.0, empty, empty, empty, np.empty(0, dtype=np.int64),
                          empty, empty, min_gap_s)
    # edges: the DVL's first sample, every locked sample, its last sample
    edges = np.concatenate([[t[0]], t[lock], [t[-1]]])
    start, end = edges[:-1], edges[1:]
    long = (end - start) > min_gap_s
    gs, ge = start[long], end[long]
    # unlocked samples strictly inside each gap (a gap edge at the first/last sample may be unlocked itself)
    unlocked = np.concatenate([[0], np.cumsum(~lock)])
    lo = np.searchsorted(t, gs, side="left")
    hi = np.searchsorted(t, ge, side="right")
    inside = unlocked[hi] - unlocked[lo]
    span = float(t[-1] - t[0])
    if k == 0:
        time_share = 0.0
    else:
        time_share = 1.0 - float((ge - gs).sum()) / span if span > 0 else 1.0
    nbins = max(1, int(np.ceil(span / bin_s))) if span > 0 else 1
    which = np.minimum(((t - t[0]) // bin_s).astype(np.int64), nbins - 1)
    total = np.bincount(which, minlength=nbins)
    good = np.bincount(which, weights=lock.astype(np.float64), minlength=nbins)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > 0, good / total, np.nan)
    return BottomLock(n, k, k / n, time_share, span, gs, ge, ge - gs, inside.astype(np.int64),
                      t[0] + bin_s * np.arange(nbins), share, min_gap_s)
