"""Scoring of detectors and filters (seed A, eqs. A.36-A.40; docs/design.md section 11).

* confusion counts and rates over epochs after t_a with known labels;
* ROC curves from open-loop scores (a threshold sweep over the same
  features), AUC and recall at FPR 1 / 5 / 10 %;
* horizontal position error of each method's track against the follower's
  GPS (the track interpolated to the GPS fix times), percentiles, RMS and the
  empirical CDF.

``score_run`` gives per method a dict with exactly the keys of docs/design.md
section 6 plus ``recall_at_fpr_1``, ``recall_at_fpr_10`` and
``capped``; undefined values (no positives, a non-detecting method) are None.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from replay.stack.labels import interpolate_track
from replay.stack.model import horizontal_distance_m

if TYPE_CHECKING:
    from replay.stack.runner import RunResults

RESULT_KEYS: tuple[str, ...] = (
    "tp", "tn", "fp", "fn", "accuracy", "precision", "recall", "fpr", "fnr", "auc",
    "recall_at_fpr_5", "error_p50_m", "error_p90_m", "error_rms_m",
)
"""The per-method keys of the machine-readable results (docs/design.md section 6), in order."""


@dataclass(frozen=True, slots=True)
class Confusion:
    """Confusion counts of one detector over labelled epochs (A.36-A.40)."""

    tp: int
    tn: int
    fp: int
    fn: int

    def rates(self) -> dict[str, float | None]:
        """Accuracy, precision, recall, FPR, FNR (A.36-A.40); None where the denominator is 0."""
        def ratio(num: int, den: int) -> float | None:
            """num / den, or None for an empty denominator."""
            return num / den if den else None
        total = self.tp + self.tn + self.fp + self.fn
        return {
            "accuracy": ratio(self.tp + self.tn, total),
            "precision": ratio(self.tp, self.tp + self.fp),
            "recall": ratio(self.tp, self.tp + self.fn),
            "fpr": ratio(self.fp, self.tn + self.fp),
            "fnr": ratio(self.fn, self.tp + self.fn),
        }


def confusion(flagged: np.ndarray, labels: np.ndarray) -> Confusion:
    """Count TP, TN, FP, FN; epochs with label -1 (no truth) are ignored."""
    flagged = np.asarray(flagged, dtype=bool)
    labels = np.asarray(labels)
    pos, neg = labels == 1, labels == 0
    return Confusion(int(np.sum(flagged & pos)), int(np.sum(~flagged & neg)),
                     int(np.sum(flagged & neg)), int(np.sum(~flagged & pos)))


def roc_curve(labels: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ROC points (fpr, tpr, thresholds) of 'flag when score >= threshold', from (0, 0) to (1, 1).

    Epochs with label -1 are ignored; a NaN score never flags (ranked below
    every finite score). Tied scores make one point, so a tie is a diagonal
    segment. Empty arrays when either class is absent or no score is finite
    (an untrained detector has no curve).
    """
    labels = np.asarray(labels)
    scores = np.asarray(scores, dtype=float)
    keep = (labels == 0) | (labels == 1)
    y, s = labels[keep] == 1, np.where(np.isfinite(scores[keep]), scores[keep], -np.inf)
    n_pos, n_neg = int(y.sum()), int((~y).sum())
    if n_pos == 0 or n_neg == 0 or not np.isfinite(s).any():
        empty = np.empty(0)
        return empty, empty.copy(), empty.copy()
    order = np.argsort(-s, kind="stable")
    s, y = s[order], y[order]
    last_of_run = np.r_[s[1:] != s[:-1], True]
    tp = np.cumsum(y)[last_of_run]
    fp = np.cumsum(~y)[last_of_run]
    thresholds = s[last_of_run]
    fpr = np.r_[0.0, fp / n_neg]
    tpr = np.r_[0.0, tp / n_pos]
    return fpr, tpr, np.r_[np.inf, thresholds]


def roc_auc(fpr: np.ndarray, tpr: np.ndarray) -> float | None:
    """Area under the ROC curve by the trapezoid rule; None for an empty curve."""
    if len(fpr) < 2:
        return None
    return float(np.sum(np.diff(fpr) * 0.5 * (tpr[1:] + tpr[:-1])))


def recall_at_fpr(fpr: np.ndarray, tpr: np.ndarray, target: float) -> float | None:
    """Best recall among operating points with FPR <= target (no interpolation); None for an empty curve."""
    if len(fpr) == 0:
        return None
    ok = fpr <= target + 1e-12
    return float(tpr[ok].max())


