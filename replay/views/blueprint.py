"""The one blueprint saved with every recording: tabs a reviewer can read without a manual.

Tabs, each answering one question (the event log sits on the right of every tab):
- Scoreboard: which method is best after t_a, by error and by detection (the ranked table with
  metrics.json's figures, the error CDFs, every method's error over the whole mission);
- Detection: where each detector hit, missed or false-alarmed (a state-timeline lane per leader
  and detector under the truth, the whole mission) and, beside the lanes, why each detector did
  (not) flag at the cursor, one line per detector and leader;
- Scores: every detector's statistic against its threshold (ANFIS outputs vs T2, chi_square's f2
  vs its gate, dual_threshold, cusum_drift's sums vs h, anfis_hybrid vs its FPR threshold);
- Features (one sub-tab per leader): paper A's features, the ranges, and the filter-independent
  features grouped by unit (or a note saying which the run did not compute);
- Navigation: the map and the local east/north plot, every track, trails ending at the cursor,
  bounds holding every vehicle and buoy, a colour key;
- ANFIS (one tab per model: each ANFIS method that ran, per leader, titled with both): what the model
  is (a note), what it learned (MFs over the input's own values) and where this epoch sits in it;
- KMCDF (one view pair per target): the fixes around the GPS truth, and the nodes by name.
With two runs, the scoreboards sit side by side with what changed, and the other views overlay
both runs (every name tagged with the run's letter, A the first run given; what differs is said once, in
the event log's title and in "What changed") instead of repeating per run; the epochs they decided
differently are a table beside the scoreboards.
The recording opens paused on the `mission_s` timeline (whole seconds, the axes read "#620") with the
cursor at the mission's start (Rerun 0.41's blueprint cannot place it elsewhere; "following" would put
it on the last sample), and every time series and lane on the whole mission.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from rerun.blueprint.api import VisualizerLike
from rerun.encodings import EntityPathLike

from replay.review.data import ReviewData
from replay.stack.methods import METHOD_TABLE
from replay.views.anfis import input_short, input_title, model_inputs, model_order, model_parts, model_path
from replay.views.cdf import HEIGHT, WIDTH
from replay.views.common import MISSION, Run, floats, track_pairs
from replay.views.features import (
    FEATURE_GROUPS,
    feature_note,
    feature_words,
    group_title,
    present_features,
    score_top,
    scored,
)
from replay.views.focus import focus_note, hide
from replay.views.lanes import LANES_ROOT, training_end_s
from replay.views.positioning import fix_methods, kmcdf_half_width
from replay.views.series import SPAN, anfis_top, truth_range
from replay.views.tracks import KEY, KEY_STEP, geo_bounds, key_rows, local_frame
from replay.views.vehicle import PANELS

TIMELINES = ("time", MISSION)


def _contents(runs: list[Run], *parts: str) -> list[str]:
    return [f"+ {r.path(*parts)}/**" for r in runs]


def _whole_mission() -> rrb.archetypes.TimeAxis:
    """The x axis of a time series: every sample of the mission, whatever the cursor."""
    return rrb.archetypes.TimeAxis(link="Independent", view_range=rr.TimeRange(
        start=rr.TimeRangeBoundary.infinite(), end=rr.TimeRangeBoundary.infinite()))


def _series(name: str, contents: list[str], y_max: float | None = None, legend: bool = True,
            y_range: tuple[float, float] | None = None,
            overrides: dict[EntityPathLike, VisualizerLike] | None = None) -> rrb.TimeSeriesView:
    """A time series over the whole mission; y from 0 to `y_max`, or over `y_range`, else fitted to the data."""
    y = y_range if y_range is not None else (0.0, y_max) if y_max else None
    return rrb.TimeSeriesView(name=name, contents=[*contents, f"+ {SPAN}"], axis_x=_whole_mission(),
                              axis_y=rrb.ScalarAxis(range=y, zoom_lock=False) if y else None,
                              plot_legend=rrb.PlotLegend(corner="RightTop", visible=legend), overrides=overrides)


def robust_range(values: np.ndarray, pad: float = 0.1) -> tuple[float, float] | None:
    """A y range holding the middle 99 % of the finite values, with room around (heavy tails would flatten the rest)."""
    v = values[np.isfinite(values)]
    if v.size == 0:
        return None
    lo, hi = (float(x) for x in np.quantile(v, [0.005, 0.995]))
    if hi <= lo:
        lo, hi = lo - 1.0, hi + 1.0
    span = hi - lo
    return lo - pad * span, hi + pad * span


def _up_to_cursor() -> rrb.VisibleTimeRanges:
    return rrb.VisibleTimeRanges([rr.VisibleTimeRange(t, start=rr.TimeRangeBoundary.infinite(),
                                                      end=rr.TimeRangeBoundary.cursor_relative())
                                  for t in TIMELINES])


def _trail_overrides(runs: list[Run], view: str) -> dict[EntityPathLike, VisualizerLike]:
    """Every trail entity shows its samples from the start up to the cursor."""
    ranges = _up_to_cursor()            # one value, the same for every trail
    return {r.path(view, v, s, "trail"): ranges for r in runs for v, s in track_pairs(r)}


def _merge(*parts: dict[EntityPathLike, VisualizerLike]) -> dict[EntityPathLike, Any]:
    """Override maps joined; an entity named in several keeps every override (a trail's time range and its
    hidden state alike)."""
    out: dict[EntityPathLike, list[VisualizerLike]] = {}
    for part_ in parts:
        for key, value in part_.items():
            out.setdefault(key, []).append(value)
    return {k: v[0] if len(v) == 1 else v for k, v in out.items()}


def _local_bounds(reviews: list[ReviewData]) -> rrb.VisualBounds2D | None:
    frame = local_frame(reviews)         # the scale bar sits in its corner (tracks.log_local_scale)
    return rrb.VisualBounds2D(x_range=list(frame[0]), y_range=list(frame[1])) if frame else None


def map_zoom(reviews: list[ReviewData], width_px: float = 450.0) -> float | None:
    """The OpenStreetMap zoom level at which every GPS fix fits in a map `width_px` wide (with a margin)."""
    found = geo_bounds(reviews)
    if found is None:
        return None
    (lat0, lon0), (lat1, lon1) = found
    span_deg = max(lon1 - lon0, (lat1 - lat0) / max(np.cos(np.radians(0.5 * (lat0 + lat1))), 1e-6), 1e-5)
    return float(np.clip(np.log2(360.0 * width_px / (256.0 * 1.3 * span_deg)), 1.0, 19.0))


def _navigation(runs: list[Run], focus: Sequence[str] | None) -> rrb.Container:
    reviews = [r.review for r in runs]
    note = focus_note(runs, focus)
    return rrb.Horizontal(
        rrb.MapView(name="Map: GPS truth and the focus tracks" + (f"; {note}" if note else ""),
                    contents=_contents(runs, "map"), zoom=map_zoom(reviews),
                    overrides=_merge(_trail_overrides(runs, "map"), hide(runs, focus, "map"))),
        rrb.Spatial2DView(name="Local east/north (m), range circles, scale bar", contents=_contents(runs, "local"),
                          overrides=_merge(_trail_overrides(runs, "local"), hide(runs, focus, "local")),
                          visual_bounds=_local_bounds(reviews)),
        rrb.Spatial2DView(name="Key", contents=[f"+ {KEY}/**"], visual_bounds=rrb.VisualBounds2D(
            x_range=[-0.5, 9.0], y_range=[-1.0, 1.0 + KEY_STEP * key_rows(runs, focus)])),
        column_shares=[5, 5, 1.6], name="Navigation",
    )


def _vehicles(runs: list[Run]) -> rrb.Container | None:
    """Per vehicle with a navigation review: its summary and drift at the fixes beside its series."""
    tabs = []
    for run in runs:
        tag = f" [{run.tag}]" if run.tag else ""
        for vehicle in run.review.navigation:
            base = run.path("vehicle", vehicle)
            plots = [_series(title, [f"+ {base}/{key}/**"], y_range=(0.0, 1.05) if key == "lock" else None)
                     for key, title in PANELS]
            left = rrb.Vertical(
                rrb.TextDocumentView(name=f"{vehicle}: drift, dives, bottom lock", contents=[f"+ {base}/summary"]),
                _series("Error at each GPS fix (m): DR restarted at fixes, INS", [f"+ {base}/error/**"]),
                row_shares=[1.2, 1])
            tabs.append(rrb.Horizontal(left, rrb.Vertical(*plots), column_shares=[1, 1.3], name=f"{vehicle}{tag}"))
    return rrb.Tabs(*tabs, name="Vehicles") if tabs else None


def _scoreboard(runs: list[Run], error_top: float, focus: Sequence[str] | None) -> rrb.Container:
    followers = sorted({str(k[0]) for r in runs for k, _ in r.groups(r.review.errors, ["follower"])})
    docs = [rrb.TextDocumentView(name=f"Scoreboard{' of ' + r.tag if r.tag else ''}",
                                 contents=[f"+ {r.path('scoreboard')}"]) for r in runs]
    if len(runs) == 2:
        docs.append(rrb.TextDocumentView(name="What changed: A vs B",
                                         contents=[f"+ {runs[1].path('changes')}"]))
        docs.append(rrb.TextDocumentView(name="Epochs that differ", contents=[f"+ {runs[1].path('differing')}"]))
    cdfs: list[rrb.View | rrb.Container] = []
    for f in followers:
        bounds = rrb.VisualBounds2D(x_range=[-13.0, WIDTH + 8.0], y_range=[-HEIGHT - 8.0, 11.0])
        cdfs.append(rrb.Spatial2DView(name=f"Error CDF of {f} after t_a, so far",
                                      contents=[f"+ {r.path('cdf', f)}/**" for r in runs]
                                      + [f"- {r.path('cdf', f, 'table')}" for r in runs], visual_bounds=bounds,
                                      overrides=hide(runs, focus, "cdf")))
        # two runs: their tables as tabs, each the column's width (side by side, neither title nor table fits)
        tables = [rrb.TextDocumentView(name=f"Percentiles from t_a to the cursor{' of ' + r.tag if r.tag else ''}",
                                       contents=[f"+ {r.path('cdf', f, 'table')}"]) for r in runs]
        cdfs.append(tables[0] if len(tables) == 1 else rrb.Tabs(*tables))
    note = focus_note(runs, focus)
    errors = _series("Error vs GPS (m), whole mission; grey line: t_a" + (f"; {note}" if note else ""),
                     _contents(runs, "series", "error") + _contents(runs, "series", "marks"), error_top,
                     overrides=hide(runs, focus, "error"))
    # two runs: what changed first, the epochs that differ and the two scoreboards as tabs beneath (side by side
    # they would not fit)
    left = (rrb.Vertical(docs[0], errors, row_shares=[1, 1]) if len(docs) == 1 else
            rrb.Vertical(docs[2], rrb.Tabs(docs[3], *docs[:2]), errors, row_shares=[1.1, 1.1, 1]))
    return rrb.Horizontal(
        left,
        rrb.Vertical(*cdfs, row_shares=[1.4, 1] * len(followers)) if cdfs else rrb.Vertical(),
        column_shares=[1.75, 1], name="Scoreboard",
    )


def _pairs(runs: list[Run]) -> list[tuple[str, str]]:
    """Every (follower, leader) with detections in any run, sorted."""
    return sorted({(str(k[0]), str(k[1])) for r in runs for k, _ in r.groups(r.review.detections,
                                                                             ["follower", "leader"])})


def _detection(runs: list[Run]) -> rrb.Container:
    """The lanes over the whole mission, and beside them why each detector did (not) flag at the cursor."""
    t_a = ", ".join(f"{training_end_s(r):.0f} s" for r in runs)
    lanes = rrb.StateTimelineView(
        name=f"Detection lanes: truth, then the detectors best first (t_a = {t_a}); top lane: the colours",
        contents=[f"+ {LANES_ROOT}/**"], time_view=_whole_mission())
    pairs = _pairs(runs)
    many = len({f for f, _ in pairs}) > 1
    whys = [rrb.TextDocumentView(
        name=f"Why (not) flagged: {f + '/' if many else ''}{ld}{' [' + r.tag + ']' if r.tag else ''}",
        contents=[f"+ {r.path('why', f, ld)}"]) for r in runs for f, ld in pairs]
    return rrb.Horizontal(lanes, rrb.Vertical(*whys), column_shares=[2.1, 1], name="Detection") if whys else \
        rrb.Vertical(lanes, name="Detection")


def _scores(runs: list[Run]) -> rrb.Container:
    """Every detector's statistic against its threshold over the whole mission, the residual, and a colour key."""
    methods = {str(m) for r in runs if "method" in r.review.detections for m in r.review.detections["method"].unique()}
    leaders = len(_pairs(runs))         # the truth marks' rows below zero (series.log_truth_marks)
    plots: list[rrb.View] = [_series(f"{ld}: ANFIS vs T2 (m)", [f"+ {r.path('series', 'anfis', f, ld)}/**"
                                                               for r in runs], y_range=truth_range(anfis_top(runs), 1),
                                     legend=False)
                             for f, ld in _pairs(runs)]
    plots += [_series(title, _contents(runs, "scores", m), y_range=truth_range(score_top(runs, m), leaders),
                      legend=False) for m, title in scored().items() if m in methods]
    plots.append(_series("Range residual (m)", _contents(runs, "series", "residual"), legend=False))
    plots.append(rrb.TextDocumentView(name="Colours", contents=[f"+ {runs[0].path('scores', 'key')}"]))
    # three columns: the titles fit, and the default eight detectors make a 3 x 3 grid with the residual and key
    return rrb.Grid(*plots, grid_columns=3, name="Scores")


