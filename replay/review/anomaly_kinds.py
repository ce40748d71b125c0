"""Anomaly kinds of ranging epochs, from the labelled intervals `auvreplay simulate` writes (anomalies.csv).

An archive holds only each epoch's binary truth label (|Z_gps - Z| > T1); which
kind of anomaly made it (stale, drift, outlier; dropouts leave no epoch) is
known only from the simulator's intervals file. Epochs are matched to an
interval of their (follower, leader) link within MATCH_S: ranges are logged at
the reply's arrival, microseconds to milliseconds after the simulator's
interval times, and epochs are seconds apart.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from replay.errors import UserError

MATCH_S = 0.1
COLUMNS = ("vehicle", "leader", "kind", "start_s", "end_s")
NONE = "none"
DROPOUT_REASON = "a missed reply leaves no ranging epoch to judge"
USBL_REASON = "a USBL node's observation, judged by the positioning methods, not by the range detectors"


@dataclass(frozen=True)
class KindInterval:
    """One labelled interval: the measuring vehicle, the other end of the link, the kind, [start, end] s."""

    vehicle: str
    leader: str
    kind: str
    start_s: float
    end_s: float


def load_intervals(path: str | Path) -> list[KindInterval]:
    """The intervals of an anomalies.csv; a missing column or a bad number is one UserError naming the line."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read {path}: {exc}") from None
    reader = csv.DictReader(io.StringIO(text))
    missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
    if missing:
        raise UserError(f"{path}: not an anomalies.csv (no column {', '.join(missing)})")
    out = []
    for line, row in enumerate(reader, start=2):
        try:
            start, end = float(row["start_s"]), float(row["end_s"])
        except (TypeError, ValueError):
            raise UserError(f"{path}:{line}: start_s/end_s are not numbers") from None
        if not (math.isfinite(start) and math.isfinite(end)) or end < start:
            raise UserError(f"{path}:{line}: bad interval [{row['start_s']}, {row['end_s']}]")
        out.append(KindInterval(row["vehicle"], row["leader"], row["kind"] or NONE, start, end))
    return out


def not_ranging(kind: str) -> str | None:
    """Why a kind has no ranging epochs to tabulate (dropouts; the USBL kinds 'usbl_*'), or None."""
    if kind == "dropout":
        return DROPOUT_REASON
    return USBL_REASON if kind.startswith("usbl") else None


def epoch_kinds(detections: pd.DataFrame, intervals: list[KindInterval]) -> np.ndarray:
    """The kind of every detection row (by its t_s, follower, leader), 'none' outside every interval.

    Where intervals overlap, stale wins (the simulator freezes a stale segment after adding drift and
    outliers), then the later start.
    """
    kinds = np.full(len(detections), NONE, dtype=object)
    if not len(detections):
        return kinds
    t = detections["t_s"].to_numpy(float)
    follower = detections["follower"].to_numpy(str)
    leader = detections["leader"].to_numpy(str)
    order = sorted(intervals, key=lambda iv: (iv.kind == "stale", iv.start_s))
    for iv in order:
        m = (follower == iv.vehicle) & (leader == iv.leader) & (t >= iv.start_s - MATCH_S) & (t <= iv.end_s + MATCH_S)
        kinds[m] = iv.kind
    return kinds
