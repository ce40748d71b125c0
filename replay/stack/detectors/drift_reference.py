"""The ``drift_reference`` detector: the range against a model of the DR error of a minute ago, on the mission's scale.

Its input (``drift_residual_m``, default ``drift_source`` "model") is the
range against `replay.stack.dr_error_model`'s filter of the follower's
dead-reckoning error, heading error and DVL scale error, as it was
``lag_s`` (60 s) ago, carried forward over the DR displacement since: it
follows the DR error as the vehicle turns, and holds none of a drift
younger than the lag, where the ACKF follows a slow drift (features module
docstring). It takes the USBL fixes where they exist. One epoch's score,
no memory: it flags every epoch while the residual stays beyond the
threshold, so there is no sum to restart after an alarm (docs/design.md
section 8) and its per-epoch recall is not capped as a restarting CUSUM's is.

It flags an epoch when |drift_z| > h_z and |drift_residual_m| > ``t1_m``
(a residual under the label threshold is not an anomaly). drift_z is the
residual against the median and MAD-scale of both leaders' residuals of
60-900 s ago (repeated ranges left out; features module), so the threshold
follows the trial's DR error. h_z is ``StackConfig.drift_reference_z``
(2.5), NOT trained: over development seeds 0-19 a training window's 98 %
quantile of drift_z did not predict the same trial's after t_a (r = 0.01,
measured on the stiff reference), so a trained h_z carried no information
about the test. 2.5 flags about 2 % of the normal epochs after t_a of
seeds 0-19 closed loop (2.4: 2.1 % on 0-9 and on 10-19; 2.6: 1.9 % and
1.5 %; with |residual| > T1 beside it). With drift_z scaled by the DR error
model's predicted sigma (issue 26) it was kept: on seeds 1-4 trained on 0
it flagged 1.4 % (default scenario) and 1.6 % (bottom-lock loss), against
1.6 % and 8.0 % unscaled without the held-step term; the held-out figures
are in docs/detection.md section 5.
With ``calibrate_thresholds`` and a training set carrying its trial's
normal epochs after t_a, h_z is instead their 2 % quantile (`calibrate`,
`replay.stack.calibration`; the default). One training trial's quantile
is decided by whether it had a burst of false alarms (docs/detection.md
section 5).
Where drift_z is NaN (the first ~70 s of a run) the metres threshold h_m
decides: the (1 - ``detection_fpr_target``) quantile of |drift_residual_m|
over the training rows labelled normal, never below ``t1_m``. The runner
trains it on every leader's rows together.

``drift_reference_input = "drift_residual_m"`` keeps the first form (586eecb):
|drift_residual_m| against h_m alone. Its h_m did not carry its false-alarm
rate to other trials: over training seeds 0-19 the 98 % quantile of a
600 s window ranged 9-18 m, and the false-alarm rate it gave on the other
seeds 1.2-17 % (mean 5.0 %; f07ec8a, 2026-12-01, measured 0.7-13.5 %, mean
3.7 %, on other runs): the residual's spread is the trial's DR error.
For a ramp residual rate·t its detection delay is h_m / rate (tests check
it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from replay.events import EpochResult
from replay.stack.calibration import MIN_ROWS
from replay.stack.config import CHOICES, ConfigError, StackConfig
from replay.stack.detectors.anfis_hybrid import fpr_threshold
from replay.stack.detectors.base import Decision
from replay.stack.detectors.why_text import cmp, num
from replay.stack.features import FEATURE_NAMES
from replay.stack.training import TrainingSet

_METRES = FEATURE_NAMES.index("drift_residual_m")
_Z = FEATURE_NAMES.index("drift_z")
_INPUTS = CHOICES["stack.drift_reference_input"]
_MIN_RECORDED = 100
Z_FLOOR = 1.0
"""A calibrated h_z never goes under one sigma of the mission's scale (a quantile of 0: |residual| > t1_m alone)."""


@dataclass(frozen=True)
class DriftReferenceExplanation:
    """Why drift_reference did (not) flag one epoch, for the views."""

    residual_m: float      # drift_residual_m: the range minus the DR error reference's prediction
    threshold_m: float     # h_m, the metres threshold (used where drift_z is NaN, or with the metres input)
    flagged: bool
    z: float = math.nan            # drift_z: the residual in units of the mission's pooled recent scale
    threshold_z: float = math.nan  # h_z (NaN with the metres input)


