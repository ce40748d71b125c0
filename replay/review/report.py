"""The shareable report of one replay run: one self-contained HTML file, nothing fetched at view time.

It holds the scoreboard (replay.review.scoreboard: exactly the figures of the
run's `metrics.json`, each cell carrying its stored value in `data-value`),
error CDFs and error-over-time for every method with an error series, the
detection timeline per leader and method beside the truth labels, t_a and the
anomaly intervals, a table per anomaly kind, and the run's configuration,
package version and input hash. Figures are inline SVG data URIs
(replay.review.report_plots); times are mission seconds from the trial start.
"""

from __future__ import annotations

import html
import json
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from replay.review.anomaly_kinds import NONE, KindInterval, epoch_kinds, not_ranging
from replay.review.data import ReviewData
from replay.review.naming import flatten
from replay.review.palette import method_hex
from replay.review.report_plots import (
    Lane,
    Span,
    cdf_figure,
    figure_uri,
    series_figure,
    timeline_figure,
    tracks_figure,
)
from replay.review.scoreboard import (
    DETECTION_COLUMNS,
    ERROR_COLUMNS,
    NAV_HEADINGS,
    NAVIGATION_COLUMNS,
    format_value,
    navigation_rows,
    scoreboard,
    skipped_lines,
    verdict,
    window_text,
)
from replay.stack.methods import detecting_names

KIND_ORDER = ("stale", "drift", "outlier", "dropout", "usbl_delay")
HEADINGS = {"error_p50_m": "p50 m", "error_p90_m": "p90 m", "error_rms_m": "RMS m", "tp": "TP", "fp": "FP",
            "fn": "FN", "fpr": "FPR", "fnr": "FNR", "auc": "AUC"}
CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; margin: 24px auto;
       max-width: 1320px; color: #1d1d1d; background: #ffffff; line-height: 1.4; }
