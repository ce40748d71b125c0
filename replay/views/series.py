"""Time series (ranges, residuals, features, ANFIS output vs T2, detection lanes) and growing error CDFs.

Entities under a run prefix P, all on the `time` timeline:
- ``P/series/range/<follower>/<leader>/{measured,true}``, ``P/series/residual/<follower>/<leader>``;
- ``P/series/<feature>/<follower>/<leader>`` for f1_innovation_m, f2_mahalanobis2, f3_r_adapted_m2;
- ``P/series/anfis/<follower>/<leader>/<method>/{output,T2}`` for every ANFIS-family detector;
- ``P/series/lanes/<follower>/<leader>/<lane>``: one step line per detector at height k
  (k + 0.8 when flagged) beside the truth labels at height 0;
- ``P/series/error/<follower>/<method>``: horizontal error against GPS;
- ``P/cdf/<follower>/<method>/{curve,percentiles}``: the empirical CDF of the errors seen
  so far, re-drawn at up to `CDF_SNAPSHOTS` instants (x = error m, y = -probability x scale),
  with p50/p90/p95 marked and labelled; ``P/cdf/<follower>/guides`` the 50/90/95 % lines.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import rerun as rr

from replay.views.common import Run, class_id, floats, groups, method_rgb

FEATURES = ("f1_innovation_m", "f2_mahalanobis2", "f3_r_adapted_m2")
CDF_SNAPSHOTS = 120
CDF_POINTS = 101
PERCENTILES = (0.50, 0.90, 0.95)
LANE_HIGH = 0.8


def _scalars(rec: rr.RecordingStream, path: str, run: Run, t_s: pd.Series, values: np.ndarray,
             name: str, rgb: tuple[int, int, int], step: bool = False) -> None:
    """One named, coloured line of scalars on `time`."""
    rec.log(path, rr.SeriesLines(names=name, colors=[rgb], widths=1.5,
                                 interpolation_mode="StepAfter" if step else None), static=True)
    rec.send_columns(path, indexes=[run.times(t_s)], columns=rr.Scalars.columns(scalars=values))


LEADER_RGB = ((255, 200, 80), (110, 200, 255), (230, 130, 255), (160, 230, 120))


def log_ranges(rec: rr.RecordingStream, run: Run) -> None:
    """Measured and GPS-true range per leader, and the residual."""
    for k, ((follower, leader), rows) in enumerate(groups(run.review.ranges, ["follower", "leader"])):
        f, ld = str(follower), str(leader)
        rgb = LEADER_RGB[k % len(LEADER_RGB)]
        _scalars(rec, run.path("series", "range", f, ld, "measured"), run, rows["t_s"], floats(rows, "measured_m"),
                 run.name(f"{ld} measured"), rgb)
        _scalars(rec, run.path("series", "range", f, ld, "true"), run, rows["t_s"], floats(rows, "true_m"),
                 run.name(f"{ld} true"), method_rgb("gps", run.index))
        _scalars(rec, run.path("series", "residual", f, ld), run, rows["t_s"], floats(rows, "residual_m"),
                 run.name(f"{ld} residual"), rgb)


def log_detections(rec: rr.RecordingStream, run: Run) -> None:
    """Features, ANFIS output against T2, and detection lanes beside the truth labels.

    Lanes: per (follower, leader) block, the truth label at the block's base and
    one lane per detector above it; blocks are stacked so leaders never overlap.
    """
    det = run.review.detections
    n_methods = det["method"].nunique() if "method" in det else 0
    for k, ((follower, leader), rows) in enumerate(groups(det, ["follower", "leader"])):
        f, ld = str(follower), str(leader)
        epochs = rows.drop_duplicates("t_s")
        for feature in FEATURES:
            _scalars(rec, run.path("series", feature, f, ld), run, epochs["t_s"], floats(epochs, feature),
                     run.name(f"{ld} {feature}"), LEADER_RGB[k % len(LEADER_RGB)])
        base = k * (n_methods + 2)
        label = floats(epochs, "label")
        _scalars(rec, run.path("series", "lanes", f, ld, "truth"), run, epochs["t_s"],
                 base + np.where(label == 1, LANE_HIGH, 0.0), run.name(f"{ld} truth label"),
                 method_rgb("truth", run.index), True)
        for lane, (method, m_rows) in enumerate(groups(rows, ["method"]), start=1):
            _log_method_lane(rec, run, f, ld, str(method[0]), m_rows, base + lane)


def _log_method_lane(rec: rr.RecordingStream, run: Run, f: str, ld: str, m: str, rows: pd.DataFrame,
                     height: float) -> None:
    flagged = rows["flagged"].to_numpy(dtype=bool)
    _scalars(rec, run.path("series", "lanes", f, ld, m), run, rows["t_s"], height + LANE_HIGH * flagged,
             run.name(f"{ld} {m}"), method_rgb(m, run.index), True)
    if m.startswith("anfis"):
        _scalars(rec, run.path("series", "anfis", f, ld, m, "output"), run, rows["t_s"], floats(rows, "score"),
                 run.name(f"{ld} {m} output"), method_rgb(m, run.index))
        _scalars(rec, run.path("series", "anfis", f, ld, m, "T2"), run, rows["t_s"], floats(rows, "threshold"),
                 run.name(f"{ld} {m} T2"), method_rgb("truth", run.index), True)


def expanding_quantiles(t_s: np.ndarray, values: np.ndarray, at_s: np.ndarray, probs: np.ndarray) -> np.ndarray:
    """Quantiles (len(at_s), len(probs)) of the finite values with t <= each instant; NaN rows where none.

    One sort of a (snapshots, n) matrix with later samples masked to +inf, then
    linear interpolation between order statistics (numpy's default "linear" rule).
    """
    ok = np.isfinite(values)
    t_s, values = t_s[ok], values[ok]
    seen = t_s[None, :] <= at_s[:, None]
    ordered = np.sort(np.where(seen, values[None, :], np.inf), axis=1)
    count = seen.sum(axis=1)
    pos = probs[None, :] * np.maximum(count - 1, 0)[:, None]
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, np.maximum(count - 1, 0)[:, None])
    frac = pos - lo
    if ordered.shape[1] == 0:
        return np.full((at_s.size, probs.size), np.nan)
    q_lo, q_hi = np.take_along_axis(ordered, lo, 1), np.take_along_axis(ordered, hi, 1)
    with np.errstate(invalid="ignore"):
        q = q_lo + frac * (q_hi - q_lo)
    return np.where((count > 0)[:, None], q, np.nan)


def _snapshot_times(t_s: np.ndarray) -> np.ndarray:
    uniq = np.unique(t_s[np.isfinite(t_s)])
    if uniq.size <= CDF_SNAPSHOTS:
        return uniq
    return uniq[np.unique(np.linspace(0, uniq.size - 1, CDF_SNAPSHOTS).round().astype(np.int64))]


def log_errors(rec: rr.RecordingStream, run: Run, scale: dict[str, float]) -> None:
    """Error series and the growing CDF per method; `scale[follower]` is the CDF's y extent in metres."""
    probs = np.linspace(0.0, 1.0, CDF_POINTS)
    marks = np.array(PERCENTILES)
    for (follower,), f_rows in groups(run.review.errors, ["follower"]):
        f = str(follower)
        at = _snapshot_times(floats(f_rows, "t_s"))
        s = scale.get(f, 1.0)
        table: dict[str, np.ndarray] = {}
        for (method,), rows in groups(f_rows, ["method"]):
            m = str(method)
            t, err = floats(rows, "t_s"), floats(rows, "error_m")
            _scalars(rec, run.path("series", "error", f, m), run, rows["t_s"], err, run.name(m),
                     method_rgb(m, run.index))
            q = expanding_quantiles(t, err, at, np.concatenate([probs, marks]))
            _log_cdf(rec, run, f, m, at, q, s)
            table[m] = q[:, CDF_POINTS:]
        _log_guides(rec, run, f, s)
        _log_table(rec, run, f, at, table)


def _log_cdf(rec: rr.RecordingStream, run: Run, follower: str, method: str, at: np.ndarray,
             q: np.ndarray, scale: float) -> None:
    ok = np.isfinite(q[:, 0])
    if not ok.any():
        return
    at, q = at[ok], q[ok]
    k, cid = at.size, class_id(method)
    curve, marks = q[:, :CDF_POINTS], q[:, CDF_POINTS:]
    ys = -np.linspace(0.0, 1.0, CDF_POINTS) * scale
    strips = np.stack([curve, np.broadcast_to(ys, curve.shape)], axis=-1)          # (k, points, 2)
    rec.send_columns(run.path("cdf", follower, method, "curve"), indexes=[run.times(at)],
                     columns=rr.LineStrips2D.columns(strips=list(strips), class_ids=np.full(k, cid, dtype=np.uint16),
                                                     radii=np.full(k, rr.Radius.ui_points(1.5), dtype=np.float32)))
    n_marks = len(PERCENTILES)
    pos = np.stack([marks.ravel(), np.tile(-np.array(PERCENTILES) * scale, k)], axis=-1)
    cols = rr.Points2D.columns(positions=pos, class_ids=np.full(k * n_marks, cid, dtype=np.uint16),
                               show_labels=np.zeros(k * n_marks, dtype=bool),
                               radii=np.full(k * n_marks, rr.Radius.ui_points(4.0), dtype=np.float32))
    rec.send_columns(run.path("cdf", follower, method, "percentiles"), indexes=[run.times(at)],
                     columns=cols.partition(np.full(k, n_marks)))


def _log_table(rec: rr.RecordingStream, run: Run, follower: str, at: np.ndarray,
               table: dict[str, np.ndarray]) -> None:
    """A markdown table of each method's percentiles so far, one document per CDF snapshot."""
    if not table or at.size == 0:
        return
    head = "| method | " + " | ".join(f"p{int(p * 100)} (m)" for p in PERCENTILES) + " |\n|---|" + "---|" * len(
        PERCENTILES) + "\n"
    rows = [f"| {run.name(m)} | " + " | ".join(np.char.mod("%.2f", q[i]).tolist()) + " |"
            for i in range(at.size) for m, q in table.items()]
    per = len(table)
    docs = [f"Errors of {follower} up to t = {t:.0f} s\n\n" + head + "\n".join(rows[i * per:(i + 1) * per])
            for i, t in enumerate(at)]
    rec.send_columns(run.path("cdf", follower, "table"), indexes=[run.times(at)],
                     columns=rr.TextDocument.columns(text=docs, media_type=["text/markdown"] * at.size))


def _log_guides(rec: rr.RecordingStream, run: Run, follower: str, scale: float) -> None:
    """Static horizontal lines at 0/50/90/95/100 % across the CDF plot, labelled."""
    levels = np.array([0.0, *PERCENTILES, 1.0])
    strips = [np.array([[0.0, -p * scale], [scale, -p * scale]]) for p in levels]
    rec.log(run.path("cdf", follower, "guides"),
            rr.LineStrips2D(strips, labels=[f"{int(p * 100)} %" for p in levels], colors=[(90, 90, 90)],
                            radii=rr.Radius.ui_points(0.5)), static=True)


def cdf_scale(errors: list[pd.DataFrame]) -> dict[str, float]:
    """Per follower, the 99th percentile of every error (all runs): the CDF plot's x extent, so it is square."""
    usable = [e for e in errors if not e.empty and "error_m" in e and "follower" in e]
    if not usable:
        return {}
    frame = pd.concat(usable, ignore_index=True)
    out = {}
    for follower, rows in frame.groupby("follower"):
        v = floats(rows, "error_m")
        v = v[np.isfinite(v)]
        out[str(follower)] = float(np.quantile(v, 0.99)) if v.size and np.quantile(v, 0.99) > 0 else 1.0
    return out