class DriftReferenceDetector:
    """``drift_reference``: flags |drift_z| > h_z with |drift_residual_m| > t1_m (h_z configured, h_m trained)."""

    name = "drift_reference"
    wide = True       # takes the whole FEATURE_NAMES vector, not paper A's (f1, f2, f3)

    def __init__(self, config: StackConfig) -> None:
        """h_m = t1_m until training; h_z = ``drift_reference_z`` (drift_z input) or none (metres input)."""
        if config.drift_reference_input not in _INPUTS:
            raise ConfigError(f"drift_reference_input must be one of {_INPUTS}, got {config.drift_reference_input!r}")
        if not config.drift_reference_z > 0.0:
            raise ConfigError(f"drift_reference_z must be positive, got {config.drift_reference_z!r}")
        self.config = config
        self.t1 = float(config.t1_m)
        self.threshold_m = self.t1
        # h_z is a configured multiple, not trained (config: one window's quantile does not carry)
        self.threshold_z = float(config.drift_reference_z) if config.drift_reference_input == "drift_z" \
            else math.nan
        self.threshold = self.threshold_z if math.isfinite(self.threshold_z) else self.t1
        self.z0 = float(config.drift_reference_z)     # the score's metres term is on this scale, calibrated or not
        self.thresholds: dict[str, float] = {"configured": self.t1}

    def train_on(self, ts: TrainingSet) -> None:
        """`train` on the recorded rows when they hold enough normal epochs, else on every row."""
        rec = ts.recorded()
        use = rec if int(np.sum(rec.labels == 0)) >= _MIN_RECORDED else ts
        self.train(use.features, use.range_error, use.labels)

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Set h_m so that at most the target share of the rows labelled normal score above it (h_z stays)."""
        x = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))
        normal = np.asarray(labels).ravel() == 0
        target = self.config.detection_fpr_target
        h_m = max(fpr_threshold(np.abs(x[normal, _METRES]), target), self.t1)
        self.threshold_m = h_m if math.isfinite(h_m) else self.t1      # no finite normal score: the floor
        self.threshold = self.threshold_z if math.isfinite(self.threshold_z) else self.threshold_m
        s = self.scores(x[normal])
        finite = s[np.isfinite(s)]
        self.thresholds = {"fpr_target": self.threshold_m, "configured": self.t1, "used": self.threshold,
                           "metres": self.threshold_m,
                           "training_alarm_rate": float(np.mean(finite > self.threshold)) if finite.size
                           else float("nan")}

    def calibrate(self, rows: np.ndarray, target: float) -> bool:
        """Set h to flag ``target`` of the training trial's normal rows (n, F) after t_a; False if too few.

        h is the (1 - target) quantile of `scores` over the rows with a
        drift_z, never under `Z_FLOOR`: it then flags |drift_z| > h with
        |drift_residual_m| > t1_m·h/h_z0 (h_z0 the configured
        ``drift_reference_z``), so the metres floor moves with h and a
        calibration can reach its target where few residuals pass t1_m (with
        USBL fixes). The metres input (no h_z) keeps its trained h_m.
        """
        if not math.isfinite(self.threshold_z):
            return False
        x = np.asarray(rows, dtype=float).reshape(-1, len(FEATURE_NAMES))
        x = x[np.isfinite(x[:, _Z]) & np.isfinite(x[:, _METRES])]
        if x.shape[0] < MIN_ROWS:
            return False
        h = max(fpr_threshold(self.scores(x), target), Z_FLOOR)
        self.threshold_z = self.threshold = h
        self.thresholds = {**self.thresholds, "configured_z": self.z0, "calibrated_z": h, "used": h,
                           "calibration_rows": float(x.shape[0])}
        return True

    def decide(self, features: np.ndarray) -> Decision:
        """Flag when the score exceeds the threshold (a NaN residual is not flagged).

        The decision is in the units of the test that made it: the score of
        `scores` against h_z where drift_z is finite, else |drift_residual_m|
        against h_m (metres), so a why line can show either as it is.
        """
        if math.isfinite(self.threshold_z) and not math.isfinite(float(features[_Z])):
            score = abs(float(features[_METRES]))
            return Decision(flagged=bool(score > self.threshold_m), score=score, threshold=self.threshold_m)
        score = float(self.scores(features)[0])
        return Decision(flagged=bool(score > self.threshold), score=score, threshold=self.threshold)

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores of the rows (n, F), on the scale of ``threshold``.

        With h_z: min(|z|, h_z0·|x|/t1_m) (h_z0 the configured multiple), above
        h_z = h_z0 exactly when |z| > h_z and |x| > t1_m (a residual under the
        label threshold is not an anomaly; a calibrated h_z moves that floor
        with it); where z is NaN, h_z·|x|/h_m (the metres threshold). Without
        h_z: |x|.
        """
        rows = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))
        x = np.abs(rows[:, _METRES])
        h_z = self.threshold_z
        if not math.isfinite(h_z):
            return x
        z = np.abs(rows[:, _Z])
        floored = np.minimum(z, self.z0 * x / self.t1) if self.t1 > 0.0 else z
        return np.where(np.isfinite(z), floored, h_z * x / self.threshold_m)

    def reset(self) -> None:
        """No memory to forget."""

    def explain(self, features: np.ndarray) -> DriftReferenceExplanation:
        """The residual, its standardized value and the thresholds at this epoch."""
        return DriftReferenceExplanation(float(features[_METRES]), self.threshold_m,
                                         self.decide(features).flagged, float(features[_Z]), self.threshold_z)


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """min(|drift_z|, h_z*|residual|/T1) against h_z in sd where drift_z exists, else |residual| against h_m (m)."""
    h_z = float(getattr(detector, "threshold_z", math.nan)) if detector is not None else math.nan
    in_sd = math.isfinite(r.drift_z) and (detector is None or math.isfinite(h_z))
    if in_sd:
        return (f"score {num(r.score)} {cmp(r.flagged)} h {num(r.threshold)} sd "
                f"(drift_z {r.drift_z:+.2f}, residual {r.drift_residual_m:+.1f} m, needs > T1 too)")
    return f"|drift residual| {num(r.score)} m {cmp(r.flagged)} h {num(r.threshold)} m"
