"""What detectors are trained on: a `TrainingSet` of labelled epochs, from a run's own window or other trials.

A runner collects one at t_a (its training window's epochs with GPS truth,
plus the hybrid database's injected copies, see `replay.stack.injection`)
and exposes it as ``RunResults.training_set``; another runner can be given
it instead of, or besides, its own window (``StackConfig.training_source``
"own", "given" or "both"), which is how an evaluation trains on one trial
and tests on others. Rows of every leader are kept with their leader, so a
per-leader model takes its own rows and a shared model takes them all.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

TRAINING_SOURCES: tuple[str, ...] = ("own", "given", "both")
"""``StackConfig.training_source``: the run's own window, a given TrainingSet, or both concatenated."""
RECORDED: str = ""
"""``TrainingSet.kinds`` of a row as recorded (not injected)."""


def _empty_object(n: int) -> np.ndarray:
    return np.full(n, RECORDED, dtype=object)


@dataclass(frozen=True)
class TrainingSet:
    """Labelled training epochs: features (n, F) named by ``feature_names``, signed error Z - Z_gps, labels, leaders.

    ``kinds`` says per row whether it was recorded ("") or comes from the
    hybrid database, and then which anomaly was injected into its range
    ("stale", "drift", "outlier"; "normal" for an injected copy's untouched
    epoch). Paper A's detectors train on the recorded rows only.
    """

    features: np.ndarray              # (n, F) float
    range_error: np.ndarray           # (n,) signed Z - Z_gps (m)
    labels: np.ndarray                # (n,) int8: 1 anomalous, 0 normal
    leaders: np.ndarray               # (n,) object: the leader ranged
    feature_names: tuple[str, ...]
    kinds: np.ndarray = field(default_factory=lambda: _empty_object(0))
    # (m, F): the trial's epochs labelled normal scored after t_a (open loop, every leader), for thresholds
    # set at a target false-alarm rate on the training trial (`replay.stack.calibration`); empty when the
    # set is a window alone (a run gives it with its `RunResults.training_set`)
    calibration: np.ndarray = field(default_factory=lambda: np.empty(0))

    def __post_init__(self) -> None:
        """Coerce the arrays and check that every column has one value per row."""
        x = np.asarray(self.features, dtype=float).reshape(-1, len(self.feature_names))
        n = x.shape[0]
        object.__setattr__(self, "features", x)
        object.__setattr__(self, "range_error", np.asarray(self.range_error, dtype=float).reshape(-1))
        object.__setattr__(self, "labels", np.asarray(self.labels, dtype=np.int8).reshape(-1))
        object.__setattr__(self, "leaders", np.asarray(self.leaders, dtype=object).reshape(-1))
        kinds = np.asarray(self.kinds, dtype=object).reshape(-1)
        object.__setattr__(self, "kinds", _empty_object(n) if kinds.size == 0 and n else kinds)
        object.__setattr__(self, "feature_names", tuple(self.feature_names))
        object.__setattr__(self, "calibration",
                           np.asarray(self.calibration, dtype=float).reshape(-1, len(self.feature_names)))
        for name in ("range_error", "labels", "leaders", "kinds"):
            if getattr(self, name).shape[0] != n:
                raise ValueError(f"TrainingSet.{name} has {getattr(self, name).shape[0]} rows, features {n}")

    def __len__(self) -> int:
        """Number of rows."""
        return int(self.features.shape[0])

    @classmethod
    def empty(cls, feature_names: Sequence[str]) -> TrainingSet:
        """A set with no rows."""
        return cls(np.empty((0, len(feature_names))), np.empty(0), np.empty(0, np.int8),
                   np.empty(0, dtype=object), tuple(feature_names))

    def select(self, mask: np.ndarray) -> TrainingSet:
        """The rows where ``mask`` is true (a boolean array or indices)."""
        return TrainingSet(self.features[mask], self.range_error[mask], self.labels[mask], self.leaders[mask],
                           self.feature_names, self.kinds[mask], self.calibration)

    def for_leader(self, leader: str) -> TrainingSet:
        """The rows of one leader."""
        return self.select(self.leaders == leader)

    def recorded(self) -> TrainingSet:
        """The rows as recorded, without the hybrid database's injected copies."""
        return self.select(self.kinds == RECORDED)

    def columns(self, names: Sequence[str]) -> np.ndarray:
        """The feature columns called ``names``, in that order: (n, len(names)); KeyError naming a missing one."""
        missing = [n for n in names if n not in self.feature_names]
        if missing:
            raise KeyError(f"TrainingSet has no feature {missing[0]!r}; it has {', '.join(self.feature_names)}")
        return self.features[:, [self.feature_names.index(n) for n in names]]

    def with_features(self, names: Sequence[str]) -> TrainingSet:
        """The same rows with only the feature columns called ``names`` (KeyError naming a missing one)."""
        if tuple(names) == self.feature_names:
            return self
        cols = [self.feature_names.index(n) for n in names]
        return TrainingSet(self.columns(names), self.range_error, self.labels, self.leaders, tuple(names), self.kinds,
                           self.calibration[:, cols])

    def with_calibration(self, rows: np.ndarray) -> TrainingSet:
        """The same rows with ``rows`` (m, F) added to the calibration rows (normal epochs after t_a)."""
        return replace(self, calibration=np.concatenate([self.calibration,
                                                         np.asarray(rows, float).reshape(-1, self.features.shape[1])]))

    def digest(self) -> str:
        """SHA-256 (hex) of every row's content and the feature names: equal sets give equal digests.

        A run trained on a given set depends on it as much as on its input
        archive, so the run id folds it in (replay.run.pipeline).
        """
        h = hashlib.sha256()
        h.update("\n".join(self.feature_names).encode())
        for arr in (self.features, self.range_error, self.labels):
            a = np.ascontiguousarray(arr)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
        for arr in (self.leaders, self.kinds):
            h.update("\x00".join(str(v) for v in arr.tolist()).encode())
            h.update(b"\x01")
        if self.calibration.size:     # a set without calibration rows keeps the digest it had before them
            h.update(f"calibration{self.calibration.shape}".encode())
            h.update(np.ascontiguousarray(self.calibration).tobytes())
        return h.hexdigest()

    def concat(self, other: TrainingSet) -> TrainingSet:
        """Both sets' rows; ValueError when their features differ."""
        if other.feature_names != self.feature_names:
            raise ValueError(f"TrainingSet features differ: {self.feature_names} against {other.feature_names}")
        return TrainingSet(np.concatenate([self.features, other.features]),
                           np.concatenate([self.range_error, other.range_error]),
                           np.concatenate([self.labels, other.labels]),
                           np.concatenate([self.leaders, other.leaders]), self.feature_names,
                           np.concatenate([self.kinds, other.kinds]),
                           np.concatenate([self.calibration, other.calibration]))
