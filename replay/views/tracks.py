"""Map and local metric plot: every track per vehicle and source, and the range circle of each epoch.

Entities under a run prefix P:
- ``P/map/<vehicle>/<source>/track``  GeoLineStrings, static (the whole track);
- ``P/map/<vehicle>/<source>/position``  GeoPoints on `time` (where it is now);
- ``P/local/<vehicle>/<source>/track`` and ``/position``  the same in east/north metres
  (LineStrips2D static, Points2D on `time`; y = -north, see replay.views.common);
- ``P/local/ranges/<follower>/<leader>``  Ellipses2D on `time`: a circle of the
  measured horizontal range around the ranged leader at that instant, red when
  the epoch is labelled anomalous.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import rerun as rr

from replay.views.common import Run, class_id, floats, groups, method_rgb

MAX_STATIC_VERTICES = 4000
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


def log_tracks(rec: rr.RecordingStream, run: Run) -> None:
    """Map and local-plot entities for every (vehicle, source) track of a run."""
    for (vehicle, source), rows in groups(run.review.tracks, ["vehicle", "source"]):
        _log_track(rec, run, str(vehicle), str(source), rows)


def _log_track(rec: rr.RecordingStream, run: Run, vehicle: str, source: str, rows: pd.DataFrame) -> None:
    lat, lon = floats(rows, "lat_deg"), floats(rows, "lon_deg")
    east, north = floats(rows, "east_m"), floats(rows, "north_m")
    n, cid, rgb = len(rows), class_id(source), method_rgb(source, run.index)
    times = [run.times(rows["t_s"])]
    geo_ok = np.isfinite(lat) & np.isfinite(lon)
    if geo_ok.any():
        keep = decimate(int(geo_ok.sum()))
        line = np.column_stack([lat[geo_ok], lon[geo_ok]])[keep]
        rec.log(run.path("map", vehicle, source, "track"),
                rr.GeoLineStrings(lat_lon=[line], radii=rr.Radius.ui_points(1.5), colors=[rgb]), static=True)
        rec.send_columns(run.path("map", vehicle, source, "position"), indexes=times,
                         columns=rr.GeoPoints.columns(positions=np.column_stack([lat, lon]),
                                                      class_ids=np.full(n, cid, dtype=np.uint16),
                                                      radii=np.full(n, rr.Radius.ui_points(5.0), dtype=np.float32)))
    local_ok = np.isfinite(east) & np.isfinite(north)
    if local_ok.any():
        keep = decimate(int(local_ok.sum()))
        strip = np.column_stack([east[local_ok], -north[local_ok]])[keep]
        rec.log(run.path("local", vehicle, source, "track"),
                rr.LineStrips2D([strip], class_ids=[cid], radii=rr.Radius.ui_points(1.0)), static=True)
        rec.send_columns(run.path("local", vehicle, source, "position"), indexes=times,
                         columns=rr.Points2D.columns(positions=np.column_stack([east, -north]),
                                                     class_ids=np.full(n, cid, dtype=np.uint16),
                                                     show_labels=np.zeros(n, dtype=bool),
                                                     radii=np.full(n, rr.Radius.ui_points(5.0), dtype=np.float32)))


def _epoch_labels(run: Run, ranges: pd.DataFrame) -> np.ndarray:
    """The truth label (1, 0, -1) of each range epoch, from the detections table."""
    det = run.review.detections
    if det.empty or "label" not in det:
        return np.full(len(ranges), -1)
    first = det.drop_duplicates(["t_s", "follower", "leader"])[["t_s", "follower", "leader", "label"]]
    merged = ranges[["t_s", "follower", "leader"]].merge(first, how="left", on=["t_s", "follower", "leader"])
    return merged["label"].fillna(-1).to_numpy(dtype=int)


def log_range_circles(rec: rr.RecordingStream, run: Run) -> None:
    """One circle per ranging epoch around the ranged leader, coloured by the epoch's truth label."""
    for (follower, leader), rows in groups(run.review.ranges, ["follower", "leader"]):
        radius = floats(rows, "horizontal_m")
        radius = np.where(np.isfinite(radius), radius, floats(rows, "measured_m"))
        centre = np.column_stack([floats(rows, "leader_east_m"), -floats(rows, "leader_north_m")])
        label = _epoch_labels(run, rows)
        rgb = np.where((label == 1)[:, None], ANOMALOUS_RGB, np.where((label == 0)[:, None], NORMAL_RGB, UNKNOWN_RGB))
        text = (f"{leader} " + pd.Series(radius).round(1).astype(str) + " m").to_numpy()
        rec.send_columns(run.path("local", "ranges", str(follower), str(leader)), indexes=[run.times(rows["t_s"])],
                         columns=rr.Ellipses2D.columns(half_sizes=np.column_stack([radius, radius]), centers=centre,
                                                       colors=rgb.astype(np.uint8), labels=text,
                                                       line_radii=np.full(len(rows), rr.Radius.ui_points(1.0),
                                                                          dtype=np.float32)))
