"""The runner's training window: what it collects before t_a and the detectors it trains at t_a.

During the window ``start < t <= t_a = start + training_window_s`` every
detecting method runs its own ACKF without isolation, and the ``ackf``
method's epochs with GPS truth give the rows: the features, the signed
range error Z - Z_gps and the label. When a new method is configured the
window's inputs are kept too, for the hybrid database
(`replay.stack.hybrid_database`).

At the first sample after t_a each detector is trained: with
``config.anfis.model == "per_leader"`` one instance per leader on that
leader's rows; with ``"shared"`` (or a method-table entry with
``pooled_training``) one instance on every leader's rows, then copied per
leader so that detectors with memory (the dual threshold's CUSUM) keep one
memory per acoustic link. A detector that cannot be trained (no labelled
rows, or its training fails) is left out (None) and reported in
``errors``; its method then runs as a plain ACKF.
"""

from __future__ import annotations

import copy
import threading
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from replay.stack.calibration import calibrate
from replay.stack.config import ConfigError, StackConfig
from replay.stack.detectors.base import Detector
from replay.stack.features import FEATURE_NAMES, PAPER_FEATURES
from replay.stack.forked import balance, can_fork, run_groups
from replay.stack.hybrid_database import HybridDatabase, WindowInput, rows_to_set
from replay.stack.methods import Method, method
from replay.stack.runner_options import RunnerOptions, Start
from replay.stack.tracking import needs_features
from replay.stack.training import RECORDED, TRAINING_SOURCES, TrainingSet

Trained = dict[str, dict[str, Detector | None]]
"""Method name -> leader -> its trained detector (None: it could not be trained)."""
_Job = tuple[Method, str, TrainingSet]     # a method, the leader it trains for (or "all"), its rows
_Trained = tuple[Detector | None, str]     # a detector (None: not trained) and why not
_INSTANT = frozenset({"chi_square"})        # trained in closed form (a gate from the window), in well under 1 ms


class TrainedCache:
    """Detectors trained before, by (method, configuration, rows' digest); the least recently used go first."""

    def __init__(self, max_entries: int = 128) -> None:
        self.max_entries = max(1, max_entries)
        self._kept: OrderedDict[tuple[str, str, str], _Trained] = OrderedDict()
        self._lock = threading.Lock()     # heavy jobs train on threads (`TrainingWindow._run`)
        self.hits = 0

    def __len__(self) -> int:
        return len(self._kept)

    def get(self, key: tuple[str, str, str]) -> _Trained | None:
        """A copy of the detector kept under `key`, or None."""
        with self._lock:
            found = self._kept.get(key)
            if found is None:
                return None
            self._kept.move_to_end(key)
            self.hits += 1
        return copy.deepcopy(found[0]), found[1]

    def put(self, key: tuple[str, str, str], trained: _Trained) -> None:
        """Keep a copy of a newly trained detector (the run scores with its own, which changes its memory)."""
        kept = (copy.deepcopy(trained[0]), trained[1])
        with self._lock:
            self._kept[key] = kept
            while len(self._kept) > self.max_entries:
                self._kept.popitem(last=False)


_REUSE = threading.local()     # .cache: the TrainedCache of `reuse_training` in this thread


@contextmanager
def reuse_training(cache: TrainedCache) -> Iterator[None]:
    """Within it, a detector trained on the same rows under the same configuration is trained once per cache.

    Training is deterministic (each job has its own data and seed), so a copy of the detector trained
    before is the detector a new training would give. `evaluate` trains every test trial's detectors
    on the train seed's set: without this, each trial (and each follower) trained the same models again.
    It holds for the training windows made in this thread while it is open.
    """
    outer = getattr(_REUSE, "cache", None)
    _REUSE.cache = cache
    try:
        yield
    finally:
        _REUSE.cache = outer


def threshold_report(det: Detector | None) -> dict[str, float]:
    """A trained detector's named thresholds (its ``thresholds`` mapping, else its ``threshold`` as "used")."""
    named = getattr(det, "thresholds", None)
    if isinstance(named, dict):
        return {str(k): float(v) for k, v in named.items()}
    thr = getattr(det, "threshold", None)
    return {"used": float(thr)} if isinstance(thr, (int, float)) else {}


