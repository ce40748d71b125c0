"""``anfis_hybrid``: paper A's ANFIS on filter-independent features, trained on the hybrid database.

Inputs (``StackConfig.hybrid_inputs``, by name from `FEATURE_NAMES`): by
default f2 (the innovation's Mahalanobis distance: the outliers),
repeat_count (stale ranges), |drift_residual_m| (with the default
``drift_source`` "model", the range against the DR error model of 60 s ago,
`replay.stack.dr_error_model`: drift and stale; the stiff reference's
residual replaced |lag_residual_m| in 531fadf (2026-12-01), development seeds 1-5
trained on 0: AUC 0.971 against 0.911, FNR at 2 % 0.258 against 0.309,
drift recall at 0.3 m/s 0.21 against 0) and
|usbl_residual_m| (a range off the USBL-anchored position). The leader-exclusion input exclusion_z
(signed, ``hybrid_signed_inputs``) did better on development seeds 1-4
trained on 0 (AUC 0.935 against 0.907, FNR 0.225 against 0.335 at 2 % FPR)
but not held out (seeds 100-109 trained on 0: AUC 0.936 against 0.937, FNR
0.302 against 0.304), so it is an option, not the default. The lag residual
is NaN on the hybrid database's rows (its reference filter does not run
there); the drift residual is not (the database's tracker runs its model). Residuals enter as magnitudes unless named in
``StackConfig.hybrid_signed_inputs``: the model learns |Z - Z_gps|;
f2 enters as sqrt(f2), the innovation in sigmas, because min-max
normalization of a squared distance (up to thousands) leaves every normal
epoch within the lowest hundredth of [0, 1]. An input with no finite
value in the training rows (no USBL fixes) is dropped at training, and the
notes say so; a NaN input at an epoch (no fresh fix) is taken as 0, "no
evidence". Trained like ``anfis`` (hybrid learning, grid rules,
``config.anfis``) on the recorded window plus the injected copies.

Threshold: the (1 - detection_fpr_target) quantile of the training scores
of the epochs labelled normal, so that the training false-alarm rate is the
target (2 % by default); the paper's 3σ rule (A.32) is computed beside it
and reported, not used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from replay.events import EpochResult
from replay.stack.config import ConfigError, StackConfig
from replay.stack.detectors.anfis_detector import (
    AnfisDetector,
    Explanation,
    threshold_from_rule,
)
from replay.stack.detectors.base import Decision
from replay.stack.detectors.why_text import cmp, epoch_features, num
from replay.stack.features import FEATURE_NAMES
from replay.stack.training import TrainingSet

SIGNED_INPUTS: frozenset[str] = frozenset({"dr_residual_m", "leader_consistency_m", "usbl_residual_m",
                                           "lag_residual_m", "drift_residual_m", "exclusion_residual_m",
                                           "drift_z", "exclusion_z"})


def fpr_threshold(normal_scores: np.ndarray, target: float) -> float:
    """The threshold flagging a fraction ``target`` of the given normal scores (scores > threshold flag).

    The ceil(n (1 - target))-th smallest score: at most floor(n·target)
    scores lie above it (exactly that many without ties). +inf for no scores.
    """
    s = np.sort(np.asarray(normal_scores, dtype=float)[np.isfinite(normal_scores)])
    if s.size == 0:
        return float("inf")
    k = int(np.ceil(s.size * (1.0 - target))) - 1
    return float(s[min(max(k, 0), s.size - 1)])


@dataclass(frozen=True)
class HybridExplanation:
    """Why ``anfis_hybrid`` did (not) flag an epoch: its named inputs, the ANFIS internals and both thresholds."""

    input_names: tuple[str, ...]
    inputs: np.ndarray              # (..., D) the raw inputs (magnitudes; NaN taken as 0)
    anfis: Explanation              # memberships, firing strengths, rule outputs, output
    threshold: float                # the threshold used (FPR target)
    threshold_3sigma: float         # paper A's rule, for comparison


class HybridAnfisDetector:
    """ANFIS on `config.hybrid_inputs` with the FPR-target threshold; one per leader or shared like ``anfis``."""

    name = "anfis_hybrid"
    wide = True

    def __init__(self, config: StackConfig) -> None:
        """Configure; nothing is trained until :meth:`train`."""
        unknown = [n for n in config.hybrid_inputs if n not in FEATURE_NAMES]
        if unknown:
            raise ConfigError(f"unknown hybrid input {unknown[0]!r}; expected names from {FEATURE_NAMES}")
        self.config = config
        self.inputs: tuple[str, ...] = tuple(config.hybrid_inputs)
        self._cols = [FEATURE_NAMES.index(n) for n in self.inputs]
        self._abs = np.array([n in SIGNED_INPUTS and n not in config.hybrid_signed_inputs for n in self.inputs])
        self._sqrt = np.array([n == "f2" for n in self.inputs])
        self._abs_list, self._sqrt_list = self._abs.tolist(), self._sqrt.tolist()   # the per-epoch path
        self.anfis = AnfisDetector(config)
        self.anfis.name = self.name
        self.threshold = float("nan")
        self.thresholds: dict[str, float] = {}
        self.dropped: tuple[str, ...] = ()

    def _x(self, features: np.ndarray) -> np.ndarray:
        """The model's inputs (n, D) of wide feature rows (n, F): magnitudes, NaN as 0."""
        f = np.atleast_2d(np.asarray(features, dtype=float))[:, self._cols]
        f = np.where(self._abs, np.abs(f), f)
        f = np.where(self._sqrt, np.sqrt(np.abs(f)), f)
        return np.nan_to_num(f, nan=0.0, posinf=0.0, neginf=0.0)

    def train_on(self, ts: TrainingSet) -> None:
        """`train` on the rows' features, range errors and labels."""
        self.train(ts.features, ts.range_error, ts.labels)

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Fit on wide rows (n, F) with |Z - Z_gps| as target; set the FPR-target and 3σ thresholds."""
        raw = np.atleast_2d(np.asarray(features, dtype=float))
        present = np.isfinite(raw[:, self._cols]).any(axis=0)
        self.dropped = tuple(n for n, ok in zip(self.inputs, present) if not ok)
        if self.dropped:
            keep = [i for i, ok in enumerate(present) if ok]
            self.inputs = tuple(self.inputs[i] for i in keep)
            self._cols = [self._cols[i] for i in keep]
            self._abs = self._abs[keep]
            self._sqrt = self._sqrt[keep]
            self._abs_list, self._sqrt_list = self._abs.tolist(), self._sqrt.tolist()
        x = self._x(raw)
        err = np.asarray(range_error, dtype=float).ravel()
        self.anfis.train(x, err, labels)
        if not self.anfis.trained:
            return
        lab = np.asarray(labels).ravel()
        ok = np.isfinite(err)
        scores = self.anfis.scores(x[ok])
        target = float(self.config.detection_fpr_target)
        self.threshold = fpr_threshold(scores[lab[ok] == 0], target)
        three_sigma = threshold_from_rule("3sigma", self.anfis.sigma, self.config.t1_m)
        normal = scores[lab[ok] == 0]
        self.thresholds = {"fpr_target": self.threshold, "3sigma": three_sigma, "used": self.threshold,
                           "training_fpr": float(np.mean(normal > self.threshold)) if normal.size else float("nan"),
                           "training_fpr_3sigma": float(np.mean(normal > three_sigma)) if normal.size
                           else float("nan")}
        self.anfis.threshold = self.threshold

    @property
    def trained(self) -> bool:
        """Whether a model exists."""
        return self.anfis.trained

    def decide(self, features: np.ndarray) -> Decision:
        """One epoch (F,): flagged when the predicted |error| exceeds the FPR-target threshold."""
        row = []
        for c, mag, root in zip(self._cols, self._abs_list, self._sqrt_list):   # `_x` of one row, in floats
            v = float(features[c])
            v = math.sqrt(abs(v)) if root else abs(v) if mag else v
            row.append(v if math.isfinite(v) else 0.0)
        return self.anfis.decide(np.array(row))

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores (n, F) -> (n,): the predicted |error|."""
        return self.anfis.scores(self._x(features))

    def reset(self) -> None:
        """No memory between epochs (the CUSUM input keeps its own, in the features)."""

    def explain(self, features: np.ndarray) -> HybridExplanation:
        """Named inputs, memberships, firing strengths, rule outputs and both thresholds, for the views."""
        x = self._x(features)
        one = np.asarray(features).ndim == 1
        return HybridExplanation(self.inputs, x[0] if one else x, self.anfis.explain(x[0] if one else x),
                                 self.threshold, self.thresholds.get("3sigma", float("nan")))


# short names of the hybrid inputs in its why-line, as the model sees them (magnitudes; f2 as its square root)
_SHORT = {"f2": "sqrt f2", "repeat_count": "repeats", "dr_residual_m": "|dr|", "leader_consistency_m": "|consist.|",
          "usbl_residual_m": "|usbl|", "lag_residual_m": "|lag|", "drift_residual_m": "|drift|",
          "exclusion_residual_m": "|excl.|", "drift_z": "|drift_z|", "exclusion_z": "|excl_z|"}


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """The output against its false-alarm-rate threshold, with its named inputs."""
    text = f"output {num(r.score)} m {cmp(r.flagged)} thr {num(r.threshold)} m"
    if isinstance(detector, HybridAnfisDetector):
        ex = detector.explain(epoch_features(r))
        text += "; " + ", ".join(f"{_SHORT.get(n, n)} {v:.3g}" for n, v in zip(ex.input_names,
                                                                               np.ravel(ex.inputs), strict=True))
    return text
