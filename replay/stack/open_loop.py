"""Open-loop ROC scores: every trained detector scores the same features, those of the ``ackf`` method after t_a.

The ``ackf`` method isolates nothing, so its features after t_a are the
same whichever detector looks at them; the runner runs it internally even
when it is not requested. Only these compact rows are kept during a run,
and `OpenLoopScores.scores` runs ``Detector.scores`` on them at the end.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from replay.events import EpochResult
from replay.stack.detectors.base import Detector
from replay.stack.features import FEATURE_NAMES

ScoredMethod = tuple[str, tuple[str, ...], Mapping[str, Detector | None]]
"""A detecting method to score: its name, the feature columns its detector reads, its detector per leader."""


class OpenLoopScores:
    """The ``ackf`` method's features after t_a, and every trained detector's scores of them."""

    def __init__(self) -> None:
        """No rows yet."""
        self._rows: list[tuple] = []      # (t, leader, label, features...) of ackf after t_a

    def add(self, results: Sequence[EpochResult], extra: tuple[float, ...]) -> None:
        """Keep the ``ackf`` result of one epoch (its (f1, f2, f3) and the epoch's extra features)."""
        self._rows.extend((r.time_s, r.leader, r.label, r.f1, r.f2, r.f3, *extra)
                          for r in results if r.method == "ackf")

    def normal_features(self) -> np.ndarray:
        """The kept epochs labelled normal: their FEATURE_NAMES rows (n, F), what a threshold is calibrated on."""
        rows = [e[3:] for e in self._rows if e[2] == 0]
        return np.array(rows, dtype=float).reshape(-1, len(FEATURE_NAMES))

    def scores(self, methods: Iterable[ScoredMethod]) -> dict[str, dict[str, np.ndarray]]:
        """Per method: time_s, leader, label and its detectors' score of each kept epoch (NaN: no detector)."""
        src = self._rows
        leaders = np.array([e[1] for e in src], dtype=object)
        wide_all = np.array([e[3:] for e in src], dtype=float).reshape(-1, len(FEATURE_NAMES))
        out = {}
        for name, features, detectors in methods:
            feats_all = wide_all[:, [FEATURE_NAMES.index(n) for n in features]]
            score = np.full(len(src), np.nan)
            for leader, det in detectors.items():
                idx = np.nonzero(leaders == leader)[0]
                if det is not None and idx.size:
                    score[idx] = det.scores(feats_all[idx])
            out[name] = {"time_s": np.array([e[0] for e in src], dtype=float),
                         "leader": leaders,
                         "label": np.array([e[2] for e in src], dtype=np.int8), "score": score}
        return out
