"""The metrics of a replay run: docs/design.md section 6, pooled over followers."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from replay.events import RunResults, RunScores
from replay.review.scoreboard import NAV_HEADINGS, NAVIGATION_COLUMNS, format_value, navigation_rows, skipped_lines
from replay.stack.methods import METHOD_TABLE
from replay.stack.scoring import RESULT_KEYS, detection_scores, error_stats


def _pool(parts: list[Any], dtype: Any) -> np.ndarray:
    """One array of the followers' columns (typed arrays or numpy), read in place where one follower holds it."""
    arrays = [np.asarray(p, dtype=dtype) for p in parts]
    if len(arrays) == 1:
        return arrays[0]
    return np.concatenate(arrays) if arrays else np.empty(0, dtype=dtype)


def _method_row(method: str, scores: RunScores, results: dict[str, RunResults]) -> dict[str, Any]:
    """One method's figures. Its pooled columns are narrow (int8 labels, bool flags) and freed on return, so the
    end of a long run holds one method's copies at a time."""
    followers = scores.followers.values()
    row = dict.fromkeys(RESULT_KEYS)
    if method in METHOD_TABLE and METHOD_TABLE[method].detects:
        flagged = _pool([s.flagged.get(method, ()) for s in followers], bool)
        labels = _pool([s.labels.get(method, ()) for s in followers], np.int8)
        ol = [r.open_loop[method] for r in results.values() if method in r.open_loop]
        row.update(detection_scores(flagged, labels, _pool([o["label"] for o in ol], np.int8),
                                    _pool([o["score"] for o in ol], float)))
        del flagged, labels
    row.update(error_stats(_pool([s.errors.get(method, ()) for s in followers], float)))
    row["capped"] = int(sum(r.capped.get(method, 0) for r in results.values()))
    return row


def run_metrics(scores: RunScores, results: dict[str, RunResults], run_id: str, end_s: float) -> dict[str, Any]:
    """The `replay --json` object from the engine's scores: run id, scoring window, epoch counts, per-method figures."""
    methods: dict[str, dict[str, Any]] = {m: _method_row(m, scores, results) for m in scores.methods}
    for method, errs in scores.positioning_errors.items():
        if len(errs):
            row: dict[str, Any] = {k: None for k in RESULT_KEYS}
            row.update(error_stats(np.asarray(errs)))
            row["epochs"] = len(errs)
            methods[method] = row
    return {
        "run_id": run_id,
        "window": [scores.training_end_s, end_s],
        "epochs": int(sum(s.epochs for s in scores.followers.values())),
        "anomalous": int(sum(s.anomalous for s in scores.followers.values())),
        "methods": _clean(methods),
        "followers": sorted(scores.followers),
        "usbl_epochs": scores.usbl_epochs,
        "rejected": {f: dict(r.rejected) for f, r in results.items()},
        "training_errors": {f: r.training_errors for f, r in results.items() if r.training_errors},
        "notes": list(scores.notes),
        "counts": dict(scores.counts),
        "skipped": dict(scores.skipped),
    }


def _clean(obj: Any) -> Any:
    """JSON-safe: numpy scalars to Python, NaN to None."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return None if not math.isfinite(float(obj)) else float(obj)
    return obj


def metrics_table(metrics: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per method (for CSV and the printed table)."""
    return [{"method": m, **{k: v.get(k) for k in RESULT_KEYS}} for m, v in metrics["methods"].items()]


def format_table(metrics: dict[str, Any]) -> str:
    """The printed metrics table."""
    cols = ["method", "tp", "tn", "fp", "fn", "accuracy", "fpr", "fnr", "auc", "error_p50_m", "error_p90_m"]
    lines = _plain_table(cols, [[format_value(r.get(c)) for c in cols] for r in metrics_table(metrics)])
    nav = navigation_rows(metrics)
    if nav:
        heads = ["vehicle", "source", *(NAV_HEADINGS[c] for c in NAVIGATION_COLUMNS)]
        lines += ["", "own navigation against GPS at the fixes (dead reckoning restarted at each fix):"]
        lines += _plain_table(heads, [[r.vehicle, r.method, *(format_value(r.figures.get(c))
                                                             for c in NAVIGATION_COLUMNS)] for r in nav], left=2)
    skipped = skipped_lines(metrics)
    if skipped:
        lines += ["", "not run:"] + [f"  {s}" for s in skipped]
    return "\n".join(lines)


def _plain_table(heads: list[str], rows: list[list[str]], left: int = 1) -> list[str]:
    """Lines of a fixed-width table: the first `left` columns left-aligned, the others right-aligned."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(heads)]
    def line(cells: list[str]) -> str:
        return "  ".join(v.ljust(w) if i < left else v.rjust(w) for i, (v, w) in enumerate(zip(cells, widths)))
    return [line(heads), "  ".join("-" * w for w in widths)] + [line(r) for r in rows]