def horizontal_errors(
    track_t: np.ndarray, track_lat: np.ndarray, track_lon: np.ndarray,
    gps_t: np.ndarray, gps_lat: np.ndarray, gps_lon: np.ndarray,
    window: tuple[float, float] = (-np.inf, np.inf),
) -> np.ndarray:
    """Horizontal error (m) of a track against GPS fixes inside the window (track interpolated to fix times).

    Where the track holds several records at one time, the last one (after
    the update) is used. Fixes outside the track or not finite are dropped.
    """
    track_t = np.asarray(track_t, float)
    keep_last = np.r_[track_t[1:] != track_t[:-1], True] if track_t.size else np.zeros(0, bool)
    gps_t, gps_lat, gps_lon = (np.asarray(a, float) for a in (gps_t, gps_lat, gps_lon))
    sel = (gps_t >= window[0]) & (gps_t <= window[1]) & np.isfinite(gps_lat) & np.isfinite(gps_lon)
    lat, lon = interpolate_track(gps_t[sel], track_t[keep_last], np.asarray(track_lat)[keep_last],
                                 np.asarray(track_lon)[keep_last], max_gap_s=np.inf)
    err = horizontal_distance_m(lat, lon, gps_lat[sel], gps_lon[sel])
    return err[np.isfinite(err)]


def error_stats(errors: np.ndarray) -> dict[str, float | None]:
    """p50, p90 and RMS of horizontal errors (m); None when there are none."""
    e = np.asarray(errors, float)
    if e.size == 0:
        return {"error_p50_m": None, "error_p90_m": None, "error_rms_m": None}
    return {"error_p50_m": float(np.percentile(e, 50)), "error_p90_m": float(np.percentile(e, 90)),
            "error_rms_m": float(np.sqrt(np.mean(e * e)))}


def empirical_cdf(errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted errors and their empirical CDF values i/n (for the error-CDF plots)."""
    e = np.sort(np.asarray(errors, float))
    return e, np.arange(1, e.size + 1) / max(e.size, 1)


def detection_scores(flagged: np.ndarray, labels: np.ndarray, open_labels: np.ndarray,
                     open_scores: np.ndarray) -> dict[str, float | int | None]:
    """Confusion counts and rates of closed-loop decisions, and ROC figures of open-loop scores."""
    c = confusion(flagged, labels)
    fpr, tpr, _ = roc_curve(open_labels, open_scores)
    out: dict[str, float | int | None] = {"tp": c.tp, "tn": c.tn, "fp": c.fp, "fn": c.fn, **c.rates()}
    out["auc"] = roc_auc(fpr, tpr)
    for pct in (1, 5, 10):
        out[f"recall_at_fpr_{pct}"] = recall_at_fpr(fpr, tpr, pct / 100.0)
    return out


def score_run(
    results: RunResults, gps_t: np.ndarray, gps_lat_rad: np.ndarray, gps_lon_rad: np.ndarray,
    window: tuple[float, float] | None = None,
) -> dict[str, dict[str, float | int | None]]:
    """Per method the result dict (docs/design.md section 6) over a window (default: after t_a to the end).

    Detection figures use epochs with time in (t0, t1] and known labels;
    position errors use the follower's GPS fixes in [t0, t1].
    """
    t0, t1 = window if window is not None else (results.training_end_s, np.inf)
    ep = results.epochs
    out: dict[str, dict[str, float | int | None]] = {}
    for method in results.methods:
        row: dict[str, float | int | None] = {k: None for k in RESULT_KEYS}
        if method in results.open_loop:
            sel = (ep["method"] == method) & (ep["time_s"] > t0) & (ep["time_s"] <= t1)
            ol = results.open_loop[method]
            osel = (ol["time_s"] > t0) & (ol["time_s"] <= t1)
            row.update(detection_scores(ep["flagged"][sel], ep["label"][sel],
                                        ol["label"][osel], ol["score"][osel]))
        tr = results.tracks[method]
        row.update(error_stats(horizontal_errors(tr.t_s, tr.lat_rad, tr.lon_rad,
                                                 gps_t, gps_lat_rad, gps_lon_rad, (t0, t1))))
        row["capped"] = results.capped.get(method, 0)
        out[method] = row
    return out
