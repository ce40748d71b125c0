"""A runner's history: every method's estimate over time (its tracks) and every reported epoch.

Off for the replay engine over long archives (``keep_history=False``), so a
runner's memory does not grow with the mission.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import chain

import numpy as np

from replay.events import EpochResult, Track
from replay.stack.filters.ckf import State2
from replay.stack.model import cov_radians_to_metres


class History:
    """Tracks and epochs of one runner, kept only when ``keep`` is true."""

    def __init__(self, keep: bool) -> None:
        """Empty; ``keep=False`` keeps nothing."""
        self.keep = keep
        self._t: list[float] = []
        self._depth: list[float] = []
        self._states: list[State2] = []        # one per method per record, flattened at the end
        self._epochs: list[EpochResult] = []

    def record(self, t_s: float, depth_m: float, states: Sequence[State2]) -> None:
        """Remember every method's state (in the runner's method order) at one instant."""
        self._t.append(t_s)
        self._depth.append(depth_m)
        self._states.extend(states)

    def add_epochs(self, results: Sequence[EpochResult]) -> None:
        """Remember one epoch's reported results."""
        if self.keep:
            self._epochs.extend(results)

    def epochs(self) -> dict[str, np.ndarray]:
        """Every kept epoch result, one array per `EpochResult` field."""
        if not self._epochs:
            return {name: np.empty(0) for name in EpochResult._fields}
        return {name: np.array([getattr(e, name) for e in self._epochs]) for name in EpochResult._fields}

    def tracks(self, names: Sequence[str], reported: Sequence[str]) -> dict[str, Track]:
        """Per reported method (``names`` is the runner's method order), its track with covariances in m²."""
        t = np.array(self._t)
        depth = np.array(self._depth)
        flat = np.fromiter(chain.from_iterable(self._states), dtype=float, count=5 * len(self._states))
        states = flat.reshape(t.size, len(names), 5)
        out = {}
        for i, name in enumerate(names):
            if name not in reported:
                continue
            s = states[:, i, :]
            p = np.stack([s[:, 2], s[:, 3], s[:, 3], s[:, 4]], axis=-1).reshape(-1, 2, 2)
            out[name] = Track(t, s[:, 0].copy(), s[:, 1].copy(), cov_radians_to_metres(p, s[:, 0], depth))
        return out
