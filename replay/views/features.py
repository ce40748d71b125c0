"""Detection features, every detector's statistic against its threshold, and why each epoch was (not) flagged.

Entities under a run prefix P, on `time` and `mission_s`:
- ``P/features/<follower>/<leader>/<group>/<feature>``: the filter-independent features of
  `replay.stack.features` (EXTRA_FEATURES), grouped by unit and meaning (FEATURE_GROUPS):
  residuals against dead reckoning, against the USBL / lagged / leader-exclusion references
  (metres), the drift residual with its CUSUM (metres), the standardized residuals (sd) and the
  repeat count. A missing value is not drawn: each series is sent only where it is finite, as
  markers, so a gap reads as a gap (a line would bridge it);
- ``P/features/note``: a TextDocument saying which features this run did not compute (a plain
  replay of paper A's methods need not compute any);
- ``P/scores/<method>/<follower>/<leader>/{score,threshold}`` for every detector outside the ANFIS
  family (that one is `replay.views.series`' ``P/series/anfis``): chi_square's f2 against its gate,
  dual_threshold's max(f2/gate, S/h) against 1, cusum_drift's max(S+, S-) against h,
  anfis_hybrid's output against its false-alarm-rate threshold; ``.../truth``: triangles below zero at
  the truth's anomalous epochs (`replay.views.series.log_truth_marks`);
- ``P/why/<follower>/<leader>``: a TextDocument per epoch after t_a, headed by the truth label and
  the epoch's true range error (measured - GPS-true range), one line per detector with
  its outcome ("hit", "false alarm", "miss", "quiet") and what it compared (`replay.review.why`),
  and one at t = 0 saying that nothing is judged before t_a.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import rerun as rr

from replay.stack.features import EXTRA_FEATURES
from replay.stack.methods import methods
from replay.views.common import Run, epochs_of, floats
from replay.views.lanes import epoch_states, training_end_s
from replay.views.series import LEADER_RGB, log_truth_marks

# (key, title, features): one plot per group and leader; units never mix within a group; "{}" in a title
# takes the names of the group's features a run computed (REFERENCE_NAMES), so a short title fits
# titles of at most about 20 characters: "leader1: " and the title fit a third of the tab at 1400 x 875
FEATURE_GROUPS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("dr", "range - DR range (m)", ("dr_residual_m", "leader_consistency_m")),
    ("anchored", "vs {} (m)", ("usbl_residual_m", "lag_residual_m", "exclusion_residual_m")),
    ("drift", "DR model, CUSUM (m)", ("drift_residual_m", "drift_cusum_m", "model_innovation_m")),
    ("z", "standardized (sd)", ("drift_z", "exclusion_z")),
    ("repeats", "same range (count)", ("repeat_count",)),
)
FEATURE_RGB: dict[str, tuple[int, int, int]] = {
    "dr_residual_m": (90, 160, 255), "leader_consistency_m": (250, 170, 60),
    "usbl_residual_m": (60, 200, 120), "lag_residual_m": (235, 90, 200), "exclusion_residual_m": (200, 160, 0),
    "drift_residual_m": (90, 160, 255), "drift_cusum_m": (240, 80, 60),
    "drift_z": (90, 160, 255), "exclusion_z": (200, 160, 0), "repeat_count": (128, 128, 140),
    "model_innovation_m": (60, 200, 120),
}


def scored() -> dict[str, str]:
    """The detectors whose score is drawn against its threshold here, with the plot's title (the method table)."""
    return {m.name: m.score_plot[0] for m in methods("detector") if m.score_plot is not None}

FEATURE_WORDS: dict[str, str] = {
    # paper A's three, short enough for a plot title in a third of the tab at 1400 x 875
    "f1_innovation_m": "f1, innovation (m)", "f2_mahalanobis2": "f2, Mahalanobis²",
    "f3_r_adapted_m2": "f3, adaptive R (m²)",
    "dr_residual_m": "range - dead-reckoned range", "leader_consistency_m": "leader consistency",
    "usbl_residual_m": "vs USBL fix", "lag_residual_m": "vs lagged ACKF", "exclusion_residual_m": "vs other leaders",
    "drift_residual_m": "DR model residual", "drift_cusum_m": "its CUSUM", "drift_z": "drift, standardized",
    "exclusion_z": "exclusion, standardized", "repeat_count": "identical ranges in a row",
    "model_innovation_m": "DR model innovation",
}
"""Each feature in words, for plot titles and legends (the field names stay in the entity paths)."""


def feature_words(name: str) -> str:
    """A feature's name in words ("f1, innovation (m)"); an unknown name as it is."""
    return FEATURE_WORDS.get(name, name)


