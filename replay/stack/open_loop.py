"""Open-loop ROC scores: every trained detector scores the same features, those of the ``ackf`` method after t_a.

The ``ackf`` method isolates nothing, so its features after t_a are the
same whichever detector looks at them; the runner runs it internally even
when it is not requested. Only these compact rows (columns of doubles) are kept during a run,
and `OpenLoopScores.scores` runs ``Detector.scores`` on them at the end.
"""

from __future__ import annotations

from array import array
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
        # per kept epoch (ackf after t_a): time, label and FEATURE_NAMES as doubles, flat; its leader beside.
        # Columns, not a tuple of float objects per epoch: a day holds some 35,000 epochs (bench_replay's memory)
        self._num = array("d")
        self._leaders: list[str] = []

    def add(self, results: Sequence[EpochResult], extra: tuple[float, ...]) -> None:
        """Keep the ``ackf`` result of one epoch (its (f1, f2, f3) and the epoch's extra features)."""
        for r in results:
            if r.method == "ackf":
                self._num.extend((r.time_s, r.label, r.f1, r.f2, r.f3, *extra))
                self._leaders.append(r.leader)

    def _table(self) -> np.ndarray:
        """The kept rows (n, 2 + len(FEATURE_NAMES)): time, label, features; a view of the kept doubles (no copy).

        Callers drop it before `add` runs again (an array with a view on it cannot grow).
        """
        return np.frombuffer(self._num, dtype=float).reshape(-1, 2 + len(FEATURE_NAMES))

    def normal_features(self) -> np.ndarray:
        """The kept epochs labelled normal: their FEATURE_NAMES rows (n, F), what a threshold is calibrated on."""
        table = self._table()
        return table[table[:, 1] == 0, 2:]

    def scores(self, methods: Iterable[ScoredMethod]) -> dict[str, dict[str, np.ndarray]]:
        """Per method: time_s, leader, label and its detectors' score of each kept epoch (NaN: no detector).

        The methods share one time, leader and label column (read-only): only the scores are per method, each
        read from the kept rows one method at a time, so the end of a day-long run copies no table.
        """
        table = self._table()
        leaders = np.array(self._leaders, dtype=object)
        rows = {leader: np.nonzero(leaders == leader)[0] for leader in dict.fromkeys(self._leaders)}
        shared = {"time_s": table[:, 0].copy(), "leader": leaders, "label": table[:, 1].astype(np.int8)}
        for column in shared.values():
            column.flags.writeable = False
        out = {}
        for name, features, detectors in methods:
            columns = np.array([2 + FEATURE_NAMES.index(n) for n in features], dtype=np.intp)
            score = np.full(len(leaders), np.nan)
            for leader, det in detectors.items():
                idx = rows.get(leader)
                if det is not None and idx is not None and idx.size:
                    score[idx] = det.scores(table[np.ix_(idx, columns)])
            out[name] = {**shared, "score": score}
        del table     # the view on the kept doubles: `add` may extend them again
        return out
