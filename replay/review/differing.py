"""The epochs two runs decided differently, with the truth and which run was right: one rule for
`auvreplay compare` (results archives) and the viewer's table (ReviewData).

A detection is keyed by (ns from the trial start, follower, leader, method) and carries (flagged, truth
label). An epoch differs when the two runs' decisions differ, or when one run has no decision there. A
run is right on such an epoch when its decision equals the truth (flagged an anomalous range, or passed
a normal one).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from formats.units import NS

DetectionKey = tuple[int, str, str, str]
Decision = tuple[bool, int]


def detection_map(detections: pd.DataFrame) -> dict[DetectionKey, Decision]:
    """ReviewData's detections as (flagged, label) by (ns from the trial start, follower, leader, method)."""
    if detections.empty or any(c not in detections for c in ("t_s", "follower", "leader", "method", "flagged")):
        return {}
    ns = np.round(detections["t_s"].to_numpy(dtype=float) * NS).astype(np.int64).tolist()
    labels = (detections["label"].fillna(0).astype(int) if "label" in detections
              else pd.Series(0, index=detections.index)).tolist()
    flagged = detections["flagged"].astype(bool).tolist()
    keys = zip(ns, detections["follower"].astype(str), detections["leader"].astype(str),
               detections["method"].astype(str), strict=True)
    return {k: (f, lab) for k, f, lab in zip(keys, flagged, labels, strict=True)}


def right(decision: bool | None, label: int) -> bool:
    """Whether a run's decision on an epoch matches its truth label (no decision is never right)."""
    return decision is not None and decision == bool(label)


def differing_epochs(det_a: Mapping[DetectionKey, Decision], det_b: Mapping[DetectionKey, Decision]
                     ) -> tuple[dict[str, list[dict[str, Any]]], dict[str, dict[str, int]]]:
    """Per method, the epochs decided differently (mission seconds, follower, leader, a, b, label; in time
    order), and per method how many of them each run got right: {"a", "b", "epochs"}."""
    differing: dict[str, list[dict[str, Any]]] = {}
    tally: dict[str, dict[str, int]] = {}
    for key in sorted(set(det_a) | set(det_b)):
        da, db = det_a.get(key), det_b.get(key)
        fa, fb = (da[0] if da else None), (db[0] if db else None)
        if fa == fb:
            continue
        t_ns, follower, leader, method = key
        label = (da or db or (False, 0))[1]
        differing.setdefault(method, []).append({"mission_s": t_ns / NS, "follower": follower, "leader": leader,
                                                 "a": fa, "b": fb, "label": label})
        t = tally.setdefault(method, {"a": 0, "b": 0, "epochs": 0})
        t["epochs"] += 1
        t["a"] += int(right(fa, label))
        t["b"] += int(right(fb, label))
    return differing, tally


def decision_word(flagged: bool | None) -> str:
    """'flagged', 'passed', or '-' where the run made no decision."""
    return "-" if flagged is None else ("flagged" if flagged else "passed")


def truth_word(label: int) -> str:
    """The truth label in words."""
    return {1: "anomalous", 0: "normal"}.get(int(label), "unlabelled")


def who_was_right(row: Mapping[str, Any]) -> str:
    """'A' or 'B' (the run whose decision matches the truth) or 'neither'."""
    a, b = right(row["a"], row["label"]), right(row["b"], row["label"])
    return "A" if a and not b else "B" if b and not a else "both" if a else "neither"
