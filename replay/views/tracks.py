"""Map and local metric plot: every track per vehicle and source, and the range circle of each epoch.

Entities under a run prefix P:
- ``P/map/<vehicle>/<source>/track``  static, faint: the whole track (GeoLineStrings; GeoPoints for
  positioning fixes, whose outliers a line would join across the plot);
- ``P/map/<vehicle>/<source>/trail``  GeoPoints on `time`, small: the blueprint shows them from the
  start up to the cursor (a per-entity visible time range), so the trail ends where the vehicle is;
- ``P/map/<vehicle>/<source>/position``  GeoPoints on `time`: where it is now, labelled
  "<vehicle> <source>" ("leader1 GPS");
- ``P/local/...`` the same in east/north metres (y = -north, see replay.views.common);
- ``P/local/ranges/<follower>/<leader>``  Ellipses2D on `time`: a circle of the
  measured horizontal range around the ranged leader at that instant, red when
  the epoch is labelled anomalous;
- ``P/local/scale`` static: a metre scale bar (replay.views.scale) in the lower left of the
  default bounds (`local_frame`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import rerun as rr

from replay.review.data import ReviewData
from replay.review.scoreboard import method_kind
from replay.views.common import Run, class_id, floats, method_rgb
from replay.views.focus import hidden_methods
from replay.views.scale import log_scale_bar

MAX_STATIC_VERTICES = 4000
GAP_S = 30.0     # a track silent for longer (a dive, a lost link) is drawn as separate strips
KEY = "/colour_key"
KEY_STEP = 1.6
"""The colour key's entity (one for the recording, every run's names in it)."""
TRAIL_STEP_S = 2.0
"""A trail keeps one sample every this many seconds (every sample of sparser tracks)."""
"""The static whole-track line keeps at most this many vertices (every k-th sample, and the last)."""
ANOMALOUS_RGB = (230, 60, 50)
NORMAL_RGB = (120, 170, 230)
UNKNOWN_RGB = (160, 160, 160)


def decimate(n: int, limit: int = MAX_STATIC_VERTICES) -> np.ndarray:
    """Indices of at most `limit` evenly strided samples of n, always keeping the last."""
    if n <= limit:
        return np.arange(n)
    idx = np.arange(0, n, int(np.ceil(n / (limit - 1))))
    return np.append(idx, n - 1) if idx[-1] != n - 1 else idx


def strips(t_s: np.ndarray, points: np.ndarray, gap_s: float = GAP_S) -> list[np.ndarray]:
    """The decimated points as line strips, broken where the track has no sample for more than `gap_s`.

    A GPS silent while its vehicle dives would otherwise draw a straight line across the lake.
    """
    idx = decimate(points.shape[0])
    gaps = np.r_[0, np.cumsum(np.diff(t_s) > gap_s)]      # gaps before each sample, decimated or not
    cuts = np.flatnonzero(np.diff(gaps[idx]) > 0) + 1
    return [points[part] for part in np.split(idx, cuts) if part.size]


def log_tracks(rec: rr.RecordingStream, run: Run, trails: Trails | None = None) -> None:
    """Map and local-plot entities for every (vehicle, source) track of a run; `trails` carries the trails' bins
    from one stretch of a run to the next (replay.views.stream), updated."""
    for (vehicle, source), rows in run.groups(run.review.tracks, ["vehicle", "source"]):
        _log_track(rec, run, str(vehicle), str(source), rows, trails)


def mark_label(vehicle: str, source: str) -> str:
    """How a mark is named on the map and the local plot: 'leader1 GPS', 'follower kmcdf2'."""
    return f"{vehicle} {source.upper() if source in ('gps', 'ins') else source}"


def trail_indices(t_s: np.ndarray, step_s: float = TRAIL_STEP_S, anchor: float | None = None,
                  after: float | None = None) -> np.ndarray:
    """Indices of the first sample in every `step_s` bin of time (all samples when sparser).

    Bins count from `anchor` (default: the first sample); `after` is the bin of an earlier stretch's last
    sample, not started again: a track given in stretches keeps the samples it keeps whole.
    """
    if t_s.size == 0:
        return np.zeros(0, dtype=np.int64)
    bins = np.floor((t_s - (t_s[0] if anchor is None else anchor)) / step_s)
    return np.flatnonzero(np.r_[after is None or bins[0] != after, bins[1:] != bins[:-1]])


Trails = dict[tuple[str, str], tuple[float, float]]
"""Per (vehicle, source), the anchor of its trail's bins and the bin of its last sample (tracks in stretches)."""


