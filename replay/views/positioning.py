"""KMCDF-family epochs (preliminary fixes by cluster, final fixes, nodes by vehicle name) and the event log.

Entities under a run prefix P, on `time` and `mission_s`:
- ``P/kmcdf/<target>/<method>/fixes``  Points2D, every preliminary fix of the epoch (methods that
  make them), coloured by its cluster (1 = C1, the kept cluster, green; 2 = C2 red; as
  replay.stack.positioning.kmcdf numbers them), as east/north offsets from the target's GPS truth
  at the epoch, so a zoomed view stays on the fixes while the target moves;
- ``P/kmcdf/<target>/<method>/final``  Points2D, the method's final fix, offset from the truth alike;
- ``P/kmcdf/<target>/<method>/nodes``  Points2D in east/north, the nodes named by vehicle ("buoy3"),
  red when the epoch judged that node's delay abnormal, amber when only a phase;
- ``P/kmcdf/<target>/truth``  static: the GPS truth at (0, 0) with 5, 10 and 20 m rings and a metre
  scale bar (replay.views.scale);
- ``P/events``  TextLog.
Offsets and east/north metres with y = -north (see replay.views.common).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import rerun as rr

from replay.views.common import CLUSTER_COLORS, Run, class_id, floats, ragged
from replay.views.scale import log_scale_bar

NODE_OK, NODE_DELAY_BAD, NODE_PHASE_BAD = (200, 200, 200), (230, 50, 40), (240, 180, 40)


RINGS_M = (5.0, 10.0, 20.0)


def log_kmcdf(rec: rr.RecordingStream, run: Run) -> None:
    """Every KMCDF-family epoch of a run, per target and method, and the truth rings of each target."""
    for (target, method), rows in run.groups(run.review.kmcdf, ["target", "method"]):
        _log_epochs(rec, run, str(target), str(method), rows)
    for (target,), _ in run.groups(run.review.kmcdf, ["target"]):
        rings = [np.column_stack([r * np.cos(a), r * np.sin(a)]) for r in RINGS_M
                 for a in [np.linspace(0, 2 * np.pi, 73)]]
        rec.log(run.path("kmcdf", str(target), "truth", "rings"),
                rr.LineStrips2D(rings, labels=[f"{r:g} m" for r in RINGS_M], colors=[(128, 128, 128, 140)],
                                radii=rr.Radius.ui_points(0.5)), static=True)
        rec.log(run.path("kmcdf", str(target), "truth", "gps"),
                rr.Points2D([[0.0, 0.0]], labels=[f"{target} GPS"], class_ids=[class_id("gps")],
                            radii=rr.Radius.ui_points(6.0)), static=True)
        half = kmcdf_half_width(run, str(target))
        log_scale_bar(rec, run.path("kmcdf", str(target), "truth", "scale"), (-half, half), (-half, half))


def truth_at(run: Run, target: str, t_s: np.ndarray) -> np.ndarray:
    """(n, 2) east/north of the target's GPS at each instant, linearly interpolated; NaN outside its track."""
    tracks = run.review.tracks
    found = run.memo("gps tracks", (tracks,), lambda: {
        str(v): (floats(rows, "t_s"), floats(rows, "east_m"), floats(rows, "north_m"))
        for (v, s), rows in run.groups(tracks, ["vehicle", "source"]) if s == "gps"})
    if target not in found:
        return np.full((t_s.size, 2), np.nan)
    gt, east, north = found[target]
    out = np.column_stack([np.interp(t_s, gt, east), np.interp(t_s, gt, north)])
    out[(t_s < gt[0]) | (t_s > gt[-1])] = np.nan
    return out


RIM = 0.95     # where a fix beyond the view is drawn, as a share of the view's half width


