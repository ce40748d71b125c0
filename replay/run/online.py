"""The engine run online, as a live capture decodes: the same push-style engine and outputs as `replay`.

Live streams settle at different moments (an epoch is complete when the next
one starts; a 0.2 Hz buoy GPS settles every 5 s), so messages are merged in
log-time order through a heap: a message is pushed once every stream that
has spoken has passed its time, or once the newest time seen is `max_lag_s`
past it (a source gone quiet holds the run back by that much at most, and
the heap stays bounded). Nothing is pushed before the newest time is
`start_hold_s` past the first and a second of wall time has gone by since
it came, so that every stream can say its first word (a capture that starts
on a backlog gets many seconds of every stream at once).
A message older than the last one pushed is counted and left out of the
online run (it is in the archive; `replay` of the capture gives the
offline run). The trial
starts at the first message pushed, or at `earliest()` when that is earlier
(a capture passes its first receive time: the archive's start, which is what
`replay` of the capture counts from); training happens at t_a after it, as in
replay. At the end the results go to an archive and metrics files exactly
as `replay -o` writes them.
"""

from __future__ import annotations

import hashlib
import heapq
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from formats.mcap_writer import ArchiveWriter
from replay.engine.config import RunConfig
from replay.engine.core import Engine
from replay.engine.layout import TrialLayout, plan_trial
from replay.events import Listener
from replay.review.collector import ReviewCollector
from replay.run.config import run_id
from replay.run.metrics import run_metrics
from replay.run.pipeline import (
    SENSORS,
    RunOutcome,
    package_version,
    save_metrics,
    write_run_metadata,
)
from replay.run.results_writer import ResultsWriter

MAX_LAG_S = 60.0
START_HOLD_S = 10.0
START_HOLD_WALL_S = 1.0
ListenerFactory = Callable[[str, int], Listener]  # (run id, trial start ns) -> a listener


class OnlineRun:
    """Takes decoded messages in any order across streams; pushes them to the engine in time order."""

    def __init__(self, trial: dict[str, Any], topics: list[str], config: RunConfig,
                 results: str | Path | None = None, review: bool = False,
                 listeners: tuple[ListenerFactory, ...] | list[ListenerFactory] = (),
                 max_lag_s: float = MAX_LAG_S, start_hold_s: float = START_HOLD_S,
                 label: str = "live", earliest: Callable[[], int | None] = lambda: None):
        self.trial, self.config = trial, config
        self.layout: TrialLayout = plan_trial(trial, {t: 1 for t in topics}, self.config.stack.methods)
        self.wanted = {t for t in topics if t == "/diagnostics"
                       or any(t == f"/{v}/{s}" for v in self.layout.roles for s in SENSORS)}
        self.run_id = run_id(config, hashlib.sha256(f"capture:{label}".encode()).hexdigest(), package_version())
        self.results = Path(results) if results is not None else None
        self.review = review
        self.earliest = earliest  # the archive's first time (a capture's first receive time), if earlier
        self.factories = list(listeners)  # more may be added until the first message is pushed
        self.max_lag_ns, self.start_hold_ns = round(max_lag_s * 1e9), round(start_hold_s * 1e9)
        self._streams: dict[str, int] = {}  # stream -> latest log time
        self._first: int | None = None
        self._first_wall = 0.0
        self._heap: list[tuple[int, int, str, Any]] = []
        self._seq = 0
        self._newest: int | None = None
        self.engine: Engine | None = None
        self.collector: ReviewCollector | None = None
        self._writer: ArchiveWriter | None = None
        self.late = 0
        self.late_topics: dict[str, int] = {}
        self._last_pushed = -1
        self._wall0 = time.monotonic()

    def add(self, stream: str, messages: list[tuple[str, int, Any]]) -> None:
        """Messages (topic, log time ns, message) one stream decoded; what every live stream has passed is pushed."""
        latest = None
        for topic, t, message in messages:
            latest = t if latest is None else max(latest, t)
            if topic in self.wanted:
                heapq.heappush(self._heap, (t, self._seq, topic, message))
                self._seq += 1
        if latest is None:
            return
        self._streams[stream] = max(latest, self._streams.get(stream, latest))
        self._newest = latest if self._newest is None else max(self._newest, latest)
        if self._first is None:
            self._first = self._heap[0][0] if self._heap else latest
            self._first_wall = time.monotonic()
        if self.engine is None and (self._newest - self._first < self.start_hold_ns
                                    or time.monotonic() - self._first_wall < START_HOLD_WALL_S):
            return
        self._release(max(min(self._streams.values()), self._newest - self.max_lag_ns))

    def _release(self, until_ns: int | None) -> None:
        heap = self._heap
        while heap and (until_ns is None or heap[0][0] <= until_ns):
            t, _, topic, message = heapq.heappop(heap)
            if t < self._last_pushed:
                self.late += 1
                self.late_topics[topic] = self.late_topics.get(topic, 0) + 1
                continue
            if self.engine is None:
                floor = self.earliest()
                self._start(t if floor is None else min(t, floor))
            assert self.engine is not None
            self.engine.push(topic, t, message)
            self._last_pushed = t

    def _start(self, t0_ns: int) -> None:
        """The engine and its listeners, at the first message pushed (the trial's start)."""
        listeners: list[Listener] = []
        if self.review:
            self.collector = ReviewCollector(self.run_id, self.trial, t0_ns, self.layout)
            listeners.append(self.collector)
        if self.results is not None:
            self._writer = ArchiveWriter(self.results)
            listeners.append(ResultsWriter(self._writer, self.run_id, t0_ns))
        listeners += [factory(self.run_id, t0_ns) for factory in self.factories]
        self.engine = Engine(self.layout, self.config, t0_ns, listeners)

    def finish(self, source: str = "capture") -> RunOutcome | None:
        """Push what is left, finish the engine, write the results; None when no message came."""
        self._release(None)
        engine = self.engine
        if engine is None:
            if self._writer is not None:
                self._writer.abort()
            return None
        try:
            results = engine.finish()
            end_s = max(engine.last_s, 0.0)
            metrics = run_metrics(engine.scores(), results, self.run_id, end_s)
            wall = time.monotonic() - self._wall0
            metrics["wall_s"] = wall
            if self._writer is not None:
                write_run_metadata(self._writer, self.config, self.run_id, "", package_version(), source, wall,
                                   metrics, engine.t0_ns, engine)
                self._writer.close()
        except BaseException:
            if self._writer is not None:
                self._writer.abort()
            raise
        notes = list(engine.notes) + ([f"{self.late} messages arrived too late for the online run ("
                                       + ", ".join(f"{t} {n}" for t, n in sorted(self.late_topics.items())) + ")"]
                                      if self.late else [])
        outcome = RunOutcome(self.run_id, metrics, results, self.results, notes, wall, None, engine.messages)
        if self.collector is not None:
            outcome.review = self.collector.finish(metrics)
        if self.results is not None:
            save_metrics(metrics, self.results)
        return outcome
