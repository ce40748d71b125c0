"""Residual chi-square test (seed A §4.2 baseline, docs/design.md section 11).

γ = 1 when f2 = rᵀ P_zz⁻¹ r (A.29, on the unadapted P_zz) exceeds the
chi-square quantile χ²₁(1 - α) of a one-dimensional measurement.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from replay.events import EpochResult
from replay.stack.config import StackConfig
from replay.stack.detectors.base import Decision
from replay.stack.detectors.why_text import cmp, num
from replay.stack.training import TrainingSet


def chi_square_threshold(alpha: float, dof: int = 1) -> float:
    """χ²_dof(1 - α): e.g. 6.635 for α = 0.01 and one degree of freedom."""
    return float(chi2.ppf(1.0 - alpha, dof))


class ChiSquareDetector:
    """Flags an epoch when its squared Mahalanobis distance f2 exceeds χ²₁(1 - α); no training, no memory."""

    name = "chi_square"

    def __init__(self, config: StackConfig) -> None:
        """Threshold from ``config.chi_square_alpha``."""
        self.threshold = chi_square_threshold(config.chi_square_alpha)

    def train_on(self, ts: TrainingSet) -> None:
        """`train` on the rows' features, range errors and labels."""
        self.train(ts.features, ts.range_error, ts.labels)

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Nothing to fit: the threshold is a quantile."""

    def decide(self, features: np.ndarray) -> Decision:
        """Compare f2 with the threshold; a non-finite f2 is not flagged (it cannot be judged)."""
        f2 = float(features[1])
        return Decision(flagged=bool(f2 > self.threshold), score=f2, threshold=self.threshold)

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores: f2 of every epoch (n, 3) -> (n,)."""
        return np.asarray(features, dtype=float).reshape(-1, 3)[:, 1].copy()

    def reset(self) -> None:
        """No memory to forget."""


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """f2 against the chi-square gate."""
    return f"f2 {num(r.score)} {cmp(r.flagged)} gate {num(r.threshold)}"