def on_rim(offset: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) offsets with those beyond `limit` (Chebyshev, the square view) pulled in to it along their
    direction, and which were pulled."""
    reach = np.max(np.abs(offset), axis=1)
    beyond = np.isfinite(reach) & (reach > limit)
    out = offset.copy()
    out[beyond] *= (limit / reach[beyond])[:, None]
    return out, beyond


def fix_methods(review_kmcdf: pd.DataFrame) -> list[str]:
    """The positioning methods whose rows carry preliminary fixes."""
    if review_kmcdf.empty or "fixes_east_m" not in review_kmcdf:
        return []
    has = review_kmcdf["fixes_east_m"].map(lambda v: hasattr(v, "__len__") and len(v) > 0)
    return sorted(review_kmcdf.loc[has, "method"].astype(str).unique())


def _log_epochs(rec: rr.RecordingStream, run: Run, target: str, method: str, rows: pd.DataFrame) -> None:
    times = run.times(rows["t_s"])
    truth = truth_at(run, target, floats(rows, "t_s"))
    fe, lengths = ragged(rows, "fixes_east_m")
    fn, n_lengths = ragged(rows, "fixes_north_m")
    cl, c_lengths = ragged(rows, "fixes_cluster")
    if np.array_equal(lengths, n_lengths) and lengths.sum() > 0:
        cl = cl if np.array_equal(c_lengths, lengths) else np.zeros(fe.size)
        colors = CLUSTER_COLORS[np.nan_to_num(cl).astype(np.int64) % len(CLUSTER_COLORS)]
        origin = np.repeat(np.nan_to_num(truth), lengths, axis=0)
        # a rejected fix lies tens to thousands of metres out: drawn on the view's rim in its direction (hollow
        # and larger), so every preliminary fix of the epoch is on screen and the kept ones stay readable
        offset, beyond = on_rim(np.column_stack([fe - origin[:, 0], fn - origin[:, 1]]),
                                RIM * kmcdf_half_width(run, target))
        radii = np.where(beyond, rr.Radius.ui_points(5.0), rr.Radius.ui_points(3.0)).astype(np.float32)
        cols = rr.Points2D.columns(positions=np.column_stack([offset[:, 0], -offset[:, 1]]), colors=colors,
                                   radii=radii)
        rec.send_columns(run.path("kmcdf", target, method, "fixes"), indexes=times, columns=cols.partition(lengths))
    n = len(rows)
    off = np.column_stack([floats(rows, "east_m"), floats(rows, "north_m")]) - np.nan_to_num(truth)
    cols = rr.Points2D.columns(positions=np.column_stack([off[:, 0], -off[:, 1]]),
                               class_ids=np.full(n, class_id(method), dtype=np.uint16),
                               labels=np.full(n, run.name(method)),
                               radii=np.full(n, rr.Radius.ui_points(7.0), dtype=np.float32))
    rec.send_columns(run.path("kmcdf", target, method, "final"), indexes=times, columns=cols)
    _log_nodes(rec, run, target, method, rows, times)


def kmcdf_half_width(run: Run, target: str) -> float:
    """Half the zoomed view's width (m): 1.5 x the 90th percentile of the fixes' distance to the truth, >= 10 m."""
    return run.memo("kmcdf half width " + target, (run.review.kmcdf, run.review.tracks),
                    lambda: _half_width(run, target))


def _half_width(run: Run, target: str) -> float:
    rows = run.review.kmcdf[run.review.kmcdf["target"] == target] if not run.review.kmcdf.empty else run.review.kmcdf
    if rows.empty:
        return 10.0
    off = np.column_stack([floats(rows, "east_m"), floats(rows, "north_m")]) - truth_at(run, target,
                                                                                      floats(rows, "t_s"))
    d = np.hypot(off[:, 0], off[:, 1])
    d = d[np.isfinite(d)]
    return float(max(10.0, 1.5 * np.quantile(d, 0.9))) if d.size else 10.0


def _log_nodes(rec: rr.RecordingStream, run: Run, target: str, method: str, rows: pd.DataFrame,
               times: list[rr.TimeColumn]) -> None:
    ne, lengths = ragged(rows, "nodes_east_m")
    nn, n_lengths = ragged(rows, "nodes_north_m")
    if not np.array_equal(lengths, n_lengths) or lengths.sum() == 0:
        return
    delay, d_len = ragged(rows, "delay_normal")
    phase, p_len = ragged(rows, "phase_normal")
    delay = delay if np.array_equal(d_len, lengths) else np.ones(ne.size)
    phase = phase if np.array_equal(p_len, lengths) else np.ones(ne.size)
    colors = np.where((delay == 0)[:, None], NODE_DELAY_BAD, np.where((phase == 0)[:, None], NODE_PHASE_BAD, NODE_OK))
    index = np.concatenate([np.arange(k) for k in lengths])
    labels = (pd.Series("node ", index=range(ne.size)) + pd.Series(index + 1).astype(str)).to_numpy()
    if "nodes" in rows:
        names = [list(v) if isinstance(v, (list, tuple, np.ndarray)) else [] for v in rows["nodes"]]
        if [len(v) for v in names] == lengths.tolist():
            labels = np.array([str(x) for v in names for x in v], dtype=object)
    cols = rr.Points2D.columns(positions=np.column_stack([ne, -nn]), colors=colors.astype(np.uint8), labels=labels,
                               radii=np.full(ne.size, rr.Radius.ui_points(6.0), dtype=np.float32))
    rec.send_columns(run.path("kmcdf", target, method, "nodes"), indexes=times, columns=cols.partition(lengths))


def log_events(rec: rr.RecordingStream, run: Run) -> None:
    """The run's events as a text log (level INFO when missing)."""
    ev = run.review.events
    if ev.empty or "text" not in ev:
        return
    ev = ev.sort_values("t_s", kind="stable")
    level = ev["level"].fillna("INFO").astype(str).str.upper() if "level" in ev else pd.Series("INFO", index=ev.index)
    text = ev["text"].astype(str)

    if run.tag:    # the letter only: what differs between A and B is said once, in the Events title
        text = f"[{run.tag}] " + text
    rec.send_columns(run.path("events"), indexes=run.times(ev["t_s"]),
                     columns=rr.TextLog.columns(text=text.to_numpy(), level=level.to_numpy()))
