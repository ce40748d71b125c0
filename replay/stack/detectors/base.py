"""The contract every anomaly detector follows, so the runner can drive them side by side.

A detector reads the feature columns its method-table entry names
(`replay.stack.methods.Method.features`): paper A's ``[f1, f2, f3]`` =
innovation magnitude (m), squared Mahalanobis distance on the unadapted
P_zz, adapted measurement variance R* (m²) (docs/design.md section 8), or
every column of `replay.stack.features.FEATURE_NAMES`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from replay.stack.training import TrainingSet


@dataclass(frozen=True, slots=True)
class Decision:
    """One epoch's decision: flagged, the score compared, its threshold, and a range correction.

    `correction_m` is non-zero only for compensation-mode detectors: the range
    is corrected by it (Z - correction) and used instead of being isolated.
    `steps_down` False: a closed-loop running threshold may raise its
    multiplier on this epoch but not lower it (a test whose cut the
    multiplier hardly moves, as `stale_aware`'s stale ranges against T1).
    """

    flagged: bool
    score: float
    threshold: float
    correction_m: float = 0.0
    steps_down: bool = True


class Detector(Protocol):
    """A trained-once, per-epoch anomaly detector (one instance per leader, or shared)."""

    name: str

    def train_on(self, ts: TrainingSet) -> None:
        """Fit on the training rows, whose feature columns are the method's (the runner selects them).

        Paper A's detectors are handed the recorded window only; the others
        the hybrid database too, with each row's kind (`TrainingSet.kinds`).
        """
        ...

    def decide(self, features: np.ndarray) -> Decision:
        """Decide one epoch from its features (F,); may keep memory between epochs."""
        ...

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores for many epochs (n, F) -> (n,), for threshold sweeps (ROC)."""
        ...

    def reset(self) -> None:
        """Forget memory (CUSUMs...) after an alarm."""
        ...
