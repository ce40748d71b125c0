"""Ground-truth labels of range epochs (seed A, eqs. A.26-A.27; docs/design.md section 9).

The true range Z_gps comes from the vehicles' GPS fixes interpolated to the
ranging instant; the label is γ = 1 when |Z_gps - Z| > T1, 0 otherwise, and
-1 when no truth is available (no GPS around that instant).
"""

from __future__ import annotations

import math

import numpy as np

from replay.stack.model import horizontal_range

UNKNOWN: int = -1
"""Label of an epoch without GPS truth."""
MAX_GPS_GAP_S: float = 5.0
"""A fix interpolated across a longer gap between GPS fixes is not truth (NaN)."""


def interpolate_track(
    t_query: np.ndarray, t: np.ndarray, lat_rad: np.ndarray, lon_rad: np.ndarray,
    max_gap_s: float = MAX_GPS_GAP_S,
) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation of a (time-sorted) track to query times; NaN outside it or across gaps.

    Non-finite fixes are dropped first. Query times outside [t0, t_end] or
    inside a gap longer than ``max_gap_s`` give NaN.
    """
    t_query = np.asarray(t_query, dtype=float)
    t, lat_rad, lon_rad = (np.asarray(a, dtype=float) for a in (t, lat_rad, lon_rad))
    ok = np.isfinite(t) & np.isfinite(lat_rad) & np.isfinite(lon_rad)
    t, lat_rad, lon_rad = t[ok], lat_rad[ok], lon_rad[ok]
    nan = np.full(t_query.shape, np.nan)
    if t.size == 0:
        return nan, nan.copy()
    order = np.argsort(t, kind="stable")
    t, lat_rad, lon_rad = t[order], lat_rad[order], lon_rad[order]
    lat = np.interp(t_query, t, lat_rad)
    lon = np.interp(t_query, t, lon_rad)
    hi = np.clip(np.searchsorted(t, t_query, side="left"), 0, t.size - 1)
    lo = np.clip(hi - 1, 0, t.size - 1)
    exact = t[hi] == t_query
    gap = np.where(exact, 0.0, t[hi] - t[lo])
    bad = ~np.isfinite(t_query) | (t_query < t[0]) | (t_query > t[-1]) | (gap > max_gap_s)
    lat[bad] = np.nan
    lon[bad] = np.nan
    return lat, lon


def truth_ranges(
    follower_lat_rad: np.ndarray, follower_lon_rad: np.ndarray, follower_depth_m: np.ndarray,
    leader_lat_rad: np.ndarray, leader_lon_rad: np.ndarray, leader_depth_m: np.ndarray,
) -> np.ndarray:
    """Horizontal true ranges Z_gps between interpolated GPS positions (A.4, common radii); NaN propagates."""
    state = np.stack(np.broadcast_arrays(np.asarray(follower_lat_rad, float), np.asarray(follower_lon_rad, float)),
                     axis=-1)
    return horizontal_range(state, np.asarray(follower_depth_m, float), leader_lat_rad, leader_lon_rad,
                            leader_depth_m)


def signed_range_error(range_m: np.ndarray, truth_range_m: np.ndarray) -> np.ndarray:
    """Signed range error Z - Z_gps (m); NaN where there is no truth."""
    return np.asarray(range_m, dtype=float) - np.asarray(truth_range_m, dtype=float)


def range_labels(range_m: np.ndarray, truth_range_m: np.ndarray, t1_m: float) -> np.ndarray:
    """Labels γ (A.27): 1 if |Z_gps - Z| > T1, 0 if not, -1 (UNKNOWN) if either range is not finite."""
    err = np.abs(signed_range_error(range_m, truth_range_m))
    known = np.isfinite(err)
    out = np.full(err.shape, UNKNOWN, dtype=np.int8)
    out[known] = (err[known] > t1_m).astype(np.int8)
    return out


def label_one(range_m: float, truth_range_m: float, t1_m: float) -> int:
    """Scalar form of ``range_labels`` for one epoch (the runner's push path)."""
    err = abs(range_m - truth_range_m)
    if not math.isfinite(err):
        return UNKNOWN
    return int(err > t1_m)
