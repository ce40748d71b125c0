"""The scoreboard on screen: every method ranked with metrics.json's figures, and what changed between two runs.

Entities under a run prefix P (static TextDocuments, markdown):
- ``P/scoreboard``: rank, method, kind, error p50/p90/RMS, TP/FP/FN/FPR/FNR/AUC, straight from
  `replay.review.scoreboard` (nothing recomputed), the window stated, and the best method by
  error and by detection said in words;
- ``P/changes`` (the second run of a comparison): what differs in the configuration, and per
  method which run did better;
- ``P/differing`` (the second run of a comparison): every epoch the two runs decided differently, with its
  truth and which run was right (`replay.review.differing`, the rule `auvreplay compare` lists them by).
"""

from __future__ import annotations

import math
from typing import Any

import rerun as rr

from replay.review.differing import decision_word, detection_map, differing_epochs, truth_word, who_was_right
from replay.review.naming import run_labels
from replay.review.scoreboard import (
    DETECTION_COLUMNS,
    ERROR_COLUMNS,
    GROUPS,
    NAV_HEADINGS,
    NAVIGATION_COLUMNS,
    format_value,
    navigation_rows,
    scoreboard,
    skipped_lines,
    verdict,
)
from replay.views.common import Run

HEADINGS = {"error_p50_m": "p50 (m)", "error_p90_m": "p90 (m)", "error_rms_m": "RMS (m)", "tp": "TP", "fp": "FP",
            "fn": "FN", "fpr": "FPR", "fnr": "FNR", "auc": "AUC"}


def _number(value: Any) -> float:
    return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else math.nan


def _count(value: float) -> str:
    return str(int(value)) if math.isfinite(value) else "-"


def scoreboard_markdown(run: Run) -> str:
    """The scoreboard of one run as a markdown document: the verdict first, then each group's table."""
    metrics = run.review.metrics
    rows = scoreboard(metrics)
    title = f"Scoreboard of {run.tag} ({run.label})" if run.tag else "Scoreboard"
    lines = [f"**{title}**", ""] + [f"- {line}" for line in verdict(metrics)]
    cols = ERROR_COLUMNS + DETECTION_COLUMNS
    for group, what in GROUPS.items():
        in_group = [r for r in rows if r.group == group]
        if not in_group:
            continue
        lines += ["", f"**{what.capitalize()}**", "", "| # | method | kind | " + " | ".join(HEADINGS[c] for c in cols)
                  + " |", "|---:|---|---|" + "---:|" * len(cols)]
        lines += [f"| {r.rank} | {r.method} | {r.kind} | " + " | ".join(format_value(r.figures.get(c)) for c in cols)
                  + " |" for r in in_group]
    if rows:
        lines += ["", "Ranked in each group by error p50, then p90. Detection columns only for detectors."]
    return "\n".join(lines) + _navigation_markdown(metrics) + _skipped_markdown(metrics)


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
    lines = [f"**A = {a.label or names[0]}** (run {a.review.run_id}) against **B = {b.label or names[1]}** "
             f"(run {b.review.run_id}), after t_a. A is the first run given (`compare A B`, `view A B`, "
             "`replay --compare A`); series, lanes and events carry the letter.", ""]
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


DIFFERING_ROWS = 400
"""Rows of the table of differing epochs shown in the viewer (the rest counted; `auvreplay compare` lists all)."""


def differing_rows(runs: list[Run]) -> tuple[dict[str, list[dict[str, Any]]], dict[str, dict[str, int]]]:
    """The epochs runs A and B decided differently, per method, and how many each got right."""
    a, b = runs
    return differing_epochs(detection_map(a.review.detections), detection_map(b.review.detections))


def differing_markdown(runs: list[Run]) -> str:
    """The differing epochs as one markdown table in time order: time, pair, method, A, B, truth, who was right."""
    differing, tally = differing_rows(runs)
    if not differing:
        return "**Epochs that differ**: none; A and B decided every epoch alike."
    total = {k: sum(t[k] for t in tally.values()) for k in ("a", "b", "epochs")}
    lines = [f"**Epochs that differ: {total['epochs']}**; A right on {total['a']}, B on {total['b']} "
             "(mission seconds; right: the decision matches the truth)", ""]
    lines += [f"- {m}: {t['epochs']} epochs, A right on {t['a']}, B on {t['b']}" for m, t in tally.items()]
    rows = sorted(((r, m) for m, rs in differing.items() for r in rs), key=lambda x: (x[0]["mission_s"], x[1]))
    lines += ["", "| t (s) | pair | method | A | B | truth | right |", "|---:|---|---|---|---|---|---|"]
    lines += [f"| {r['mission_s']:.1f} | {r['follower']} <- {r['leader']} | {m} | {decision_word(r['a'])} | "
              f"{decision_word(r['b'])} | {truth_word(r['label'])} | {who_was_right(r)} |"
              for r, m in rows[:DIFFERING_ROWS]]
    if len(rows) > DIFFERING_ROWS:
        lines += ["", f"... {len(rows) - DIFFERING_ROWS} more (`auvreplay compare A B --limit N` lists them all)"]
    return "\n".join(lines)


def log_scores(rec: rr.RecordingStream, runs: list[Run]) -> None:
    """The scoreboard of every run, and with two runs what changed."""
    for run in runs:
        rec.log(run.path("scoreboard"), rr.TextDocument(scoreboard_markdown(run), media_type="text/markdown"),
                static=True)
    if len(runs) == 2:
        rec.log(runs[1].path("changes"), rr.TextDocument(changes_markdown(runs), media_type="text/markdown"),
                static=True)
        rec.log(runs[1].path("differing"), rr.TextDocument(differing_markdown(runs), media_type="text/markdown"),
                static=True)