h1 { font-size: 24px; margin-bottom: 4px; } h2 { font-size: 19px; margin-top: 34px;
     border-bottom: 1px solid #ddd; padding-bottom: 4px; }
p.sub, p.note { color: #555; margin: 4px 0 10px; } p.note { font-size: 14px; }
table { border-collapse: collapse; font-size: 14px; margin: 8px 0; }
th, td { border: 1px solid #d8d8d8; padding: 4px 9px; } th { background: #f3f3f3; text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.best td { background: #eef8ee; font-weight: 600; }
span.swatch { display: inline-block; width: 12px; height: 12px; border-radius: 2px; margin-right: 6px;
              vertical-align: -1px; }
img.plot { max-width: 100%; height: auto; display: block; margin: 8px 0; }
nav a { margin-right: 14px; } code { background: #f5f5f5; padding: 0 3px; }
table.config td { padding: 2px 9px; }
table.config td:first-child { font-family: ui-monospace, Menlo, Consolas, monospace; }
"""


@dataclass(frozen=True)
class DetectionTally:
    """What one detector decided on one leader's ranges after t_a: mission seconds of hits, false alarms, misses."""

    leader: str
    method: str
    hits: np.ndarray
    false_alarms: np.ndarray
    misses: np.ndarray


def _esc(value: Any) -> str:
    return html.escape(str(value), quote=True)


def detection_tallies(review: ReviewData, t_a: float) -> list[DetectionTally]:
    """Per (leader, detecting method) the epochs after t_a that were hits, false alarms and misses."""
    det = review.detections
    if not len(det):
        return []
    leaders, present = sorted(det["leader"].unique()), set(det["method"])
    det = det[det["t_s"] >= t_a]
    out = []
    for leader in leaders:
        for method in [m for m in detecting_names() if m in present]:
            d = det[(det["leader"] == leader) & (det["method"] == method)]
            flagged, label = d["flagged"].to_numpy(bool), d["label"].to_numpy(int) > 0
            t = d["t_s"].to_numpy(float)
            out.append(DetectionTally(leader, method, t[flagged & label], t[flagged & ~label], t[~flagged & label]))
    return out


def _label_spans(det: pd.DataFrame, leader: str) -> list[tuple[float, float]]:
    """Runs of consecutive labelled epochs of one leader's ranges (the truth where kinds are unknown)."""
    d = det[det["leader"] == leader].drop_duplicates("t_s").sort_values("t_s")
    t, lab = d["t_s"].to_numpy(float), d["label"].to_numpy(int) > 0
    spans, start = [], None
    for i in range(len(t)):
        if lab[i] and start is None:
            start = t[i]
        if start is not None and (not lab[i] or i == len(t) - 1):
            spans.append((start, t[i] if lab[i] else t[i - 1]))
            start = None
    return spans


def _scoreboard_html(metrics: dict[str, Any]) -> str:
    cols = ERROR_COLUMNS + DETECTION_COLUMNS
    head = "".join(f"<th>{HEADINGS[c]}</th>" for c in cols)
    rows = []
    for r in scoreboard(metrics):
        cells = "".join(f'<td class="num" data-key="{c}" data-value="{_esc(json.dumps(r.figures[c]))}">'
                        f"{_esc(format_value(r.figures[c]))}</td>" for c in cols)
        swatch = f'<span class="swatch" style="background:{_esc(method_hex(r.method))}"></span>'
        best = ' class="best"' if r.rank == 1 else ""
        rows.append(f'<tr{best} data-method="{_esc(r.method)}">'
                    f'<td class="num">{_esc(r.rank)}</td><td>{swatch}{_esc(r.method)}</td><td>{_esc(r.kind)}</td>'
                    f"{cells}</tr>")
    return (f'<table id="scoreboard-table"><tr><th>rank</th><th>method</th><th>kind</th>{head}</tr>'
            + "".join(rows) + "</table>")


def _bold(escaped: str) -> str:
    """Markdown's **bold** of an escaped verdict line as HTML <b>."""
    return re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", escaped)


def _navigation_html(metrics: dict[str, Any]) -> str:
    """Each vehicle's own navigation against GPS at its fixes, ranked, and the methods the trial could not run."""
    out = []
    rows = navigation_rows(metrics)
    if rows:
        head = "".join(f"<th>{_esc(NAV_HEADINGS[c])}</th>" for c in NAVIGATION_COLUMNS)
        body = "".join(
            f'<tr><td class="num">{_esc(r.rank)}</td><td>{_esc(r.vehicle)}</td><td>{_esc(r.method)}</td>'
            + "".join(f'<td class="num">{_esc(format_value(r.figures.get(c)))}</td>' for c in NAVIGATION_COLUMNS)
            + "</tr>" for r in rows)
        out.append('<h3>Own navigation against GPS at the fixes</h3><p class="sub">Dead reckoning from the DVL '
                   "and heading, restarted at each GPS fix, and the INS, each against the fix; scored at the fixes "
                   "that end a dive where the trial has dives (GPS gaps), else at every fix.</p>"
                   f'<table id="navigation-table"><tr><th>rank</th><th>vehicle</th><th>source</th>{head}</tr>'
                   f"{body}</table>")
    skipped = skipped_lines(metrics)
    if skipped:
        out.append('<h3>Not run</h3><ul id="skipped">' + "".join(f"<li>{_esc(s)}</li>" for s in skipped) + "</ul>")
    return "\n".join(out)


def _tracks_section(review: ReviewData) -> str:
    """Every position track of the run (GPS, INS, other sources, dead reckoning, estimates) on one local plot."""
    tr = review.tracks
    if tr.empty:
        return '<p class="note">No position track in this run.</p>'
    lines, colours, rows = {}, {}, []
    for (vehicle, source), g in tr.groupby(["vehicle", "source"], sort=True):
        name = f"{vehicle} {source}"
        lines[name] = (g["east_m"].to_numpy(float), g["north_m"].to_numpy(float))
        colours[name] = method_hex(str(source))
        t = g["t_s"].to_numpy(float)
        rows.append(f"<tr><td>{_esc(vehicle)}</td><td>{_esc(source)}</td><td class=\"num\">{len(g)}</td>"
                    f'<td class="num">{t.min():.0f}</td><td class="num">{t.max():.0f}</td></tr>')
    fig = tracks_figure(lines, colours)
    return (f'<img alt="tracks" src="{figure_uri(fig)}">'
            '<table id="tracks-table"><tr><th>vehicle</th><th>source</th><th>points</th><th>first (s)</th>'
            "<th>last (s)</th></tr>" + "".join(rows) + "</table>")


def _error_sections(review: ReviewData, metrics: dict[str, Any], t_a: float, end_s: float) -> tuple[str, str]:
    err = review.errors
    ranked = [r.method for r in scoreboard(metrics)]
    seen = list(dict.fromkeys(err["method"])) if len(err) else []
    order = ranked + [m for m in seen if m not in ranked]     # a series scored nowhere (no epoch after t_a) last
    methods = [m for m in order if m in seen]
    missing = [m for m in order if m not in methods]
    rows = {m: metrics["methods"].get(m, {}) for m in order}
    after = {m: err.loc[(err["method"] == m) & (err["t_s"] >= t_a), "error_m"].to_numpy(float) for m in methods}
    scored = [m for m in methods if len(after[m])]
    labels = {m: f"{m} ({format_value(rows[m].get('error_p50_m'))}, {format_value(rows[m].get('error_p90_m'))} m)"
              for m in scored}
    note = (f'<p class="note">No error series in the run for: {_esc(", ".join(missing))}.</p>' if missing else "")
    if scored:
        uri = figure_uri(cdf_figure(after, labels, window_text(metrics)))
        cdf = f'<img class="plot" alt="error CDF of every method" src="{uri}">' + note
    else:
        cdf = f'<p class="note">No error sample {_esc(window_text(metrics))}: nothing to draw.</p>'
    series = {m: (err.loc[err["method"] == m, "t_s"].to_numpy(float), err.loc[err["method"] == m, "error_m"]
                  .to_numpy(float)) for m in methods}
    titles = {m: f"{m}: p50 after t_a {format_value(rows[m].get('error_p50_m'))} m" for m in methods}
    over_time = note
    if methods:
        uri = figure_uri(series_figure(series, titles, t_a, end_s), tight=False)
        over_time = f'<img class="plot" alt="error over mission time per method" src="{uri}">' + note
    return cdf, over_time


def _timeline_section(review: ReviewData, tallies: list[DetectionTally], t_a: float, end_s: float,
                      intervals: list[KindInterval] | None) -> str:
    det = review.detections
    if not tallies:
        return '<p class="note">No detections in this run (no detecting method ran).</p>'
    lanes: list[Lane] = []
    spans: list[Span] = []
    for leader in sorted({t.leader for t in tallies}):
        first = len(lanes)
        d = det[det["leader"] == leader].drop_duplicates("t_s")
        lanes.append(Lane(f"{leader} · truth", truth=d.loc[d["label"] > 0, "t_s"].to_numpy(float)))
        for t in (t for t in tallies if t.leader == leader):
            lanes.append(Lane(f"{leader} · {t.method}  (TP {len(t.hits)}, FP {len(t.false_alarms)}, "
                              f"FN {len(t.misses)})", t.hits, t.false_alarms, t.misses))
        last = len(lanes) - 1
        if intervals is None:
            spans += [Span(first, last, a, b, "labelled") for a, b in _label_spans(det, leader)]
        else:
            spans += [Span(first, last, iv.start_s, iv.end_s, iv.kind) for iv in intervals
                      if iv.leader == leader and not_ranging(iv.kind) is None]
    what = ("simulator intervals by kind (anomalies.csv)" if intervals is not None
            else "runs of labelled epochs (kinds not recorded in the archive)")
    return (f'<p class="sub">Every lane counts after t_a = {t_a:.0f} s, as the scoreboard does; shaded: {what}.</p>'
            f'<img class="plot" alt="detection timeline" '
            f'src="{figure_uri(timeline_figure(lanes, spans, t_a, end_s))}">')


def _kinds_section(review: ReviewData, t_a: float, intervals: list[KindInterval] | None) -> str:
    det = review.detections
    methods = [m for m in detecting_names() if len(det) and m in set(det["method"])]
    if not methods:
        return '<p class="note">No detecting method ran: nothing to tabulate.</p>'
    det = det[det["t_s"] >= t_a]
    epochs = det.drop_duplicates(["t_s", "follower", "leader"])
    if intervals is None:
        note = ('<p class="note">The archive records each range\'s truth label (|Z<sub>GPS</sub> − Z| &gt; T1) but '
                "not the kind of anomaly behind it: kinds are known only from the simulator's "
                "<code>anomalies.csv</code> (give it with <code>--anomalies</code>). Below: labelled and normal "
                "epochs, kind unknown.</p>")
        kinds_e = np.where(epochs["label"].to_numpy(int) > 0, "labelled (kind unknown)", "normal")
        kinds_d = np.where(det["label"].to_numpy(int) > 0, "labelled (kind unknown)", "normal")
        order = ["labelled (kind unknown)", "normal"]
    else:
        note = ('<p class="note">Kinds from the simulator\'s intervals (anomalies.csv) matched to each range '
                "by its link and time; an epoch inside a kind's interval may still be labelled normal when its "
                "range stayed within T1 of GPS (flagging it then counts as a false alarm on the scoreboard).</p>")
        kinds_e, kinds_d = epoch_kinds(epochs, intervals), epoch_kinds(det, intervals)
        present = {iv.kind for iv in intervals}
        order = [k for k in KIND_ORDER if k in present] + sorted(present - set(KIND_ORDER) - {NONE}) + [NONE]
    head = "".join(f"<th>{_esc(m)} flagged</th>" for m in methods)
    rows = []
    for kind in order:
        reason = not_ranging(kind)
        if reason is not None:
            rows.append(f'<tr><td>{_esc(kind)}</td><td colspan="{2 + len(methods)}">{_esc(reason)}</td></tr>')
            continue
        sel = kinds_e == kind
        n, labelled = int(sel.sum()), int((epochs["label"].to_numpy(int)[sel] > 0).sum())
        cells = []
        for m in methods:
            dm = (kinds_d == kind) & (det["method"].to_numpy(str) == m)
            cells.append(f'<td class="num" data-kind="{_esc(kind)}" data-method="{_esc(m)}">'
                         f"{int(det['flagged'].to_numpy(bool)[dm].sum())} of {n}</td>")
        name = "none (outside every interval)" if kind == NONE else kind
        rows.append(f'<tr><td>{_esc(name)}</td><td class="num">{n}</td><td class="num">{labelled}</td>'
                    + "".join(cells) + "</tr>")
    return (note + f'<table id="kinds-table"><tr><th>kind</th><th>epochs after t_a</th><th>labelled anomalous</th>'
            f"{head}</tr>" + "".join(rows) + "</table>")


def _config_section(meta: dict[str, Any]) -> str:
    start = meta.get("trial_start_ns")
    start_ns = start if isinstance(start, int) and 0 <= start < 2**63 else 0
    facts = [("run id", meta.get("run_id")), ("package version", f"auvreplay {meta.get('package_version')}"),
             ("input file", meta.get("input_file")), ("input sha256", meta.get("input_sha256")),
             ("trial start (mission 0 s)", pd.Timestamp(start_ns, tz="UTC").isoformat() if start_ns else "-"),
             ("replay wall time", f"{meta.get('wall_time_s')} s")]
    top = "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in facts)
    params = meta.get("parameters") or {}
    rows = "".join(f"<tr><td>{_esc(k)}</td><td>{_esc(json.dumps(v))}</td></tr>"
                   for k, v in sorted(flatten(params).items()))
    return (f'<table id="run-table">{top}</table><h3>Configuration</h3>'
            f'<table class="config" id="config-table"><tr><th>parameter</th><th>value</th></tr>{rows}</table>')


def _notes_section(metrics: dict[str, Any]) -> str:
    items = [f"<li>{_esc(n)}</li>" for n in metrics.get("notes", [])]
    for follower, rejected in (metrics.get("rejected") or {}).items():
        items += [f"<li>{_esc(follower)}: {_esc(v)} ranges rejected ({_esc(k)})</li>" for k, v in rejected.items() if v]
    return "<ul>" + "".join(items) + "</ul>" if items else '<p class="note">None.</p>'


def build_report(meta: dict[str, Any], review: ReviewData, intervals: list[KindInterval] | None = None) -> str:
    """The HTML report of a run: `meta` its `run` metadata (metrics and parameters decoded), `review` its data,
    `intervals` the simulator's labelled anomaly intervals when known."""
    metrics = meta["metrics"]
    window = metrics.get("window") or [math.nan, math.nan]
    t_a, end_s = float(window[0]), float(window[1])
    tallies = detection_tallies(review, t_a)
    cdf, over_time = _error_sections(review, metrics, t_a, end_s)
    best = scoreboard(metrics)
    best_p50 = best[0].figures.get("error_p50_m") if best else None
    title = f"auvreplay report: {review.trial or meta.get('input_file', '')} run {meta.get('run_id')}"
    body = [
        f"<h1>{_esc(title)}</h1>",
        (f'<p class="sub">{_esc(window_text(metrics))}; {_esc(metrics.get("epochs"))} scored ranging epochs '
         f'({_esc(metrics.get("anomalous"))} labelled anomalous), {_esc(metrics.get("usbl_epochs"))} USBL epochs; '
         f"followers {_esc(', '.join(metrics.get('followers', [])))}."
         + ("</p>" if best_p50 is not None else " No epoch was scored: the run ended before t_a.</p>")),
        '<ul id="verdict">' + "".join(f"<li>{_bold(_esc(line))}</li>" for line in verdict(metrics)) + "</ul>",
        ('<nav><a href="#scoreboard">Scoreboard</a><a href="#tracks">Tracks</a>'
         '<a href="#cdf">Error CDF</a><a href="#series">Error over time</a>'
         '<a href="#timeline">Detections</a><a href="#kinds">By anomaly kind</a><a href="#run">Run</a></nav>'),
        '<h2 id="scoreboard">Scoreboard</h2>',
        (f'<p class="sub">Every method ranked by horizontal error p50 {_esc(window_text(metrics))}; figures '
         "exactly those of the run's metrics.json; detection columns for the detectors (an ACKF isolating what "
         "they flag).</p>"),
        _scoreboard_html(metrics),
        _navigation_html(metrics),
        '<h2 id="tracks">Tracks</h2>', _tracks_section(review),
        '<h2 id="cdf">Error CDF</h2>', cdf,
        '<h2 id="series">Error over time</h2>',
        '<p class="sub">The whole mission; dashed: t_a, where scoring starts.</p>', over_time,
        '<h2 id="timeline">Detection timeline</h2>', _timeline_section(review, tallies, t_a, end_s, intervals),
        '<h2 id="kinds">What each detector caught, by anomaly kind</h2>', _kinds_section(review, t_a, intervals),
        '<h2 id="run">Run</h2>', _config_section(meta),
        "<h3>Notes</h3>", _notes_section(metrics),
    ]
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{_esc(title)}</title><style>{CSS}</style></head><body>\n" + "\n".join(body)
            + "\n</body></html>\n")
