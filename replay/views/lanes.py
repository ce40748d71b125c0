"""Detection lanes: one named lane per leader and detector, beside the truth, in a state timeline.

Rerun 0.41 labels a lane with its whole entity path, sorted naturally and case-blind, so the paths
are short and say what a lane is (one run per recording, or two under one root):
- ``/lanes/<leader>/_truth``: "anomaly" or "normal" (the truth label), so the labelled anomaly
  intervals are the lane's "anomaly" stretches ("_" sorts it first);
- ``/lanes/<leader>/<method>``: "hit", "false alarm", "miss" or "quiet" (a correct silence),
  "training" before t_a and "no label" where the truth is unknown;
- ``/lanes/_scoring_window``: "training" before t_a, "scored" after.
With several followers each path has the follower after ``/lanes``. In a comparison the run's label
comes last (``/lanes/leader1/chi_square/1_r_m_2.5``), so a detector's two runs are neighbours.
Every lane has a static StateConfiguration that fixes each state's label and colour, so hits, false
alarms and misses read the same in every lane; rows on `time` and `mission_s`, one per ranging epoch.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import rerun as rr

from replay.review.scoreboard import detectors_by_merit, scoreboard
from replay.views.common import Run, part

# state -> colour; the same in every lane and every run (errors loud, correct silence quiet)
STATES: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("hit", (40, 170, 70)),
    ("false alarm", (245, 150, 20)),
    ("miss", (220, 40, 40)),
    ("quiet", (95, 105, 120)),
    ("anomaly", (200, 40, 160)),
    ("normal", (95, 105, 120)),
    ("training", (60, 60, 70)),
    ("scored", (70, 120, 200)),
    ("no label", (150, 150, 150)),
)


def epoch_states(flagged: np.ndarray, label: np.ndarray, trained: np.ndarray) -> np.ndarray:
    """Per epoch: 'hit' (flagged, anomalous), 'false alarm', 'miss', 'quiet', 'training' or 'no label'."""
    out = np.where(flagged, np.where(label == 1, "hit", "false alarm"), np.where(label == 1, "miss", "quiet"))
    out = np.where(label < 0, "no label", out)
    return np.where(trained, out, "training").astype(object)


def truth_states(label: np.ndarray) -> np.ndarray:
    """Per epoch: 'anomaly' where the truth label is 1, 'normal' where 0, 'no label' otherwise."""
    return np.where(label == 1, "anomaly", np.where(label == 0, "normal", "no label")).astype(object)


def training_end_s(run: Run) -> float:
    """t_a of a run: the start of its metrics window (else the first explained ANFIS epoch, else 0)."""
    window = run.review.metrics.get("window") if run.review.metrics else None
    if window:
        return float(window[0])
    ex = run.review.anfis_explain
    return float(ex["t_s"].min()) if not ex.empty and "t_s" in ex else 0.0


LANES_ROOT = "/lanes"
TRUTH_LANE = "_truth"
WINDOW_LANE = "_scoring_window"


def lane_path(run: Run, *parts: str) -> str:
    """A lane's entity path: under LANES_ROOT, the run's label last in a comparison."""
    tail = (run.tag,) if run.tag else ()
    # `part` strips a leading "_", which sorts the truth and window lanes first: keep theirs
    return "/".join([LANES_ROOT, *(p if p in (TRUTH_LANE, WINDOW_LANE) else part(p) for p in (*parts, *tail))])


def lane_paths(run: Run, where: tuple[str, ...], leader: str, methods: list[str]) -> list[str]:
    """The lanes of one leader (`where`: (follower,) with several followers, else ()), truth first."""
    return [lane_path(run, *where, leader, TRUTH_LANE)] + [lane_path(run, *where, leader, m) for m in methods]


def _configure(rec: rr.RecordingStream, path: str) -> None:
    rec.log(path, rr.StateConfiguration(values=[s for s, _ in STATES], labels=[s for s, _ in STATES],
                                        colors=[c for _, c in STATES]), static=True)


def _send(rec: rr.RecordingStream, run: Run, path: str, t_s: np.ndarray, states: np.ndarray) -> None:
    _configure(rec, path)
    rec.send_columns(path, indexes=run.times(t_s), columns=rr.StateChange.columns(state=states.tolist()))


def log_lanes(rec: rr.RecordingStream, run: Run) -> None:
    """Every lane of a run: the scoring window, and per leader the truth and each detector."""
    det = run.review.detections
    t_a = training_end_s(run)
    present = {str(m) for m in det["method"].unique()} if "method" in det else set()
    # detectors best first (fewest false alarms and misses, as the scoreboard's verdict), then any other
    ranked = [r.method for r in detectors_by_merit(scoreboard(run.review.metrics))]
    order = [m for m in ranked if m in present] + [m for m in run.review.methods if m in present and m not in ranked]
    by_follower = run.groups(det, ["follower"])
    # a follower's leaders as the other views group them: the same rows, in time order, grouped once
    pairs = run.groups(det, ["follower", "leader"])
    for (follower,), f_rows in by_follower:
        where = (str(follower),) if len(by_follower) > 1 else ()
        t = np.unique(f_rows["t_s"].to_numpy(dtype=float))
        if t.size:
            marks = np.array([t[0], t_a, t[-1]]) if t[0] < t_a < t[-1] else np.array([t[0], t[-1]])
            _send(rec, run, lane_path(run, *where, WINDOW_LANE), marks,
                  np.where(marks < t_a, "training", "scored").astype(object))
        methods = order + sorted({str(m) for m in f_rows["method"].unique()} - set(order))
        for (pair_follower, leader), rows in pairs:
            if pair_follower != follower:
                continue
            paths = lane_paths(run, where, str(leader), methods)
            epochs = rows.drop_duplicates("t_s")
            label = pd.to_numeric(epochs["label"], errors="coerce").fillna(-1).to_numpy(dtype=int)
            _send(rec, run, paths[0], epochs["t_s"].to_numpy(dtype=float), truth_states(label))
            by_method = {str(k[0]): r for k, r in run.groups(rows, ["method"])}
            for path, method in zip(paths[1:], methods, strict=True):
                m_rows = by_method.get(method)
                if m_rows is None:
                    continue
                t_m = m_rows["t_s"].to_numpy(dtype=float)
                lab = pd.to_numeric(m_rows["label"], errors="coerce").fillna(-1).to_numpy(dtype=int)
                _send(rec, run, path, t_m, epoch_states(m_rows["flagged"].to_numpy(dtype=bool), lab, t_m > t_a))