def _log_track(rec: rr.RecordingStream, run: Run, vehicle: str, source: str, rows: pd.DataFrame,
               trails: Trails | None = None) -> None:
    lat, lon = floats(rows, "lat_deg"), floats(rows, "lon_deg")
    east, north = floats(rows, "east_m"), floats(rows, "north_m")
    t = floats(rows, "t_s")
    cid, rgb = class_id(source), method_rgb(source, run.index)
    # only GPS marks carry a name ("leader1 GPS"): INS and every estimate sit within metres of their
    # vehicle's GPS and their names would pile up on it (the colour key names them)
    truth = source == "gps"
    faint = (*rgb, 110 if truth else 45)
    # positioning fixes jump (outliers of hundreds of metres): their whole track would hatch the plot
    scatter = method_kind(source) == "positioning"
    size, trail_size = (6.0, 2.0) if truth else (4.5, 1.0)
    times = run.times(rows["t_s"])
    before = trails.get((vehicle, source)) if trails is not None else None
    anchor = before[0] if before else (float(t[0]) if t.size else 0.0)
    trail = trail_indices(t, anchor=anchor, after=before[1] if before else None)
    if trails is not None and t.size:
        trails[(vehicle, source)] = (anchor, float(np.floor((t[-1] - anchor) / TRAIL_STEP_S)))
    trail_times = run.times(t[trail])
    # what is the same on every row (colour, size, name) is logged once, static; the rows carry positions
    geo_ok = np.isfinite(lat) & np.isfinite(lon)
    if geo_ok.any():
        base = run.path("map", vehicle, source)
        ll = np.column_stack([lat[geo_ok], lon[geo_ok]])
        if scatter:
            rec.log(base + "/track", rr.GeoPoints(lat_lon=ll, radii=rr.Radius.ui_points(1.0), colors=[faint]),
                    static=True)
        else:
            rec.log(base + "/track", rr.GeoLineStrings(lat_lon=strips(t[geo_ok], ll), radii=rr.Radius.ui_points(1.0),
                                                       colors=[faint]), static=True)
        rec.log(base + "/position", rr.GeoPoints.from_fields(colors=[rgb], class_ids=[cid],
                                                            radii=rr.Radius.ui_points(size)), static=True)
        rec.send_columns(base + "/position", indexes=times,
                         columns=rr.GeoPoints.columns(positions=np.column_stack([lat, lon])))
        rec.log(base + "/trail", rr.GeoPoints.from_fields(colors=[rgb], radii=rr.Radius.ui_points(trail_size)),
                static=True)
        rec.send_columns(base + "/trail", indexes=trail_times,
                         columns=rr.GeoPoints.columns(positions=np.column_stack([lat[trail], lon[trail]])))
    local_ok = np.isfinite(east) & np.isfinite(north)
    if local_ok.any():
        base = run.path("local", vehicle, source)
        xy = np.column_stack([east[local_ok], -north[local_ok]])
        if scatter:
            rec.log(base + "/track", rr.Points2D(xy, colors=[faint], radii=rr.Radius.ui_points(1.0)), static=True)
        else:
            rec.log(base + "/track", rr.LineStrips2D(strips(t[local_ok], xy), colors=[faint],
                                                     radii=rr.Radius.ui_points(0.75)), static=True)
        rec.log(base + "/position", rr.Points2D.from_fields(
            class_ids=[cid], labels=[run.name(mark_label(vehicle, source))], show_labels=truth,
            radii=rr.Radius.ui_points(size), draw_order=40.0 if truth else 30.0), static=True)
        rec.send_columns(base + "/position", indexes=times,
                         columns=rr.Points2D.columns(positions=np.column_stack([east, -north])))
        rec.log(base + "/trail", rr.Points2D.from_fields(class_ids=[cid], show_labels=False,
                                                         radii=rr.Radius.ui_points(trail_size),
                                                         draw_order=20.0 if truth else 10.0), static=True)
        rec.send_columns(base + "/trail", indexes=trail_times,
                         columns=rr.Points2D.columns(positions=np.column_stack([east[trail], -north[trail]])))


