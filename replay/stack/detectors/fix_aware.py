"""The ``fix_aware`` detector: drift_reference's test without a fresh USBL fix, chi-square's with one.

What the drift residual is depends on the fix age (`replay.stack.features`):
without a USBL fix younger than ``lag_s`` it is the range against the DR
error model of a minute ago carried forward, which holds none of a young
drift, and drift_reference's test on it beats chi-square's by 2-4x on
the innovation of an ACKF that follows a slow drift. With a fresh fix it is
the model's current innovation: the fixes hold both the model and the ACKF
off a drift, so the two statistics are innovations of filters anchored by
the same fixes, and the ACKF's (f2, on the navigation filter's own
covariance) separates better in every condition measured
(docs/detection.md section 5: drift_reference 1.1-2.8x chi-square's FNR at
2 % FPR with USBL).

So at each epoch the test is the one that is informative at that fix age:

- no fix younger than ``usbl_max_age_s`` (``usbl_residual_m`` NaN): the
  `DriftReferenceDetector` score and decision, unchanged;
- a fresh fix (``usbl_residual_m`` finite; ``usbl_max_age_s`` and ``lag_s``
  are both 60 s by default, so this is when the drift residual is the
  model's innovation): f2 against chi-square's gate χ²₁(1 - α), the score
  put on drift_reference's scale as h_z·(f2 / gate)^`FRESH_POWER` (the
  innovation in sigmas, p = 1/2), so one threshold h_z serves both and the
  open-loop ranking within the fresh epochs is chi-square's.

The power sets what the running threshold (`replay.stack.running_threshold`)
does to the gate: its band (1.3 h) and its step act on the score, so on f2
they are 1.3^(1/p) and gain/p (p = 1/2: f2 in (T, 1.69 T), the cut moved
by twice the gain). A larger power (1, 2, 4) lifts the conditions whose
label noise lies in that band (sound speed, heavy tails, combined) but
slows g where the training gate is too low (drawn_usbl on 2001-2008: 3.6 %
to 8.1 % at p = 2), so it stays 1/2 (docs/detection.md section 5, "The
fresh-fix gate with USBL").

Calibrated (`calibrate`, marked in the method table): each test's threshold
flags the target share of the training trial's normal rows of its own fix
age, and the closed-loop decision runs through the running threshold
(`replay.stack.running_threshold`), as drift_reference's does.

The choice is by fix age, not learned per trial: on development seeds
(9101-9104 trained on 9100) the training set ranked chi-square above the
drift residual in every condition, with and without USBL, while the test
trials without USBL ranked them the other way, so neither a logistic
combination nor a choice made on the training set carried (figures in
docs/detection.md section 5).
"""

from __future__ import annotations

import math

import numpy as np

from replay.events import EpochResult
from replay.stack.calibration import MIN_ROWS
from replay.stack.config import StackConfig
from replay.stack.detectors.anfis_hybrid import fpr_threshold
from replay.stack.detectors.base import Decision
from replay.stack.detectors.chi_square import chi_square_threshold
from replay.stack.detectors.drift_reference import DriftReferenceDetector
from replay.stack.detectors.drift_reference import why_line as drift_why
from replay.stack.detectors.why_text import cmp, num
from replay.stack.features import FEATURE_NAMES
from replay.stack.training import TrainingSet

_F2 = FEATURE_NAMES.index("f2")
_USBL = FEATURE_NAMES.index("usbl_residual_m")
FRESH_POWER = 0.5
"""The power of f2/gate in a fresh epoch's score: the running threshold's band and step on f2 are 1.3^(1/p), gain/p."""


