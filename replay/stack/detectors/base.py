"""The contract every anomaly detector follows, so the runner can drive them side by side.

Features at a range epoch are ``[f1, f2, f3]`` = innovation magnitude (m),
squared Mahalanobis distance on the unadapted P_zz, adapted measurement
variance R* (m²) (docs/design.md section 8).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True, slots=True)
class Decision:
    """One epoch's decision: flagged, the score compared, its threshold, and a range correction.

    `correction_m` is non-zero only for compensation-mode detectors: the range
    is corrected by it (Z - correction) and used instead of being isolated.
    """

    flagged: bool
    score: float
    threshold: float
    correction_m: float = 0.0


class Detector(Protocol):
    """A trained-once, per-epoch anomaly detector (one instance per leader, or shared)."""

    name: str

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Fit on the training window: features (n, 3), signed range error Z - Z_gps (n,), labels (n,)."""
        ...

    def decide(self, features: np.ndarray) -> Decision:
        """Decide one epoch from its features (3,); may keep memory between epochs."""
        ...

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores for many epochs (n, 3) -> (n,), for threshold sweeps (ROC)."""
        ...

    def reset(self) -> None:
        """Forget memory (CUSUMs...) after an alarm."""
        ...
