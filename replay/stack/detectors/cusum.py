"""The ``cusum_drift`` detector: a two-sided CUSUM (replay.stack.cusum) on a filter-independent range residual.

The residual is ``drift_residual_m`` of `replay.stack.features`: the range
against the USBL-anchored position where fixes exist, else the
dead-reckoning range residual relative to its windowed median. The ACKF
follows a slow drift, so no innovation sees it; these residuals do not
involve the filter. The sums restart after every alarm (STACK.md section 2).

The detector's h is set at training so that its alarm rate over the training
window's normal epochs is ``StackConfig.detection_fpr_target`` (default 2 %),
never below the configured ``features.cusum_h_m`` / 2 (a floor that keeps an
almost noise-free window from making the test hair-trigger).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replay.stack.config import StackConfig
from replay.stack.cusum import Cusum, alarm_rate, calibrate_h
from replay.stack.detectors.base import Decision
from replay.stack.features import FEATURE_NAMES
from replay.stack.training import TrainingSet

_RESIDUAL = FEATURE_NAMES.index("drift_residual_m")
_MIN_RECORDED = 100


@dataclass(frozen=True)
class CusumExplanation:
    """Why the drift CUSUM did (not) alarm at one epoch, for the views."""

    residual_m: float      # the residual added (drift_residual_m)
    allowance_m: float     # k
    up_m: float            # S+ after the epoch
    down_m: float          # S- after the epoch
    threshold_m: float     # h
    flagged: bool


class CusumDriftDetector:
    """``cusum_drift``: a two-sided CUSUM on the drift residual, h set by the target false-alarm rate."""

    name = "cusum_drift"
    wide = True       # takes the whole FEATURE_NAMES vector, not paper A's (f1, f2, f3)

    def __init__(self, config: StackConfig) -> None:
        """k from ``config.features.cusum_k_m``; h until training: ``config.features.cusum_h_m``."""
        self.config = config
        self.k = float(config.features.cusum_k_m)
        self.threshold = float(config.features.cusum_h_m)
        self.thresholds: dict[str, float] = {"configured": self.threshold}
        self._cusum = Cusum(self.k, self.threshold)

    def train_on(self, ts: TrainingSet) -> None:
        """`train` on the recorded rows when they hold enough normal epochs, else on every row.

        An injected copy's normal rows right after an injected anomaly still
        carry it in their windowed residuals, and would set h for anomalies
        rather than for the normal noise.
        """
        rec = ts.recorded()
        use = rec if int(np.sum(rec.labels == 0)) >= _MIN_RECORDED else ts
        self.train(use.features, use.range_error, use.labels)

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Set h so that the training rows labelled normal alarm at the target rate (rows in time order)."""
        x = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))[:, _RESIDUAL]
        normal = np.asarray(labels).ravel() == 0
        floor = 0.5 * float(self.config.features.cusum_h_m)
        h = calibrate_h([x[normal]], self.k, self.config.detection_fpr_target, floor)
        self.threshold = h
        self.thresholds = {"fpr_target": h, "configured": float(self.config.features.cusum_h_m),
                           "used": h, "training_alarm_rate": alarm_rate(x[normal], self.k, h)}
        self._cusum = Cusum(self.k, h)

    def decide(self, features: np.ndarray) -> Decision:
        """Add the epoch's residual; flagged when a sum exceeds h (the runner then calls `reset`)."""
        up, down, alarm = self._cusum.step(float(features[_RESIDUAL]), restart=False)
        return Decision(flagged=alarm, score=max(up, down), threshold=self.threshold)

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores: max(S+, S-) of a fresh CUSUM(k, trained h) over the rows (n, F) of one leader in order.

        The sums restart when they exceed the trained h, as in closed loop; a
        sweep of the threshold below h then reads the same statistic.
        """
        x = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))[:, _RESIDUAL]
        c = Cusum(self.k, self.threshold)
        return np.array([max(c.step(float(v))[:2]) for v in x])

    def reset(self) -> None:
        """Restart the sums after an alarm."""
        self._cusum.reset()

    def explain(self, features: np.ndarray) -> CusumExplanation:
        """The sums as they stand (after the last `decide`) beside this epoch's residual, k and h."""
        c = self._cusum
        return CusumExplanation(float(features[_RESIDUAL]), self.k, c.up, c.down, self.threshold,
                                max(c.up, c.down) > self.threshold)