REFERENCE_NAMES: dict[str, str] = {"usbl_residual_m": "USBL", "lag_residual_m": "lagged",
                                   "exclusion_residual_m": "others"}


def group_title(title: str, shown: list[str]) -> str:
    """A group's plot title, "{}" filled with the names of the features shown."""
    return title.format(" / ".join(REFERENCE_NAMES.get(f, f) for f in shown)) if "{}" in title else title


def present_features(detections: pd.DataFrame) -> list[str]:
    """The EXTRA_FEATURES with at least one finite value in a run's detections."""
    return [f for f in EXTRA_FEATURES if np.isfinite(floats(detections, f)).any()]


def feature_note(detections: pd.DataFrame) -> str:
    """What the features views cannot show for this run, in a sentence ('' when every feature is there)."""
    have = present_features(detections)
    if not have:
        return ("The filter-independent features (repeat_count, residuals, drift_z, ...) were not computed in "
                "this run: a replay of paper A's methods need not compute them. Name a new method (cusum_drift, "
                "anfis_hybrid, drift_reference: `--set methods=...`), or run `make demo`, to see them here.")
    missing = [f for f in EXTRA_FEATURES if f not in have]
    if not missing:
        return ""
    return (f"Not computed in this run, so not drawn: {', '.join(missing)}"
            + (" (usbl_residual_m needs a USBL fix of the follower)." if "usbl_residual_m" in missing else "."))


def _finite_series(rec: rr.RecordingStream, run: Run, path: str, t_s: np.ndarray, v: np.ndarray, name: str,
                   rgb: tuple[int, int, int]) -> None:
    """Markers where `v` is finite: a missing feature leaves a gap, never a zero or a bridging line."""
    ok = np.isfinite(v)
    if not ok.any():
        return
    rec.log(path, rr.SeriesPoints(names=name, colors=[rgb], marker_sizes=1.5), static=True)
    rec.send_columns(path, indexes=run.times(t_s[ok]), columns=rr.Scalars.columns(scalars=v[ok]))


def _line(rec: rr.RecordingStream, run: Run, path: str, t_s: np.ndarray, v: np.ndarray, name: str,
          rgb: tuple[int, int, int], step: bool) -> None:
    ok = np.isfinite(v)
    if not ok.any():
        return
    rec.log(path, rr.SeriesLines(names=name, colors=[rgb], widths=1.2 if step else 1.0,
                                 interpolation_mode="StepAfter" if step else None), static=True)
    rec.send_columns(path, indexes=run.times(t_s[ok]), columns=rr.Scalars.columns(scalars=v[ok]))


def log_features(rec: rr.RecordingStream, run: Run) -> None:
    """Every computed feature per follower, leader and group, and the note on what is missing."""
    det = run.review.detections
    note = feature_note(det)
    if note:
        rec.log(run.path("features", "note"), rr.TextDocument(note), static=True)
    have = set(present_features(det))
    for (follower, leader), rows in run.groups(det, ["follower", "leader"]):
        epochs = epochs_of(run, rows)
        t = floats(epochs, "t_s")
        for key, _, names in FEATURE_GROUPS:
            for f in names:
                if f in have:
                    _finite_series(rec, run, run.path("features", str(follower), str(leader), key, f), t,
                                   floats(epochs, f), run.name(feature_words(f)), FEATURE_RGB[f])


LEADER_COLOUR_NAMES = ("orange", "blue", "violet", "green")     # of LEADER_RGB, for the colour key


def scores_key(leaders: list[str]) -> str:
    """The Scores tab's colour note, short enough for its grid cell with every detector plotted: the leaders'
    colours, the threshold and the truth marks (each plot's title says what it compares; the Detection tab's
    why lines spell out each statistic)."""
    colours = ", ".join(f"{LEADER_COLOUR_NAMES[k % len(LEADER_RGB)]} {leader}" for k, leader in enumerate(leaders))
    return (f"**Lines**: {colours}; grey: the threshold (above it: flagged). ANFIS plots: each method in its "
            "Scoreboard colour, its T2 a step line alike.\n\n**Triangles below 0**: the truth's anomalous epochs, "
            "in the leader's colour.\n\nWhat each statistic is: the why lines of the Detection tab.")


