"""Time series: ranges, residuals, features, ANFIS output vs T2, and every method's error against GPS.

Entities under a run prefix P, all on the `time` and `mission_s` timelines:
- ``P/series/range/<follower>/<leader>/{measured,true}``, ``P/series/residual/<follower>/<leader>``;
- ``P/series/<feature>/<follower>/<leader>`` for f1_innovation_m, f2_mahalanobis2, f3_r_adapted_m2;
- ``P/series/anfis/<follower>/<leader>/<method>/{output,T2}`` for anfis, anfis_aqpso, anfis_compensation
  (anfis_hybrid's output is drawn with the other detectors' statistics, `replay.views.features`), and
  ``P/series/anfis/<follower>/<leader>/truth``: triangles below zero at the truth's anomalous epochs;
- ``P/series/error/<follower>/<method>``: horizontal error against GPS, filters and positioning alike;
- ``P/series/marks/t_a``: a vertical line at t_a (the start of the metrics window) in every plot
  that includes it.
Detection lanes are in `replay.views.lanes`, the error CDFs in `replay.views.cdf`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import rerun as rr

from replay.review.scoreboard import method_kind
from replay.stack.methods import anfis_family
from replay.views.common import Run, epochs_of, floats, method_rgb
from replay.views.lanes import training_end_s

FEATURES = ("f1_innovation_m", "f2_mahalanobis2", "f3_r_adapted_m2")
FEATURE_NAMES = {"f1_innovation_m": "f1", "f2_mahalanobis2": "f2", "f3_r_adapted_m2": "f3"}
"""How a legend names paper A's features (the plot's title says them in words, replay.views.features)."""


def _scalars(rec: rr.RecordingStream, path: str, run: Run, t_s: pd.Series, values: np.ndarray,
             name: str, rgb: tuple[int, int, int], step: bool = False, points: bool = False) -> None:
    """One named, coloured series of scalars on `time` and `mission_s`: a line, or markers with `points`."""
    if points:
        rec.log(path, rr.SeriesPoints(names=name, colors=[rgb], marker_sizes=1.5), static=True)
    else:
        rec.log(path, rr.SeriesLines(names=name, colors=[rgb], widths=1.5,
                                     interpolation_mode="StepAfter" if step else None), static=True)
    rec.send_columns(path, indexes=run.times(t_s), columns=rr.Scalars.columns(scalars=values))


LEADER_RGB = ((235, 150, 30), (60, 150, 235), (200, 100, 240), (90, 190, 80))
TRUTH_ROW = 0.05
"""Truth marks sit below zero, leader k's row at -(k + 1) * TRUTH_ROW of the plot's height."""


def anfis_top(runs: list[Run]) -> float | None:
    """The ANFIS plot's y extent: four times the largest T2 (outputs reach 1000 m where T2 is a few)."""
    family = anfis_family()
    thr = [floats(rows, "threshold") for r in runs for (m,), rows in r.groups(r.review.detections, ["method"])
           if str(m) in family]
    v = np.concatenate(thr) if thr else np.zeros(0)
    v = v[np.isfinite(v)]
    return float(4.0 * v.max()) if v.size else None


def truth_range(top: float | None, leaders: int) -> tuple[float, float] | None:
    """A score plot's y range from its top down to below the truth marks of `leaders` leaders."""
    return (-(leaders + 0.5) * TRUTH_ROW * top, top) if top else None


def log_truth_marks(rec: rr.RecordingStream, run: Run, path: str, rows: pd.DataFrame, k: int,
                    top: float | None, row: int | None = None) -> None:
    """Triangles below zero at the epochs whose truth label is anomalous, in leader k's colour, on its row (k's
    unless given): the truth windows under a detector's statistic."""
    epochs = epochs_of(run, rows)
    anomalous = pd.to_numeric(epochs["label"], errors="coerce").to_numpy() == 1 if "label" in epochs else []
    t = floats(epochs, "t_s")[anomalous]
    if t.size == 0:
        return
    rgb = LEADER_RGB[k % len(LEADER_RGB)]
    leader = str(epochs["leader"].iloc[0]) if "leader" in epochs else ""
    rec.log(path, rr.SeriesPoints(names=run.name(f"{leader} truth: anomaly"), colors=[rgb], markers="Up",
                                  marker_sizes=2.5), static=True)
    rec.send_columns(path, indexes=run.times(t), columns=rr.Scalars.columns(
        scalars=np.full(t.size, -((k if row is None else row) + 1) * TRUTH_ROW * (top or 1.0))))


def log_ranges(rec: rr.RecordingStream, run: Run) -> None:
    """Measured and GPS-true range per leader, and the residual."""
    for k, ((follower, leader), rows) in enumerate(run.groups(run.review.ranges, ["follower", "leader"])):
        f, ld = str(follower), str(leader)
        rgb = LEADER_RGB[k % len(LEADER_RGB)]
        _scalars(rec, run.path("series", "range", f, ld, "measured"), run, rows["t_s"], floats(rows, "measured_m"),
                 run.name(f"{ld} measured"), rgb)
        _scalars(rec, run.path("series", "range", f, ld, "true"), run, rows["t_s"], floats(rows, "true_m"),
                 run.name(f"{ld} true"), method_rgb("gps", run.index))
        _scalars(rec, run.path("series", "residual", f, ld), run, rows["t_s"], floats(rows, "residual_m"),
                 run.name(f"{ld} residual"), rgb)


