"""The ``stale_aware`` detector: fix_aware's tests, and a repeated range judged by its error predicted now.

A stale modem repeats its last range (``repeat_count`` > 0). A repeated
range carries nothing new, and its error is where the leader was when the
value was fresh against where it is now, a change of geometry that dead
reckoning and the DR error model predict well over tens of seconds. The DR
error model never takes a repeated range, so its current innovation
(``model_innovation_m``) on a repeated range is that error predicted, the
quantity the label thresholds at T1 (|Z_gps - Z| > T1). drift_reference
tests the same epoch on the lagged residual standardized by the mission's
spread, whose threshold rises where the model mispredicts normal ranges (a
compass deviation at turns, ``combined``): over development seeds
2001-2016 (docs/detection.md section 5) stale ranges were two thirds of
the anomalous epochs, and drift_reference missed 19 % of them under a
compass deviation against 4 % in the default scenario.

So at each epoch, in order:

- a USBL fix younger than ``usbl_max_age_s`` (``usbl_residual_m``
  finite): chi-square's test on f2, as `FixAwareDetector`;
- a repeated range with a model innovation: |model_innovation_m| against
  ``t1_m``, its score put on the threshold's scale as h·(|e|/T1)^8, above h
  exactly when |e| > T1 and steep (a threshold moved by 2x moves the cut in
  metres by 9 %), so the open-loop ranking of stale ranges is by their
  predicted error and the decision is |e| > T1 whatever h is calibrated to;
- otherwise drift_reference's score and decision.

No new key, nothing read from truth; both of fix_aware's thresholds are
calibrated on the training trial's normal epochs they decide (`calibrate`):
the drift part's on those neither repeated nor under a fresh fix, the
gate on those under a fresh fix.
"""

from __future__ import annotations

import math

import numpy as np

from replay.events import EpochResult
from replay.stack.config import StackConfig
from replay.stack.detectors.base import Decision
from replay.stack.detectors.fix_aware import FixAwareDetector
from replay.stack.detectors.fix_aware import why_line as fix_why
from replay.stack.detectors.why_text import cmp, num
from replay.stack.features import FEATURE_NAMES
from replay.stack.training import TrainingSet

_REPEAT = FEATURE_NAMES.index("repeat_count")
_USBL = FEATURE_NAMES.index("usbl_residual_m")
_INNOVATION = FEATURE_NAMES.index("model_innovation_m")
STEEP = 8.0
"""The power of |e|/T1 in a stale range's score: steep, so the cut stays near T1 for any threshold of 0.5-2x h."""


class StaleAwareDetector:
    """``stale_aware``: a repeated range's predicted error against T1; fix_aware's tests on every other epoch."""

    name = "stale_aware"
    wide = True

    def __init__(self, config: StackConfig) -> None:
        """fix_aware (drift_reference without a fresh fix, chi-square with one) and the label threshold T1."""
        self.inner = FixAwareDetector(config)
        self.t1 = float(config.t1_m)
        self.threshold = self.inner.threshold
        self.thresholds: dict[str, float] = dict(self.inner.thresholds)

    @property
    def threshold_z(self) -> float:
        """drift_reference's h_z (NaN with its metres input)."""
        return self.inner.threshold_z

    @property
    def threshold_m(self) -> float:
        """drift_reference's metres threshold h_m."""
        return self.inner.threshold_m

    def train_on(self, ts: TrainingSet) -> None:
        """Train the fix_aware part (drift_reference's metres threshold)."""
        self.inner.train_on(ts)
        self._after()

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Train the fix_aware part on wide rows (n, F)."""
        self.inner.train(features, range_error, labels)
        self._after()

    def calibrate(self, rows: np.ndarray, target: float) -> bool:
        """fix_aware's calibration on the normal rows (n, F) its tests decide: every row but a repeat without a fix.

        drift_reference's h on the rows neither repeated nor under a fresh
        fix, chi-square's gate on every row under one (repeated or not:
        the gate decides them all), as `FixAwareDetector.calibrate`; the
        stale test's cut is T1 and is not calibrated.
        """
        x = np.asarray(rows, dtype=float).reshape(-1, len(FEATURE_NAMES))
        judged = ~(x[:, _REPEAT] > 0) | np.isfinite(x[:, _USBL])
        done = self.inner.calibrate(x[judged], target)
        self._after()
        return done

    def _after(self) -> None:
        # fix_aware's threshold is drift_reference's (calibrated here, not by fix_aware)
        self.threshold = self.inner.threshold = self.inner.drift.threshold
        self.thresholds = {**self.inner.thresholds, "stale_t1_m": self.t1}

    def _stale(self, rows: np.ndarray) -> np.ndarray:
        """True where a row is a repeated range with a model innovation and no fresh fix."""
        return (rows[:, _REPEAT] > 0) & np.isfinite(rows[:, _INNOVATION]) & ~np.isfinite(rows[:, _USBL])

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores of wide rows (n, F) on the threshold's scale: h·(|e|/T1)^8 on a stale range."""
        rows = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))
        stale = self.threshold * (np.abs(rows[:, _INNOVATION]) / self.t1) ** STEEP
        return np.where(self._stale(rows), stale, self.inner.scores(rows))

    def decide(self, features: np.ndarray) -> Decision:
        """A stale range: |model_innovation_m| > T1 (as its score against h); else fix_aware's decision."""
        x = np.asarray(features, dtype=float)
        if bool(self._stale(x.reshape(1, -1))[0]):
            score = float(self.scores(x)[0])
            # its cut is T1 whatever g is, so a stale range only raises the running threshold (when marginal)
            return Decision(flagged=bool(abs(float(x[_INNOVATION])) > self.t1), score=score, threshold=self.threshold,
                            steps_down=False)
        return self.inner.decide(x)

    def reset(self) -> None:
        """No memory to forget."""


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """A stale range's predicted error against T1, else fix_aware's line."""
    if r.repeat_count > 0 and math.isfinite(r.model_innovation_m) and not math.isfinite(r.usbl_residual_m):
        t1 = float(getattr(detector, "t1", math.nan)) if detector is not None else math.nan
        return (f"repeated range: its error predicted now {r.model_innovation_m:+.1f} m "
                f"{cmp(r.flagged)} T1 {num(t1)} m (score {num(r.score)} against h {num(r.threshold)})")
    return fix_why(r, getattr(detector, "inner", None) if detector is not None else None)