class TrainingWindow:
    """Collects one runner's training rows and window inputs, and trains its detectors once at t_a."""

    def __init__(self, config: StackConfig, leaders: Sequence[str], start: Start, options: RunnerOptions) -> None:
        """Check the training source against the given set; ConfigError or ValueError naming the problem."""
        given = options.training_set
        if config.training_source not in TRAINING_SOURCES:
            raise ConfigError(f"unknown training_source {config.training_source!r}; expected one of "
                              f"{', '.join(TRAINING_SOURCES)}")
        if config.training_source != "own" and given is None:
            raise ValueError(f"training_source {config.training_source!r} needs a training_set")
        if given is not None and given.feature_names != FEATURE_NAMES:
            raise ValueError(f"the given training set's features {given.feature_names} are not {FEATURE_NAMES}")
        self.config = config
        self.leaders = tuple(leaders)
        self.end_s = float(start.time_s) + config.training_window_s
        self.threads = options.threads()
        self.keeps_window = needs_features(config)     # the hybrid database replays the window
        self._given = given
        self._factories = dict(options.factories)      # overrides of the method table's factories (tests)
        self._reused: TrainedCache | None = getattr(_REUSE, "cache", None)
        self._database = HybridDatabase(config, leaders, start)
        self.rows: list[tuple] = []            # (t, leader, features..., Z - Z_gps, label) of ackf in the window
        self.window: list[WindowInput] = []    # the window's inputs in push order
        self.trained = False
        self.training_set: TrainingSet | None = None
        self.thresholds: dict[str, dict[str, dict[str, float]]] = {}
        self.notes: dict[str, str] = {}
        self.errors: dict[str, str] = {}

    def due(self, t_s: float) -> bool:
        """True at the first sample after t_a, when the detectors are to be trained."""
        return not self.trained and t_s > self.end_s

    def keep(self, kind: str, args: tuple) -> None:
        """Remember one input (its time first) for the hybrid database, when inside the window and needed."""
        if self.keeps_window and args[0] <= self.end_s:
            self.window.append((kind, args))

    def train(self, entries: Sequence[Method]) -> Trained:
        """Train every detecting method's detectors (AQPSO-GA models on threads); thresholds and notes kept."""
        self.trained = True
        ts = self._assemble()
        self.training_set = ts
        jobs = [(e, key, data) for e in entries if e.detects for key, data in self._split(e, ts)]
        out: Trained = {e.name: {} for e in entries if e.detects}
        for (e, key, data), (det, error) in zip(jobs, self._run(jobs), strict=True):
            if error:
                self.errors[f"{e.name}/{key}"] = error
            if det is not None and e.calibrated and self.config.calibrate_thresholds \
                    and calibrate(det, data.calibration, self.config.detection_fpr_target):
                self.notes[f"{e.name}/calibration"] = \
                    f"threshold at {self.config.detection_fpr_target:g} of {len(data.calibration)} normal epochs"
            if key == "all":        # shared: one model, a copy per leader (memory per acoustic link)
                out[e.name] = {ld: copy.deepcopy(det) if det is not None else None for ld in self.leaders}
            else:
                out[e.name][key] = det
        for name, per_leader in out.items():
            self.thresholds[name] = {ld: threshold_report(det) for ld, det in per_leader.items() if det is not None}
        for name, named_per_leader in self.thresholds.items():
            if named_per_leader:
                self.notes[f"{name}/thresholds"] = "; ".join(
                    f"{ld}: " + ", ".join(f"{k} {v:.3g}" for k, v in named.items())
                    for ld, named in named_per_leader.items())
        return out

    def _run(self, jobs: list[_Job]) -> list[tuple[Detector | None, str]]:
        """Every job's (detector or None, error): kept ones from the cache, the others trained side by side."""
        cache = self._reused
        keys = [None if cache is None or e.name in self._factories else (e.name, repr(self.config), data.digest())
                for e, _, data in jobs]
        outcomes: list[_Trained | None] = [None if key is None or cache is None else cache.get(key) for key in keys]
        todo = [i for i, o in enumerate(outcomes) if o is None]
        if can_fork():
            # each job is many small numpy calls, bound by the interpreter: processes, not threads, run them
            # side by side; the heavy ones (whole-population AQPSO-GA) weigh about four of the others, and
            # one trained in an instant is not worth a fork (~20 ms): it trains here
            instant = [i for i in todo if jobs[i][0].name in _INSTANT]
            timed = [i for i in todo if jobs[i][0].name not in _INSTANT]
            costs = [4.0 if jobs[i][0].threaded_training else 1.0 for i in timed]
            groups = [[timed[k] for k in g] for g in balance(costs, self.threads)] or [[]]
            groups[0] = sorted(groups[0] + instant)
            trained = run_groups(lambda i: self._train_new(jobs[i][0], jobs[i][2]), groups)
        else:
            trained = dict(zip(todo, self._run_threads([jobs[i] for i in todo]), strict=True))
        for i in todo:
            outcomes[i] = trained[i]
            key = keys[i]
            if cache is not None and key is not None:
                cache.put(key, trained[i])
        return [o for o in outcomes if o is not None]     # every job has its outcome by now

    def _run_threads(self, jobs: list[_Job]) -> list[_Trained]:
        """Every job's outcome where there is no fork: the heavy ones on threads, the others here in turn."""
        # AQPSO-GA evaluates whole populations, where numpy and LAPACK release the GIL: two such
        # models train ~1.5x faster side by side. The other trainers are many small numpy calls
        # that only contend for the GIL (3x slower each on threads), so they run here, in turn,
        # while the threaded ones train. Each job has its own data and seed: results do not depend
        # on the threads.
        outcomes: list[_Trained | None] = [None] * len(jobs)
        heavy = [i for i, job in enumerate(jobs) if job[0].threaded_training]
        futures = {}
        pool = None
        if self.threads > 1 and len(heavy) > 1:
            from concurrent.futures import ThreadPoolExecutor

            pool = ThreadPoolExecutor(min(self.threads, len(heavy)))
            futures = {i: pool.submit(self._train_new, jobs[i][0], jobs[i][2]) for i in heavy}
        try:
            for i, (e, _, data) in enumerate(jobs):
                if i not in futures:
                    outcomes[i] = self._train_new(e, data)
            for i, future in futures.items():
                outcomes[i] = future.result()
        finally:
            if pool is not None:
                pool.shutdown()
        return [o for o in outcomes if o is not None]

    def _assemble(self) -> TrainingSet:
        """The rows every detector trains on, by ``config.training_source`` (see the module doc)."""
        source = self.config.training_source
        if source == "given" and self._given is not None:
            self.notes["source"] = f"given: {len(self._given)} rows"
            return self._given
        own = rows_to_set(self.rows, RECORDED)
        recorded = len(own)
        if self.keeps_window:
            database, note = self._database.build(self.window)
            if note:
                self.notes["database"] = note
            own = own.concat(database)
        note = f"own window: {recorded} rows, hybrid database: {len(own) - recorded} rows"
        if source == "both" and self._given is not None:
            self.notes["source"] = note + f", given: {len(self._given)} rows"
            return own.concat(self._given)
        self.notes["source"] = note
        return own

    def _split(self, entry: Method, ts: TrainingSet) -> list[tuple[str, TrainingSet]]:
        """(leader or "all", its rows) to train for one method (see the module doc).

        Paper A's detectors get the recorded rows only, as published; the new
        ones every row, the hybrid database included.
        """
        sub = (ts if entry.wide else ts.recorded()).with_features(entry.features or PAPER_FEATURES)
        if self.config.anfis.model == "shared" or entry.pooled_training:
            return [("all", sub)]
        return [(ld, sub.for_leader(ld)) for ld in self.leaders]

    def _train_new(self, entry: Method, ts: TrainingSet) -> tuple[Detector | None, str]:
        """One detector trained on the given rows, or (None, why not)."""
        if len(ts) == 0:
            return None, "no labelled epochs in the training window"
        factory = self._factories.get(entry.name) or method(entry.name).factory
        if factory is None:
            return None, f"{entry.name} has no detector factory"
        det = factory(self.config)
        try:
            det.train_on(ts)
        except Exception as exc:  # noqa: BLE001 - a detector that cannot train is disabled, the run goes on
            return None, f"{type(exc).__name__}: {exc}"
        return det, ""
