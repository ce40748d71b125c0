"""The scoreboard: every method of a run ranked, with exactly the figures of its metrics (`metrics.json`).

One rule for the Rerun views, the HTML report and the command line: rows come
straight from `metrics["methods"]`, nothing is recomputed, so what a reviewer
reads on screen is what `replay --json` printed. Methods are ranked in their
group by horizontal error p50 after t_a (ties and missing errors by p90,
then name): the cooperative methods (filters and detectors, scored at the
follower's estimate) apart from the USBL positioning methods (scored at USBL
epochs), so a rank never compares errors of different epochs. Detection
columns sit beside the errors for the methods that detect; `verdict` says
the best of each group and the best detector in words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from replay.stack.methods import METHOD_TABLE

__all__ = ["DETECTION_COLUMNS", "ERROR_COLUMNS", "NAV_HEADINGS", "NAVIGATION_COLUMNS", "NavigationRow", "ScoreRow",
           "best_detector", "best_of_groups", "detectors_by_merit", "format_value", "method_kind", "navigation_rows",
           "scoreboard", "skipped_lines", "verdict", "window_text"]

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


GROUPS: dict[str, str] = {
    "cooperative": "cooperative estimates of the follower (filters and detectors), after t_a",
    "positioning": "USBL positioning, at the USBL epochs after t_a",
}
"""Group -> what its errors are measured on; each group is ranked on its own."""


@dataclass(frozen=True)
class ScoreRow:
    """One method's line: its rank in its group, its kind (filter, detector or positioning) and its figures."""

    rank: int
    method: str
    kind: str
    figures: dict[str, Any]

    @property
    def group(self) -> str:
        """'positioning' for USBL positioning methods, else 'cooperative'."""
        return "positioning" if self.kind == "positioning" else "cooperative"


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
    """Every method of `metrics["methods"]`: the cooperative group then positioning, best first in each,
    ranked within its group, with its error and detection figures unchanged."""
    out: list[ScoreRow] = []
    for group in GROUPS:
        items = [(m, r) for m, r in metrics.get("methods", {}).items()
                 if ("positioning" if method_kind(m) == "positioning" else "cooperative") == group]
        out += [ScoreRow(i + 1, method, method_kind(method), {k: row.get(k) for k in ERROR_COLUMNS + DETECTION_COLUMNS})
                for i, (method, row) in enumerate(sorted(items, key=_rank_key))]
    return out


def _number(value: Any) -> float:
    return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else math.nan


def detectors_by_merit(rows: list[ScoreRow]) -> list[ScoreRow]:
    """The scored detectors, fewest wrong decisions (FP + FN) after t_a first; ties by AUC, then name."""
    det = [r for r in rows if r.kind == "detector" and r.figures.get("fp") is not None]
    return sorted(det, key=lambda r: (_number(r.figures["fp"]) + _number(r.figures["fn"]),
                                      -_number(r.figures.get("auc")), r.method))


def best_detector(rows: list[ScoreRow]) -> ScoreRow | None:
    """The detector with the fewest wrong decisions (FP + FN) after t_a; ties by AUC, then name."""
    ranked = detectors_by_merit(rows)
    return ranked[0] if ranked else None


def best_of_groups(rows: list[ScoreRow]) -> dict[str, ScoreRow]:
    """Per group (GROUPS' order), its best method: the first of the group with a finite error p50."""
    out: dict[str, ScoreRow] = {}
    for r in rows:
        if r.group not in out and math.isfinite(_number(r.figures.get("error_p50_m"))):
            out[r.group] = r
    return {g: out[g] for g in GROUPS if g in out}


def verdict(metrics: dict[str, Any]) -> list[str]:
    """The answer in a few lines (markdown bold on names): the best of each group, the best detector, the window."""
    rows = scoreboard(metrics)
    lines = []
    best_rows = best_of_groups(rows)
    for group, label in (("cooperative", "Best position estimate"), ("positioning", "Best USBL positioning")):
        best = best_rows.get(group)
        if best is not None:
            f = best.figures
            lines.append(f"{label}: **{best.method}**, p50 {format_value(f.get('error_p50_m'))} m, "
                         f"p90 {format_value(f.get('error_p90_m'))} m")
    det = best_detector(rows)
    if det is not None:
        f = det.figures
        lines.append(f"Best detector: **{det.method}**, {format_value(f.get('fp'))} false alarms, "
                     f"{format_value(f.get('fn'))} misses, AUC {format_value(f.get('auc'))} "
                     f"({metrics.get('epochs', 0)} scored epochs, {metrics.get('anomalous', 0)} anomalous)")
    if not lines:
        lines.append("No cooperative or positioning method was scored in this run")
    lines.append(f"Scored {window_text(metrics)}")
    return lines


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