class FixAwareDetector:
    """``fix_aware``: chi-square's test on f2 where a USBL fix is fresh, drift_reference's elsewhere."""

    name = "fix_aware"
    wide = True

    def __init__(self, config: StackConfig) -> None:
        """The drift_reference detector it defers to without a fix, and chi-square's gate for the fresh epochs."""
        self.drift = DriftReferenceDetector(config)
        self.gate = chi_square_threshold(config.chi_square_alpha)
        self.threshold = self.drift.threshold
        self.thresholds: dict[str, float] = {**self.drift.thresholds, "chi_square_gate": self.gate}

    @property
    def threshold_z(self) -> float:
        """drift_reference's h_z (NaN with its metres input): the scale of the scores."""
        return self.drift.threshold_z

    @property
    def threshold_m(self) -> float:
        """drift_reference's metres threshold h_m (where drift_z is NaN and no fix is fresh)."""
        return self.drift.threshold_m

    def _scale(self) -> float:
        """The score a fresh epoch gets at f2 = gate: h_z, or drift_reference's metres threshold."""
        h_z = self.drift.threshold_z
        return h_z if math.isfinite(h_z) else self.drift.threshold

    def train_on(self, ts: TrainingSet) -> None:
        """Train the drift_reference part (its metres threshold); chi-square's gate is a quantile."""
        self.drift.train_on(ts)
        self._after_training()

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Train the drift_reference part on wide rows (n, F)."""
        self.drift.train(features, range_error, labels)
        self._after_training()

    def calibrate(self, rows: np.ndarray, target: float) -> bool:
        """Each part on its own rows (n, F): drift_reference's h without a fresh fix, chi-square's gate with one.

        The two parts are two tests on two populations of epochs (by fix
        age), so each takes the threshold flagging ``target`` of the
        training trial's normal rows of its own kind: the rows without a
        fresh fix through `DriftReferenceDetector.calibrate`, the gate as the
        (1 - target) quantile of f2 over the rows with one (f2 > gate then
        flags, whatever h is). A part with fewer than `MIN_ROWS` rows keeps
        its threshold (without USBL no row has a fix; with KMCDF's fixes
        every one has); False when neither moved.
        """
        x = np.asarray(rows, dtype=float).reshape(-1, len(FEATURE_NAMES))
        fresh = np.isfinite(x[:, _USBL])
        drift_done = self.drift.calibrate(x[~fresh], target)
        f2 = x[fresh, _F2]
        f2 = f2[np.isfinite(f2)]
        gate = fpr_threshold(np.abs(f2), target) if f2.size >= MIN_ROWS else math.nan
        chi_done = gate > 0.0       # NaN (too few rows) compares False
        if chi_done:
            self.gate = gate
        self._after_training()
        if chi_done:
            self.thresholds["calibration_rows_fresh"] = float(f2.size)
        return drift_done or chi_done

    def _after_training(self) -> None:
        self.threshold = self.drift.threshold
        self.thresholds = {**self.drift.thresholds, "chi_square_gate": self.gate}

    def decide(self, features: np.ndarray) -> Decision:
        """f2 against the gate (on the h_z scale) with a fresh fix; drift_reference's decision without."""
        x = np.asarray(features, dtype=float)
        if math.isfinite(float(x[_USBL])):
            score = float(self.scores(x)[0])
            return Decision(flagged=bool(score > self.threshold), score=score, threshold=self.threshold)
        return self.drift.decide(x)

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores of wide rows (n, F) on drift_reference's scale: h_z·(f2/gate)^p where a fix is fresh."""
        rows = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_NAMES))
        fresh = np.isfinite(rows[:, _USBL])
        chi = self._scale() * (np.abs(rows[:, _F2]) / self.gate) ** FRESH_POWER
        return np.where(fresh, chi, self.drift.scores(rows))

    def reset(self) -> None:
        """No memory to forget."""


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """Which test decided: chi-square's on f2 with a fresh USBL fix, else drift_reference's."""
    if math.isfinite(r.usbl_residual_m):
        gate = float(getattr(detector, "gate", math.nan)) if detector is not None else math.nan
        return (f"fresh USBL fix: f2 {num(r.f2)} {cmp(r.flagged)} gate {num(gate)} "
                f"(score {num(r.score)} against h {num(r.threshold)})")
    return "no fresh fix: " + drift_why(r, getattr(detector, "drift", None) if detector is not None else None)