CIRCLE_SHARE = 0.98
"""The default bounds hold this share of the range circles whole (the rest are outliers of hundreds of metres)."""


def track_bounds(runs: list[ReviewData]) -> tuple[np.ndarray, np.ndarray] | None:
    """(min, max) east/north over every GPS fix and buoy of the runs and nearly every range circle (CIRCLE_SHARE
    of their edges), for the default view bounds: no circle runs off under the colour key beside the view."""
    parts = [r.tracks[r.tracks["source"] == "gps"] for r in runs if not r.tracks.empty and "source" in r.tracks]
    frame = pd.concat(parts) if parts else pd.DataFrame()
    if frame.empty:
        return None
    en = np.column_stack([floats(frame, "east_m"), floats(frame, "north_m")])
    en = en[np.isfinite(en).all(axis=1)]
    if not en.size:
        return None
    lo, hi = en.min(axis=0), en.max(axis=0)
    circles = [np.column_stack([floats(r.ranges, "leader_east_m"), floats(r.ranges, "leader_north_m"),
                                floats(r.ranges, "horizontal_m")]) for r in runs if not r.ranges.empty]
    c = np.concatenate(circles) if circles else np.zeros((0, 3))
    c = c[np.isfinite(c).all(axis=1)]
    if c.size:
        q = (1 - CIRCLE_SHARE) / 2
        lo = np.minimum(lo, np.quantile(c[:, :2] - c[:, 2:3], q, axis=0))
        hi = np.maximum(hi, np.quantile(c[:, :2] + c[:, 2:3], 1 - q, axis=0))
    return lo, hi


