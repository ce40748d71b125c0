"""The scoreboard: every method of a run ranked, with exactly the figures of its metrics (`metrics.json`).

One rule for the Rerun views, the HTML report and the command line: rows come
straight from `metrics["methods"]`, nothing is recomputed, so what a reviewer
reads on screen is what `replay --json` printed. Methods are ranked by
horizontal error p50 after t_a (ties and missing errors by p90, then name);
detection columns sit beside the errors for the methods that detect.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from replay.stack.methods import METHOD_TABLE

__all__ = ["DETECTION_COLUMNS", "ERROR_COLUMNS", "NAV_HEADINGS", "NAVIGATION_COLUMNS", "NavigationRow", "ScoreRow",
           "format_value", "method_kind", "navigation_rows", "scoreboard", "skipped_lines", "window_text"]

ERROR_COLUMNS: tuple[str, ...] = ("error_p50_m", "error_p90_m", "error_rms_m")
DETECTION_COLUMNS: tuple[str, ...] = ("tp", "fp", "fn", "fpr", "fnr", "auc")
# a vehicle's own navigation against GPS at its fixes (replay.navigation): the worst fix in mission seconds
NAVIGATION_COLUMNS: tuple[str, ...] = ("error_p50_m", "error_p90_m", "error_max_m", "final_drift_pct", "worst_fix_s",
                                       "fixes", "scored_at")
NAV_HEADINGS: dict[str, str] = {"error_p50_m": "p50 (m)", "error_p90_m": "p90 (m)", "error_max_m": "max (m)",
                                "final_drift_pct": "last dive (% dist.)", "worst_fix_s": "worst fix (s)",
                                "fixes": "fixes", "scored_at": "scored at"}


def format_value(value: Any) -> str:
    """A figure as printed in metrics tables and the scoreboard: '-' for none, 3 decimals under 100, 1 above."""
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 100 else f"{value:.1f}"
    return str(value)


@dataclass(frozen=True)
class ScoreRow:
    """One method's line: its rank, its kind (filter, detector or positioning) and its metrics figures."""

    rank: int
    method: str
    kind: str
    figures: dict[str, Any]


def method_kind(method: str) -> str:
    """'detector' (an ACKF isolated by a detector), 'positioning' (USBL/LBL fixes) or 'filter'."""
    entry = METHOD_TABLE.get(method)
    return entry.kind if entry is not None else "filter"


def _rank_key(item: tuple[str, dict[str, Any]]) -> tuple[float, float, str]:
    method, row = item
    p50, p90 = row.get("error_p50_m"), row.get("error_p90_m")
    return (p50 if isinstance(p50, (int, float)) and math.isfinite(p50) else math.inf,
            p90 if isinstance(p90, (int, float)) and math.isfinite(p90) else math.inf, method)


def scoreboard(metrics: dict[str, Any]) -> list[ScoreRow]:
    """Every method of `metrics["methods"]`, best first, with its error and detection figures unchanged."""
    ranked = sorted(metrics.get("methods", {}).items(), key=_rank_key)
    return [ScoreRow(i + 1, method, method_kind(method),
                     {k: row.get(k) for k in ERROR_COLUMNS + DETECTION_COLUMNS})
            for i, (method, row) in enumerate(ranked)]


def window_text(metrics: dict[str, Any]) -> str:
    """The scoring window as a reviewer reads it: 't_a = 600 s to 1700 s (mission seconds)'."""
    window = metrics.get("window") or [math.nan, math.nan]
    return f"after t_a: {window[0]:.0f} s to {window[1]:.0f} s (mission seconds)"


@dataclass(frozen=True)
class NavigationRow:
    """One vehicle's source (dead reckoning from its DVL, its INS) against GPS at its fixes, ranked."""

    rank: int
    vehicle: str
    method: str
    figures: dict[str, Any]


def navigation_rows(metrics: dict[str, Any]) -> list[NavigationRow]:
    """Every vehicle's navigation sources of `metrics["navigation"]`, best first by p50 then p90, figures unchanged."""
    items = [((vehicle, method), row) for vehicle, nav in sorted(metrics.get("navigation", {}).items())
             for method, row in nav.get("methods", {}).items()]
    ranked = sorted(items, key=lambda kv: (*_rank_key((kv[0][1], kv[1]))[:2], kv[0]))
    return [NavigationRow(i + 1, vehicle, method, {k: row.get(k) for k in NAVIGATION_COLUMNS})
            for i, ((vehicle, method), row) in enumerate(ranked)]


def skipped_lines(metrics: dict[str, Any]) -> list[str]:
    """What the trial could not run, one line per method: 'ackf: needs modem ranges from a leader with a position'."""
    return [f"{method}: {why}" for method, why in metrics.get("skipped", {}).items()]
