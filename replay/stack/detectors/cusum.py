"""The ``cusum_drift`` detector: a two-sided CUSUM (replay.stack.cusum) on a filter-independent range residual.

The summed input (``features.cusum_input``) is by default ``drift_z`` of
`replay.stack.features`: the drift residual (the range against the
USBL-anchored position where fixes exist, else against the lagged reference
or the leader-exclusion filter, else dead reckoning) standardized by its own
median and MAD of 60-300 s before, with k and h in sigmas
(``cusum_k_sigma``, ``cusum_h_sigma``); or the raw ``drift_residual_m`` in
metres (``cusum_k_m``, ``cusum_h_m``), the first cut. The ACKF follows a
slow drift, so no innovation sees it; these residuals do not involve the
filter. The sums restart after every alarm (docs/design.md section 8).

The detector's h is set at training so that its alarm rate over the training
window's normal epochs is ``StackConfig.detection_fpr_target`` (default 2 %),
never below half the configured h (a floor that keeps an almost noise-free
window from making the test hair-trigger). Calibrated on the raw residual,
that rate did not carry past t_a: the residual's spread there was up to
twice the window's (seed 0, leader1: MAD-sigma 5.8 m in the window, 13.3 m
after), so the closed-loop false-alarm rate came out at 6.8-8 %; the
standardized input carries its own scale along the mission.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replay.events import EpochResult
from replay.stack.config import CHOICES, ConfigError, StackConfig
from replay.stack.cusum import Cusum, alarm_rate, calibrate_h
from replay.stack.detectors.base import Decision
from replay.stack.detectors.why_text import cmp, epoch_features, num
from replay.stack.features import FEATURE_NAMES
from replay.stack.training import TrainingSet

_METRES = "drift_residual_m"
_MIN_RECORDED = 100


@dataclass(frozen=True)
class CusumExplanation:
    """Why the drift CUSUM did (not) alarm at one epoch, for the views."""

    residual_m: float      # the residual added (drift_z in sigmas, or drift_residual_m in metres: `input`)
    allowance_m: float     # k, in the residual's unit
    up_m: float            # S+ after the epoch
    down_m: float          # S- after the epoch
    threshold_m: float     # h
    flagged: bool
    input: str = "drift_z"  # the feature summed: "drift_z" (sigmas, despite the _m names) or "drift_residual_m"


class CusumDriftDetector:
    """``cusum_drift``: a two-sided CUSUM on the drift residual, h set by the target false-alarm rate."""

    name = "cusum_drift"
    wide = True       # takes the whole FEATURE_NAMES vector, not paper A's (f1, f2, f3)

    def __init__(self, config: StackConfig) -> None:
        """k and h until training from ``config.features`` (in sigmas for drift_z, metres for drift_residual_m)."""
        self.config = config
        fc = config.features
        allowed = CHOICES["stack.features.cusum_input"]
        if fc.cusum_input not in allowed:
            raise ConfigError(f"features.cusum_input must be one of {allowed}, got {fc.cusum_input!r}")
        self.input = fc.cusum_input
        self._col = FEATURE_NAMES.index(self.input)
        sigma = self.input == "drift_z"
        self.k = float(fc.cusum_k_sigma if sigma else fc.cusum_k_m)
        self._h0 = float(fc.cusum_h_sigma if sigma else fc.cusum_h_m)
        self.threshold = self._h0
        self.thresholds: dict[str, float] = {"configured": self._h0}
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
        x = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))[:, self._col]
        normal = np.asarray(labels).ravel() == 0
        floor = 0.5 * self._h0
        h = calibrate_h([x[normal]], self.k, self.config.detection_fpr_target, floor)
        self.threshold = h
        self.thresholds = {"fpr_target": h, "configured": self._h0,
                           "used": h, "training_alarm_rate": alarm_rate(x[normal], self.k, h)}
        self._cusum = Cusum(self.k, h)

    def decide(self, features: np.ndarray) -> Decision:
        """Add the epoch's residual; flagged when a sum exceeds h (the runner then calls `reset`)."""
        up, down, alarm = self._cusum.step(float(features[self._col]), restart=False)
        return Decision(flagged=alarm, score=max(up, down), threshold=self.threshold)

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores: max(S+, S-) of a fresh CUSUM(k, trained h) over the rows (n, F) of one leader in order.

        The sums restart when they exceed the trained h, as in closed loop; a
        sweep of the threshold below h then reads the same statistic.
        """
        x = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))[:, self._col]
        c = Cusum(self.k, self.threshold)
        return np.array([max(c.step(float(v))[:2]) for v in x])

    def reset(self) -> None:
        """Restart the sums after an alarm."""
        self._cusum.reset()

    def explain(self, features: np.ndarray) -> CusumExplanation:
        """The sums as they stand (after the last `decide`) beside this epoch's residual, k and h."""
        c = self._cusum
        return CusumExplanation(float(features[self._col]), self.k, c.up, c.down, self.threshold,
                                max(c.up, c.down) > self.threshold, self.input)


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """max(S+, S-) against h, with the residual summed and its allowance k."""
    ex = detector.explain(epoch_features(r)) if isinstance(detector, CusumDriftDetector) else None
    unit = " m" if ex is not None and ex.input.endswith("_m") else " sd"
    text = f"S {num(r.score)} {cmp(r.flagged)} h {num(r.threshold)}{unit}"
    if ex is not None:
        text += f" ({ex.input} {ex.residual_m:+.2f}, k {ex.allowance_m:.2f})"
    return text