def local_frame(runs: list[ReviewData]) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The local east/north view's default bounds in view units (x east, y = -north): `track_bounds` with a
    margin of 8 % of the larger side (at least 4 m)."""
    found = track_bounds(runs)
    if found is None:
        return None
    lo, hi = found
    pad = 0.08 * max(float(np.max(hi - lo)), 50.0)
    return (float(lo[0] - pad), float(hi[0] + pad)), (float(-hi[1] - pad), float(-lo[1] + pad))


def log_local_scale(rec: rr.RecordingStream, runs: list[Run]) -> None:
    """A metre scale bar in the local east/north view (under the first run's ``local``), once per recording."""
    frame = local_frame([r.review for r in runs])
    if frame is not None:
        log_scale_bar(rec, runs[0].path("local", "scale"), *frame)


def geo_bounds(runs: list[ReviewData]) -> tuple[np.ndarray, np.ndarray] | None:
    """(min, max) latitude/longitude over every GPS fix of the runs."""
    parts = [r.tracks[r.tracks["source"] == "gps"] for r in runs if not r.tracks.empty and "source" in r.tracks]
    frame = pd.concat(parts) if parts else pd.DataFrame()
    if frame.empty:
        return None
    ll = np.column_stack([floats(frame, "lat_deg"), floats(frame, "lon_deg")])
    ll = ll[np.isfinite(ll).all(axis=1)]
    return (ll.min(axis=0), ll.max(axis=0)) if ll.size else None


def _epoch_labels(run: Run, ranges: pd.DataFrame) -> np.ndarray:
    """The truth label (1, 0, -1) of each range epoch of one follower and leader (`ranges`), from the detections."""
    det = run.review.detections
    if det.empty or "label" not in det or ranges.empty:
        return np.full(len(ranges), -1)
    # the pair's detections in time order (groups: a stable sort), so the first row of an instant is the table's
    # first of that instant and pair
    pairs = dict(run.groups(det, ["follower", "leader"]))
    rows = pairs.get((ranges["follower"].iloc[0], ranges["leader"].iloc[0]))
    if rows is None:
        return np.full(len(ranges), -1)
    t = floats(rows, "t_s")
    first = np.flatnonzero(np.r_[True, t[1:] != t[:-1]])
    t, label = t[first], pd.to_numeric(rows["label"], errors="coerce").to_numpy(dtype=float)[first]
    rt = floats(ranges, "t_s")
    k = np.clip(np.searchsorted(t, rt), 0, t.size - 1)
    found = (t[k] == rt) & np.isfinite(label[k])
    return np.where(found, label[k], -1).astype(int)


def log_range_circles(rec: rr.RecordingStream, run: Run) -> None:
    """One circle per ranging epoch around the ranged leader, coloured by the epoch's truth label."""
    for (follower, leader), rows in run.groups(run.review.ranges, ["follower", "leader"]):
        radius = floats(rows, "horizontal_m")
        radius = np.where(np.isfinite(radius), radius, floats(rows, "measured_m"))
        centre = np.column_stack([floats(rows, "leader_east_m"), -floats(rows, "leader_north_m")])
        label = _epoch_labels(run, rows)
        rgb = np.where((label == 1)[:, None], ANOMALOUS_RGB, np.where((label == 0)[:, None], NORMAL_RGB, UNKNOWN_RGB))
        rec.send_columns(run.path("local", "ranges", str(follower), str(leader)), indexes=run.times(rows["t_s"]),
                         columns=rr.Ellipses2D.columns(half_sizes=np.column_stack([radius, radius]), centers=centre,
                                                       colors=rgb.astype(np.uint8),
                                                       line_radii=np.full(len(rows), rr.Radius.ui_points(1.0),
                                                                          dtype=np.float32)))


def colour_key_names(run: Run) -> list[str]:
    """The names the colour key lists for a run: every track source, methods in the run's order first."""
    sources = {str(s) for s in run.review.tracks["source"].unique()} if "source" in run.review.tracks else set()
    return [m for m in [*run.review.methods, "gps", "ins"] if m in sources] + sorted(
        sources - set(run.review.methods) - {"gps", "ins"})


def _key_names(run: Run, focus: Sequence[str] | None) -> list[str]:
    hidden = set(hidden_methods(run, focus))
    return [n for n in colour_key_names(run) if n not in hidden]


def key_rows(runs: list[Run], focus: Sequence[str] | None = None) -> int:
    """Rows of the colour key: one per run and name shown."""
    return sum(len(_key_names(r, focus)) for r in runs)


def log_colour_key(rec: rr.RecordingStream, runs: list[Run], focus: Sequence[str] | None = None) -> None:
    """A legend for the map and the local plot: a swatch in each shown name's colour, top to bottom."""
    entries = [(r.name("GPS truth" if n == "gps" else n), method_rgb(n, r.index)) for r in runs
               for n in _key_names(r, focus)]
    if not entries:
        return
    y = KEY_STEP * np.arange(len(entries), dtype=float)
    rec.log(KEY + "/swatches", rr.LineStrips2D([np.array([[0.0, v], [1.5, v]]) for v in y],
                                               colors=[c for _, c in entries], radii=rr.Radius.ui_points(4.0)),
            static=True)
    # names in the truth's middle grey, which reads on the dark and the light theme; the swatch carries the colour
    # (a pale method colour as text vanishes on the light theme)
    rec.log(KEY + "/names", rr.Points2D(np.column_stack([np.full(y.size, 5.0), y]), labels=[t for t, _ in entries],
                                        colors=[method_rgb("truth")] * len(entries), radii=rr.Radius.ui_points(0.1)),
            static=True)
