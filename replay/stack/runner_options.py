"""What a `CooperativeRunner` is started with: where and when it starts, and its options.

Kept apart from the runner so that its collaborators (training window,
hybrid database, feature tracking) read them without importing the runner.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field

from replay.stack.methods import DetectorFactory
from replay.stack.training import TrainingSet


@dataclass(frozen=True)
class Start:
    """Where and when a follower's runner starts: time (s), position (rad) and depth (m)."""

    time_s: float
    lat_rad: float
    lon_rad: float
    depth_m: float = 0.0


@dataclass(frozen=True)
class RunnerOptions:
    """How a runner keeps its results and trains its detectors.

    ``keep_history=False`` (the replay engine over long archives) keeps no
    tracks and no epochs, so memory does not grow with the mission; the
    caller takes them from ``range_epoch`` and ``estimates``.
    ``training_threads`` (None: `default_training_threads()`) trains the
    AQPSO-GA models at t_a side by side; the results are the same for any
    count. ``training_set`` (another run's ``RunResults.training_set``) is
    trained on instead of the own window (``training_source == "given"``) or
    besides it (``"both"``). ``factories`` override the method table's
    detector factories by method name (tests).
    """

    keep_history: bool = True
    training_threads: int | None = None
    training_set: TrainingSet | None = None
    factories: Mapping[str, DetectorFactory] = field(default_factory=dict)

    def threads(self) -> int:
        """The training threads to use: the given count (at least 1), else `default_training_threads()`."""
        return default_training_threads() if self.training_threads is None else max(1, self.training_threads)


def default_training_threads() -> int:
    """Threads for AQPSO-GA training at t_a: $AUVREPLAY_TRAINING_THREADS, else the machine's cores up to 4."""
    env = os.environ.get("AUVREPLAY_TRAINING_THREADS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    return max(1, min(4, os.cpu_count() or 1))

