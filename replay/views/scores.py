"""The scoreboard on screen: every method ranked with metrics.json's figures, and what changed between two runs.

Entities under a run prefix P (static TextDocuments, markdown):
- ``P/scoreboard``: rank, method, kind, error p50/p90/RMS, TP/FP/FN/FPR/FNR/AUC, straight from
  `replay.review.scoreboard` (nothing recomputed), the window stated, and the best method by
  error and by detection said in words;
- ``P/changes`` (the second run of a comparison): what differs in the configuration, and per
  method which run did better.
"""

from __future__ import annotations

import math
from typing import Any

import rerun as rr

from replay.review.naming import run_labels
from replay.review.scoreboard import (
    DETECTION_COLUMNS,
    ERROR_COLUMNS,
    NAV_HEADINGS,
    NAVIGATION_COLUMNS,
    ScoreRow,
    format_value,
    navigation_rows,
    scoreboard,
    skipped_lines,
    window_text,
)
from replay.views.common import Run

HEADINGS = {"error_p50_m": "p50 (m)", "error_p90_m": "p90 (m)", "error_rms_m": "RMS (m)", "tp": "TP", "fp": "FP",
            "fn": "FN", "fpr": "FPR", "fnr": "FNR", "auc": "AUC"}


def _number(value: Any) -> float:
    return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else math.nan


def _count(value: float) -> str:
    return str(int(value)) if math.isfinite(value) else "-"


def best_detector(rows: list[ScoreRow]) -> ScoreRow | None:
    """The detector with the fewest wrong decisions (FP + FN) after t_a; ties by AUC, then name."""
    det = [r for r in rows if r.kind == "detector" and r.figures.get("fp") is not None]
    if not det:
        return None
    return min(det, key=lambda r: (_number(r.figures["fp"]) + _number(r.figures["fn"]),
                                   -_number(r.figures.get("auc")), r.method))


def scoreboard_markdown(run: Run) -> str:
    """The scoreboard of one run as a markdown document."""
    metrics = run.review.metrics
    rows = scoreboard(metrics)
    title = f"Scoreboard{' [' + run.label + ']' if run.label else ''}: {window_text(metrics)}"
    tail = _navigation_markdown(metrics) + _skipped_markdown(metrics)
    if not rows:
        return f"**{title}**\n\nno cooperative method ran in this run" + tail
    cols = ERROR_COLUMNS + DETECTION_COLUMNS
    lines = [f"**{title}**", "", "| # | method | kind | " + " | ".join(HEADINGS[c] for c in cols) + " |",
             "|---:|---|---|" + "---:|" * len(cols)]
    lines += [f"| {r.rank} | {r.method} | {r.kind} | " + " | ".join(format_value(r.figures.get(c)) for c in cols)
              + " |" for r in rows]
    best = rows[0]
    said = [f"Lowest error: **{best.method}** (p50 {format_value(best.figures.get('error_p50_m'))} m)."]
    det = best_detector(rows)
    if det is not None:
        f = det.figures
        said.append(f"Best detector: **{det.method}** ({format_value(f.get('fp'))} false alarms, "
                    f"{format_value(f.get('fn'))} misses, AUC {format_value(f.get('auc'))}).")
    return "\n".join(lines + ["", " ".join(said),
                              "", "Ranked by error p50, then p90. Detection columns only for detectors."]) + tail


def _navigation_markdown(metrics: dict[str, Any]) -> str:
    """Each vehicle's dead reckoning and INS against GPS at its fixes, ranked (empty without a navigation review)."""
    rows = navigation_rows(metrics)
    if not rows:
        return ""
    lines = ["", "", "**Own navigation against GPS at the fixes** (dead reckoning restarted at each fix)", "",
             "| # | vehicle | source | " + " | ".join(NAV_HEADINGS[c] for c in NAVIGATION_COLUMNS) + " |",
             "|---:|---|---|" + "---:|" * (len(NAVIGATION_COLUMNS) - 1) + "---|"]
    lines += [f"| {r.rank} | {r.vehicle} | {r.method} | "
              + " | ".join(format_value(r.figures.get(c)) for c in NAVIGATION_COLUMNS) + " |" for r in rows]
    return "\n".join(lines)


def _skipped_markdown(metrics: dict[str, Any]) -> str:
    """The methods this trial could not run, each with the input it lacked."""
    lines = skipped_lines(metrics)
    return "\n\n**Not run** (the trial lacks their inputs):\n\n" + "\n".join(f"- {s}" for s in lines) if lines else ""


def changes_markdown(runs: list[Run]) -> str:
    """What differs between two runs' configurations, and per method which run had the lower error p50."""
    a, b = runs
    names = run_labels([a.review.parameters, b.review.parameters])
    lines = [f"**A = {a.label or names[0]}** against **B = {b.label or names[1]}** (after t_a)", ""]
    ma, mb = a.review.metrics.get("methods", {}), b.review.metrics.get("methods", {})
    lines += ["| method | p50 A (m) | p50 B (m) | FP+FN A | FP+FN B | better |", "|---|---:|---:|---:|---:|---|"]
    for method in [m for m in ma if m in mb]:
        pa, pb = _number(ma[method].get("error_p50_m")), _number(mb[method].get("error_p50_m"))
        wa = _number(ma[method].get("fp")) + _number(ma[method].get("fn"))
        wb = _number(mb[method].get("fp")) + _number(mb[method].get("fn"))
        key = (wa, pa) if math.isfinite(wa) and math.isfinite(wb) and wa != wb else (pa, 0.0)
        other = (wb, pb) if math.isfinite(wa) and math.isfinite(wb) and wa != wb else (pb, 0.0)
        better = "same" if key == other or not (math.isfinite(key[0]) and math.isfinite(other[0])) else (
            "A" if key < other else "B")
        lines.append(f"| {method} | {format_value(ma[method].get('error_p50_m'))} | "
                     f"{format_value(mb[method].get('error_p50_m'))} | {_count(wa)} | {_count(wb)} | {better} |")
    lines += ["", "better: fewer wrong detections (FP + FN) where both runs detect, else the lower error p50."]
    return "\n".join(lines)


def log_scores(rec: rr.RecordingStream, runs: list[Run]) -> None:
    """The scoreboard of every run, and with two runs what changed."""
    for run in runs:
        rec.log(run.path("scoreboard"), rr.TextDocument(scoreboard_markdown(run), media_type="text/markdown"),
                static=True)
    if len(runs) == 2:
        rec.log(runs[1].path("changes"), rr.TextDocument(changes_markdown(runs), media_type="text/markdown"),
                static=True)