def log_detections(rec: rr.RecordingStream, run: Run) -> None:
    """Features per leader, and each ANFIS-family detector's output against its T2."""
    det = run.review.detections
    family = anfis_family()
    top = anfis_top([run])
    for k, ((follower, leader), rows) in enumerate(run.groups(det, ["follower", "leader"])):
        f, ld = str(follower), str(leader)
        epochs = epochs_of(run, rows)
        if "method" in rows and family & set(rows["method"].astype(str).unique()):      # one leader a plot: row 0
            log_truth_marks(rec, run, run.path("series", "anfis", f, ld, "truth"), rows, k, top, row=0)
        for feature in FEATURES:
            _scalars(rec, run.path("series", feature, f, ld), run, epochs["t_s"], floats(epochs, feature),
                     run.name(f"{ld} {FEATURE_NAMES[feature]}"), LEADER_RGB[k % len(LEADER_RGB)])
        for (method,), m_rows in run.groups(rows, ["method"]):
            m = str(method)
            if m in family:
                _scalars(rec, run.path("series", "anfis", f, ld, m, "output"), run, m_rows["t_s"],
                         floats(m_rows, "score"), run.name(f"{ld} {m} output"), method_rgb(m, run.index))
                _scalars(rec, run.path("series", "anfis", f, ld, m, "T2"), run, m_rows["t_s"],
                         floats(m_rows, "threshold"), run.name(f"{ld} {m} T2"), method_rgb(m, run.index), True)


def log_errors(rec: rr.RecordingStream, run: Run, height: float) -> None:
    """The error series of every method, and the t_a mark.

    Positioning methods (a fix every few seconds, with outliers of hundreds of metres) are drawn as
    markers: as lines their outliers would hatch the whole plot.
    """
    for (follower, method), rows in run.groups(run.review.errors, ["follower", "method"]):
        m = str(method)
        _scalars(rec, run.path("series", "error", str(follower), m), run, rows["t_s"], floats(rows, "error_m"),
                 run.name(m), method_rgb(m, run.index), points=method_kind(m) == "positioning")
    log_t_a(rec, run, height)


def log_t_a(rec: rr.RecordingStream, run: Run, height: float) -> None:
    """A vertical line at t_a: two samples at one instant, from 0 to `height` (a plot clips it to its axis)."""
    t_a = training_end_s(run)
    if t_a <= 0:
        return
    path = run.path("series", "marks", "t_a")
    # aggregation off: zoomed out, Rerun averages the samples that share a pixel column, and the two samples of
    # one instant would average to a point (the line would vanish)
    rec.log(path, rr.SeriesLines(names=run.name(f"t_a = {t_a:.0f} s (scoring starts)"), colors=[(128, 128, 128)],
                                 widths=2.0, aggregation_policy="Off"), static=True)
    rec.send_columns(path, indexes=run.times(np.array([t_a, t_a])), columns=rr.Scalars.columns(
        scalars=np.array([0.0, height])))


def error_ceiling(reviews: list[pd.DataFrame]) -> float:
    """The error plots' y extent: the 95th percentile of every error of every run, with room above."""
    v = np.concatenate([floats(e, "error_m") for e in reviews if not e.empty] or [np.zeros(0)])
    v = v[np.isfinite(v)]
    return float(1.2 * np.quantile(v, 0.95)) if v.size else 1.0


SPAN = "/mission_span"
"""An entity with no visible value at the mission's first and last second, in every time series view: each
plot's x axis then spans the whole mission from 0 (round ticks, "#0 #1000"; plots aligned with each other),
not from its own first sample ("#6 #1006")."""


def mission_end(runs: list[Run]) -> float | None:
    """The last second any run's tracks, errors or ranges reach (None for empty tables)."""
    ends = [float(np.nanmax(floats(f, "t_s"))) for r in runs for f in (r.review.tracks, r.review.errors,
                                                                       r.review.ranges) if len(f) and "t_s" in f]
    return max(ends) if ends else None


def log_mission_span(rec: rr.RecordingStream, runs: list[Run], end_s: float | None = None) -> None:
    """The span entity: NaN (drawn as nothing) at 0 s and at the last second (`end_s`, default: the last second
    any run's table reaches), a hidden series whose greyed legend entry names the x axis ("x: mission s
    (0-1700)")."""
    end = mission_end(runs) if end_s is None else end_s
    if end is None:
        return
    rec.log(SPAN, rr.SeriesPoints(names=f"x: mission s (0-{end:.0f})", colors=[(0, 0, 0, 0)], marker_sizes=0.0,
                                  visible_series=[False]), static=True)
    rec.send_columns(SPAN, indexes=runs[0].times(np.array([0.0, end])),
                     columns=rr.Scalars.columns(scalars=np.array([np.nan, np.nan])))
