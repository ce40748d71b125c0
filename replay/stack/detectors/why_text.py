"""Helpers every detector's why-line shares: numbers, comparison signs and an epoch's feature vector.

A why-line names the statistic a detector compared at an epoch, its value, the
threshold and the outcome (docs/design.md section 5, the method table; docs/views.md, the Detection tab). Lines are
plain ASCII: the Rerun viewer aborts on a glyph its font lacks.
"""

from __future__ import annotations

import math

import numpy as np

from replay.events import EpochResult
from replay.stack.features import EXTRA_FEATURES


def cmp(flagged: bool) -> str:
    """'>' for a flagged epoch, '<=' for a quiet one."""
    return ">" if flagged else "<="


def num(v: float, digits: int = 2) -> str:
    """A number with `digits` decimals, or 'n/a' when it is not finite."""
    return f"{v:.{digits}f}" if math.isfinite(v) else "n/a"


def epoch_features(r: EpochResult) -> np.ndarray:
    """An epoch's feature vector in FEATURE_NAMES order (f1, f2, f3, then EXTRA_FEATURES), as wide detectors take."""
    return np.array([r.f1, r.f2, r.f3, *(getattr(r, n) for n in EXTRA_FEATURES)], dtype=float)


def generic_why(r: EpochResult, detector: object | None = None) -> str:
    """The line of a detector without its own: its score against its threshold."""
    return f"score {r.score:.3g} {cmp(r.flagged)} threshold {r.threshold:.3g}"