def _features(runs: list[Run]) -> rrb.Container:
    """Per leader: paper A's features, the ranges, and the computed new features by group (3 x 3 plots)."""
    have = {f for r in runs for f in present_features(r.review.detections)}
    by_pair = [{(str(k[0]), str(k[1])): rows for k, rows in r.groups(r.review.detections, ["follower", "leader"])}
               for r in runs]
    pairs = _pairs(runs)
    many = len({f for f, _ in pairs}) > 1
    tabs = []
    for f, ld in pairs:
        plots = [_series(f"{ld}: {feature_words(name)}", [f"+ {r.path('series', name, f, ld)}" for r in runs])
                 for name in ("f1_innovation_m", "f2_mahalanobis2", "f3_r_adapted_m2")]
        plots.append(_series(f"{ld}: range measured / true (m)", [f"+ {r.path('series', 'range', f, ld)}/**"
                                                                   for r in runs]))
        for key, title, names in FEATURE_GROUPS:
            shown = [n for n in names if n in have]
            if not shown:
                continue
            mine = [d[(f, ld)] for d in by_pair if (f, ld) in d]
            v = np.concatenate([floats(d, n) for d in mine for n in shown] or [np.zeros(0)])
            plots.append(_series(f"{ld}: {group_title(title, shown)}", [f"+ {r.path('features', f, ld, key)}/**"
                                                                        for r in runs],
                                 y_range=robust_range(v)))
        grid = rrb.Grid(*plots, grid_columns=3)
        notes = [r for r in runs if feature_note(r.review.detections)]
        tabs.append(rrb.Vertical(grid, rrb.TextDocumentView(
            name="Features this run did not compute", contents=[f"+ {r.path('features', 'note')}" for r in notes]),
            row_shares=[12, 1.3 if have else 6], name=f"{f + '/' if many else ''}{ld}") if notes else
            rrb.Vertical(grid, name=f"{f + '/' if many else ''}{ld}"))
    return rrb.Tabs(*tabs, name="Features")