def log_detector_scores(rec: rr.RecordingStream, run: Run) -> None:
    """Each detector with a score plot (the method table): per leader its statistic, its threshold in grey and the
    truth marks; a key."""
    pairs = run.groups(run.review.detections, ["follower", "leader"])
    plotted = scored()
    shown = {str(m) for m in run.review.detections["method"].unique()} & set(plotted) \
        if "method" in run.review.detections else set()
    rec.log(run.path("scores", "key"), rr.TextDocument(scores_key([str(ld) for (_, ld), _ in pairs]),
                                                       media_type="text/markdown"), static=True)
    tops = {m: score_top([run], m) for m in shown}
    for k, ((follower, leader), rows) in enumerate(pairs):
        rgb = LEADER_RGB[k % len(LEADER_RGB)]
        for (method,), m_rows in run.groups(rows, ["method"]):
            m = str(method)
            if m not in plotted:
                continue
            base = run.path("scores", m, str(follower), str(leader))
            t = floats(m_rows, "t_s")
            _line(rec, run, base + "/score", t, floats(m_rows, "score"), run.name(f"{leader} {m}"), rgb, False)
            _line(rec, run, base + "/threshold", t, floats(m_rows, "threshold"), run.name(f"{leader} threshold"),
                  (150, 150, 150), True)
            log_truth_marks(rec, run, base + "/truth", m_rows, k, tops[m])


def score_top(runs: list[Run], method: str) -> float | None:
    """A score plot's y extent: four times the method's largest threshold (scores reach hundreds)."""
    v = np.concatenate([floats(rows, "threshold") for r in runs
                        for (m,), rows in r.groups(r.review.detections, ["method"]) if str(m) == method]
                       or [np.zeros(0)])
    v = v[np.isfinite(v)]
    return float(4.0 * v.max()) if v.size and v.max() > 0 else None


def range_error_at(ranges: pd.DataFrame | None, t_s: np.ndarray) -> np.ndarray:
    """The true range error (measured - GPS-true range, m) of one follower and leader's ranging epoch at each
    instant (`ranges` in time order); NaN where no epoch is at that instant or its truth is unknown."""
    out = np.full(t_s.size, np.nan)
    if ranges is None or ranges.empty or "residual_m" not in ranges:
        return out
    rt, err = floats(ranges, "t_s"), floats(ranges, "residual_m")
    k = np.clip(np.searchsorted(rt, t_s), 0, max(rt.size - 1, 0))
    same = np.abs(rt[k] - t_s) < 1e-6
    return np.where(same, err[k], np.nan)


def why_documents(rows: pd.DataFrame, t_a: float, ranges: pd.DataFrame | None = None) -> tuple[np.ndarray, list[str]]:
    """Per epoch after t_a of one follower and leader: its time and a markdown list, one line per detector, under
    a heading with the truth label and the epoch's true range error (from `ranges`, that pair's ranging epochs).

    `rows` in time order (as `groups` gives them); one join per epoch over contiguous slices.
    """
    keep = (floats(rows, "t_s") > t_a) & (rows["why"].astype(str) != "").to_numpy() if "why" in rows else None
    if keep is None or not keep.any():
        return np.zeros(0), []
    rows = rows[keep]
    t = floats(rows, "t_s")
    label = pd.to_numeric(rows["label"], errors="coerce").fillna(-1).to_numpy(dtype=int)
    state = epoch_states(rows["flagged"].to_numpy(dtype=bool), label, np.ones(len(rows), dtype=bool))
    lines = [f"- **{st}** {m}: {w}" for st, m, w in zip(state, rows["method"].astype(str), rows["why"].astype(str),
                                                        strict=True)]
    starts = np.flatnonzero(np.r_[True, t[1:] != t[:-1]])
    ends = np.r_[starts[1:], t.size]
    leaders = rows["leader"].astype(str).to_numpy()
    truth = np.where(label == 1, "anomaly", np.where(label == 0, "normal", "no label"))
    err = range_error_at(ranges, t[starts])
    said = np.where(np.isfinite(err), np.char.mod("; true range error %+.1f m", np.nan_to_num(err)), "")
    docs = [f"**{leaders[a]} at {t[a]:.1f} s: truth {truth[a]}{e}**\n\n" + "\n".join(lines[a:b])
            for a, b, e in zip(starts, ends, said, strict=True)]
    return t[starts], docs


def log_why(rec: rr.RecordingStream, run: Run) -> None:
    """The "why (not) flagged" document of every follower and leader, one per epoch after t_a."""
    t_a = training_end_s(run)
    ranges = dict(run.groups(run.review.ranges, ["follower", "leader"]))
    for (follower, leader), rows in run.groups(run.review.detections, ["follower", "leader"]):
        t, docs = why_documents(rows, t_a, ranges.get((follower, leader)))
        if docs:
            # before t_a the view would say "(empty)": say why instead
            t = np.r_[0.0, t]
            docs = [f"**{leader}**: the detectors train until t_a = {t_a:.0f} s; no epoch is judged before.", *docs]
            rec.send_columns(run.path("why", str(follower), str(leader)), indexes=run.times(t),
                             columns=rr.TextDocument.columns(text=docs, media_type=["text/markdown"] * len(docs)))
