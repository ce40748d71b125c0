"""Closed-loop thresholds set on the training trial: the target false-alarm rate on its own normal epochs.

A method whose table entry says ``calibrated`` gets its threshold from the
training set's calibration rows (`TrainingSet.calibration`: the training
trial's epochs labelled normal after t_a, scored open loop, every leader),
as the (1 - ``detection_fpr_target``) quantile of the detector's scores
there, instead of a configured multiple. The rows come with a training set
that a whole run produced (`evaluate`'s train seed); a set that is a window
alone has none, and the detector keeps the threshold it trained.

Why the trial after t_a and not the window (issue 26, docs/detection.md
section 5): drift_reference's score is defined only after its scale has
~70 s of history, so a 600 s window holds ~180 normal epochs with a score,
about 4 beyond a 2 % quantile; over development seeds 30-36 the window's
quantile was 2.97 in one condition and 0 in another, the whole trial's
2.24 and 2.23.

A detector with a ``calibrate(rows, target)`` method does its own (its
score may depend on its threshold, as drift_reference's does); any other
gets ``threshold`` set to the quantile of ``scores(rows)``.
"""

from __future__ import annotations

import numpy as np

from replay.stack.detectors.anfis_hybrid import fpr_threshold
from replay.stack.detectors.base import Detector

MIN_ROWS = 200
"""Fewer finite calibration scores than this: the threshold stays as trained (a 2 % quantile of 200 is 4 epochs)."""


def calibrate(detector: Detector, rows: np.ndarray, target: float) -> bool:
    """Set the detector's threshold to flag ``target`` of the calibration rows (n, F); False if it kept its own."""
    rows = np.asarray(rows, dtype=float)
    if rows.ndim != 2 or rows.shape[0] < MIN_ROWS:
        return False
    own = getattr(detector, "calibrate", None)
    if callable(own):
        return bool(own(rows, target))
    scores = np.asarray(detector.scores(rows), dtype=float)
    if int(np.sum(np.isfinite(scores))) < MIN_ROWS or not hasattr(detector, "threshold"):
        return False
    detector.threshold = fpr_threshold(scores, target)
    return True
