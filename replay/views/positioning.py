"""KMCDF epochs (preliminary fixes coloured by cluster, final fix, nodes) and the text log of events.

Entities under a run prefix P, on `time`:
- ``P/kmcdf/<target>/<method>/fixes``  Points2D, every preliminary fix of the epoch,
  coloured by its cluster (1 = C1, the kept cluster, green; 2 = C2 red; as replay.stack.positioning.kmcdf numbers them);
- ``P/kmcdf/<target>/<method>/final``  Points2D, the final fix in the method's colour;
- ``P/kmcdf/<target>/<method>/nodes``  Points2D, the nodes, red when the epoch judged
  that node's delay abnormal, amber when only a phase;
- ``P/events``  TextLog.
East/north metres with y = -north (see replay.views.common).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import rerun as rr

from replay.views.common import CLUSTER_COLORS, Run, class_id, floats, groups, ragged

NODE_OK, NODE_DELAY_BAD, NODE_PHASE_BAD = (200, 200, 200), (230, 50, 40), (240, 180, 40)


def log_kmcdf(rec: rr.RecordingStream, run: Run) -> None:
    """Every KMCDF-family epoch of a run, per target and method."""
    for (target, method), rows in groups(run.review.kmcdf, ["target", "method"]):
        _log_epochs(rec, run, str(target), str(method), rows)


def _log_epochs(rec: rr.RecordingStream, run: Run, target: str, method: str, rows: pd.DataFrame) -> None:
    times = [run.times(rows["t_s"])]
    fe, lengths = ragged(rows, "fixes_east_m")
    fn, n_lengths = ragged(rows, "fixes_north_m")
    cl, c_lengths = ragged(rows, "fixes_cluster")
    if np.array_equal(lengths, n_lengths) and lengths.sum() > 0:
        cl = cl if np.array_equal(c_lengths, lengths) else np.zeros(fe.size)
        colors = CLUSTER_COLORS[np.nan_to_num(cl).astype(np.int64) % len(CLUSTER_COLORS)]
        cols = rr.Points2D.columns(positions=np.column_stack([fe, -fn]), colors=colors,
                                   radii=np.full(fe.size, rr.Radius.ui_points(3.0), dtype=np.float32))
        rec.send_columns(run.path("kmcdf", target, method, "fixes"), indexes=times, columns=cols.partition(lengths))
    n = len(rows)
    cols = rr.Points2D.columns(positions=np.column_stack([floats(rows, "east_m"), -floats(rows, "north_m")]),
                               class_ids=np.full(n, class_id(method), dtype=np.uint16),
                               radii=np.full(n, rr.Radius.ui_points(7.0), dtype=np.float32))
    rec.send_columns(run.path("kmcdf", target, method, "final"), indexes=times, columns=cols)
    _log_nodes(rec, run, target, method, rows, times)


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
    if run.label:
        text = f"[{run.label}] " + text
    rec.send_columns(run.path("events"), indexes=[run.times(ev["t_s"])],
                     columns=rr.TextLog.columns(text=text.to_numpy(), level=level.to_numpy()))
