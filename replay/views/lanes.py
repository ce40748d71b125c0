"""Detection lanes: one named lane per leader and detector, beside the truth, in a state timeline.

Rerun 0.41 labels a lane with its whole entity path, sorted naturally and case-blind, so the paths
are short, say what a lane is, and carry their rank so that the sort puts them in the scoreboard's
order (one run per recording, or two under one root):
- ``/lanes/<leader>/0_truth``: "anomaly" or "normal" (the truth label), so the labelled anomaly
  intervals are the lane's "anomaly" stretches;
- ``/lanes/<leader>/<rank>_<method>``: the detectors best first (1 = fewest false alarms plus misses,
  as the verdict), "hit", "false alarm", "miss" or "quiet" (a correct silence), "training" before t_a
  and "no label" where the truth is unknown;
- ``/lanes/_scoring_window``: "training" before t_a, "scored" after;
- ``/lanes/_key``: not a time series but the key of the colours, each state named over an equal share
  of the mission. The other lanes write no state names in their segments: a segment one epoch long
  would cut the name ("mi", "fals"). With several followers each path has the follower after
``/lanes``. In a comparison the run's label comes last (``/lanes/leader1/1_chi_square/1_r_m_2.5``) and
both runs take the first run's ranks, so a detector's two runs are neighbours.
Every lane has a static StateConfiguration that fixes each state's label and colour, so hits, false
alarms and misses read the same in every lane; rows on `time` and `mission_s`, one per ranging epoch.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pandas as pd
import rerun as rr

from replay.review.scoreboard import detectors_by_merit, scoreboard
from replay.views.common import Run, epochs_of, floats, part

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
TRUTH_LANE = "0_truth"
WINDOW_LANE = "_scoring_window"


def lane_path(run: Run, *parts: str) -> str:
    """A lane's entity path: under LANES_ROOT, the run's label last in a comparison."""
    tail = (run.tag,) if run.tag else ()
    # `part` strips a leading "_", which sorts the window lane first: keep it
    return "/".join([LANES_ROOT, *(p if p == WINDOW_LANE else part(p) for p in (*parts, *tail))])


def lane_paths(run: Run, where: tuple[str, ...], leader: str, methods: list[str]) -> list[str]:
    """The lanes of one leader (`where`: (follower,) with several followers, else ()): the truth, then each
    method with its 1-based rank in `methods` before its name, so Rerun's natural sort keeps that order."""
    return [lane_path(run, *where, leader, TRUTH_LANE)] + [lane_path(run, *where, leader, f"{i}_{m}")
                                                           for i, m in enumerate(methods, start=1)]


def detector_order(run: Run) -> list[str]:
    """The run's detectors best first (fewest false alarms and misses, as the scoreboard's verdict), then any
    other detecting method of its table."""
    det = run.review.detections
    present = {str(m) for m in det["method"].unique()} if "method" in det else set()
    ranked = [r.method for r in detectors_by_merit(scoreboard(run.review.metrics))]
    order = [m for m in ranked if m in present] + [m for m in run.review.methods if m in present and m not in ranked]
    return order + sorted(present - set(order))


KEY_LANE = "_key"
KEY_STATES = ("hit", "false alarm", "miss", "quiet", "anomaly", "training")
"""The states the key lane spells out, each over an equal share of the mission (the others: scoring window)."""


def _configure(rec: rr.RecordingStream, path: str, labelled: bool) -> None:
    """A lane's states and colours; `labelled`: the state's name written in its segments (else blank: a lane of
    one-epoch segments would show "mi", "fals"; the key lane names the colours). Blank is a space: Rerun
    0.41 writes the raw value for an empty label."""
    rec.log(path, _state_configuration(labelled), static=True)


@cache
def _state_configuration(labelled: bool) -> rr.StateConfiguration:
    """The lanes' configuration, built once (every lane logs one of the two)."""
    return rr.StateConfiguration(values=[s for s, _ in STATES], labels=[s if labelled else " " for s, _ in STATES],
                                 colors=[c for _, c in STATES])


def _send(rec: rr.RecordingStream, run: Run, path: str, t_s: np.ndarray, states: np.ndarray,
          labelled: bool = False) -> None:
    _configure(rec, path, labelled)
    rec.send_columns(path, indexes=run.times(t_s), columns=rr.StateChange.columns(state=states.tolist()))


def key_segments(t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """The key lane: each of KEY_STATES over an equal share of [t0, t1] (its start times, its states)."""
    edges = np.linspace(t0, t1, len(KEY_STATES) + 1)
    return np.r_[edges[:-1], t1], np.array([*KEY_STATES, KEY_STATES[-1]], dtype=object)


def log_lanes(rec: rr.RecordingStream, run: Run, order: list[str] | None = None) -> None:
    """Every lane of a run: the scoring window, and per leader the truth and each detector in `order` (default:
    `detector_order(run)`; a comparison passes the first run's, so both runs rank a detector alike)."""
    det = run.review.detections
    t_a = training_end_s(run)
    order = detector_order(run) if order is None else order
    by_follower = run.groups(det, ["follower"])
    t_all = floats(det, "t_s") if "t_s" in det else np.zeros(0)
    if run.index == 0 and t_all.size:        # one key per recording, sorted to the top ("_")
        _send(rec, run, f"{LANES_ROOT}/{KEY_LANE}", *key_segments(float(t_all.min()), float(t_all.max())),
              labelled=True)
    # a follower's leaders as the other views group them: the same rows, in time order, grouped once
    pairs = run.groups(det, ["follower", "leader"])
    for (follower,), f_rows in by_follower:
        where = (str(follower),) if len(by_follower) > 1 else ()
        t = np.unique(f_rows["t_s"].to_numpy(dtype=float))
        if t.size:
            marks = np.array([t[0], t_a, t[-1]]) if t[0] < t_a < t[-1] else np.array([t[0], t[-1]])
            _send(rec, run, lane_path(run, *where, WINDOW_LANE), marks,
                  np.where(marks < t_a, "training", "scored").astype(object), labelled=True)

        methods = order + sorted({str(m) for m in f_rows["method"].unique()} - set(order))
        for (pair_follower, leader), rows in pairs:
            if pair_follower != follower:
                continue
            paths = lane_paths(run, where, str(leader), methods)
            epochs = epochs_of(run, rows)
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