def short_name(method: str) -> str:
    """A method's short name from the method table (the name itself for a method it does not know)."""
    entry = METHOD_TABLE.get(method)
    return entry.short if entry is not None else method


def _anfis_model(run: Run, model: str, inputs: tuple[str, ...]) -> rrb.Container:
    """One ANFIS model's tab, titled with its method and leader: note, MFs (x in the input's units), surface, why."""
    method, leader = model_parts(model)
    base = model_path(run, model)
    tag = f" [{run.tag}]" if run.tag else ""
    mf_bounds = rrb.VisualBounds2D(x_range=[-0.14, 1.1], y_range=[-1.12, 0.2])
    names = [input_title(n, method) for n in inputs]
    # titles short enough for a quarter of 1400 px: the learned MFs by the input's name, the cursor's by "now"
    mf = [rrb.Spatial2DView(name=n, contents=[f"+ {base}/training/mf/in{i}/**"],
                            visual_bounds=mf_bounds) for i, n in enumerate(names, start=1)]
    now = [rrb.Spatial2DView(name=f"{input_short(n)} now", contents=[f"+ {base}/explain/mf/in{i}/**",
                                                                      f"+ {base}/training/mf/in{i}/axis/**"],
                             visual_bounds=mf_bounds) for i, n in enumerate(names, start=1)]
    third = f"{input_short(names[2])} at median" if len(names) > 2 else "2 inputs"
    surface = rrb.Spatial3DView(name=f"Output surface, {third}",
                                eye_controls=rrb.EyeControls3D(kind="Orbital", position=(2.5, -1.7, 1.8),
                                                               look_target=(0.45, 0.45, 0.3), eye_up=(0, 0, 1)),
                                contents=[f"+ {base}/training/surface", f"+ {base}/training/axes",
                                          f"+ {base}/training/T2", f"+ {base}/training/T2_label",
                                          f"+ {base}/training/epoch"])
    return rrb.Horizontal(
        rrb.Vertical(*mf),
        rrb.Vertical(rrb.TextDocumentView(name=f"{method} {leader}", contents=[f"+ {base}/note"]),
                     surface, rrb.BarChartView(name="Training RMSE (m) per epoch",
                                               contents=[f"+ {base}/training/rmse_bars"],
                                               plot_legend=rrb.PlotLegend(visible=False)), row_shares=[1.7, 2.7, 1]),
        rrb.Vertical(*now),
        rrb.Vertical(rrb.Spatial2DView(name="Rule firing w",
                                       contents=[f"+ {base}/explain/firing/**", f"+ {base}/explain/firing_axis/**"],
                                       visual_bounds=rrb.VisualBounds2D(x_range=[-0.34, 1.12], y_range=[-1.2, 0.16])),
                     rrb.TextDocumentView(name="Verdict", contents=[f"+ {base}/explain/verdict"])),
        # the tab by the method's short name (eight models' tabs fit 1400 px); the note inside names it in full
        column_shares=[1, 1.4, 1, 1], name=f"{short_name(method)} {leader}{tag}",
    )


def _anfis(runs: list[Run]) -> rrb.Container | None:
    """One tab per ANFIS model that ran (method and leader), in the method table's order; with two runs, a
    model's A and B tabs side by side."""
    found: dict[str, list[tuple[Run, tuple[str, ...]]]] = {}
    for run in runs:
        epochs = {str(k[0]): rows for k, rows in run.groups(run.review.anfis_epochs, ["model"])}
        for m in set(epochs) | {str(k[0]) for k, _ in run.groups(run.review.anfis_explain, ["model"])}:
            found.setdefault(m, []).append((run, model_inputs(epochs.get(m))))
    tabs = [_anfis_model(run, m, inputs) for m in model_order(set(found)) for run, inputs in found[m]]
    return rrb.Tabs(*tabs, name="ANFIS") if tabs else None


def _kmcdf(runs: list[Run]) -> rrb.Container | None:
    views = []
    for run in runs:
        tag = f" [{run.tag}]" if run.tag else ""
        with_fixes = fix_methods(run.review.kmcdf)
        for (target,), rows in run.groups(run.review.kmcdf, ["target"]):
            t = str(target)
            half = kmcdf_half_width(run, t)
            methods = sorted(rows["method"].astype(str).unique())
            prelim = ", ".join(with_fixes) if with_fixes else "none"
            views.append(rrb.Spatial2DView(
                name=f"KMCDF {t}{tag}: fix - GPS (m); prelim. fixes of {prelim}: green kept, red C2 "
                     "(large on the rim: farther out)",
                contents=[f"+ {run.path('kmcdf', t, m)}/final" for m in methods]
                + [f"+ {run.path('kmcdf', t, m)}/fixes" for m in with_fixes]
                + [f"+ {run.path('kmcdf', t, 'truth')}/**"],
                visual_bounds=rrb.VisualBounds2D(x_range=[-half, half], y_range=[-half, half])))
            views.append(rrb.Spatial2DView(
                name=f"Nodes{tag} by name (red: delay judged abnormal) and {t}'s fixes",
                contents=[f"+ {run.path('kmcdf', t, methods[0])}/nodes", f"+ {run.path('local', t, 'gps')}/**"]
                + [f"+ {run.path('local', t, m)}/position" for m in methods],
                overrides={run.path("local", t, "gps", "trail"): _up_to_cursor()}))
    return rrb.Grid(*views, name="KMCDF", grid_columns=2) if views else None


EVENTS_TITLE_MAX = 44
"""Characters of the event log's title that fit its panel at 1400 px (a longer one is cut off)."""


def events_title(runs: list[Run]) -> str:
    """The event log's title: in a comparison it says once what A and B are (each line carries only the letter):
    "Events; chi_square_alpha: A 0.01, B 0.05", or "Events of A and B (What changed says which)" if that is too long."""
    if len(runs) < 2:
        return "Events"
    pairs = [[kv.split("=", 1) for kv in r.label.split(", ")] for r in runs]
    keys = [[p[0] for p in ps] for ps in pairs]
    if all(len(p) == 2 for ps in pairs for p in ps) and keys[0] == keys[1]:
        title = f"Events; {', '.join(keys[0])}: " + ", ".join(
            f"{r.tag} {'/'.join(p[1] for p in ps)}" for r, ps in zip(runs, pairs, strict=True))
    else:
        title = "Events; " + ", ".join(f"{r.tag} = {r.label}" for r in runs)
    return title if len(title) <= EVENTS_TITLE_MAX else "Events of A and B (What changed says which)"


def build_blueprint(runs: list[Run], error_top: float, active_tab: int | str = 0,
                    focus: Sequence[str] | None = None) -> rrb.Blueprint:
    """The workstation layout for one run or two compared; `error_top` the error plots' y extent.

    `focus` names the methods shown at first (None: each run's default focus; "all": every method).
    """
    tabs = [_scoreboard(runs, error_top, focus), _detection(runs), _scores(runs), _features(runs),
            _navigation(runs, focus),
            _vehicles(runs), _anfis(runs), _kmcdf(runs)]
    main = rrb.Tabs(*(t for t in tabs if t is not None), active_tab=active_tab)
    log = rrb.TextLogView(name=events_title(runs), contents=_contents(runs, "events"),
                          columns=rrb.archetypes.TextLogColumns(
                              timeline_columns=[rrb.encodings.TimelineColumn(MISSION)],
                              text_log_columns=[rrb.encodings.TextLogColumn("LogLevel"),
                                                rrb.encodings.TextLogColumn("Body")]))
    return rrb.Blueprint(
        rrb.Horizontal(main, log, column_shares=[3, 1.3]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        # Rerun 0.41's blueprint cannot place the cursor: paused, it opens at the mission's start (the time
        # series and lanes still show the whole mission); "following" would open on the last sample
        rrb.TimePanel(timeline=MISSION, state="collapsed", play_state="paused"),
    )
