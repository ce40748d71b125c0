"""The evaluation harness: simulated trials through the real pipeline, trained on one, scored on the others.

Every trial is simulated (`samples.simulator`), written as vendor logs,
recorded into an archive and replayed (`replay_archive`), exactly as
`auvreplay simulate`, `record` and `replay` do. The manifest and the logs
go to a scratch directory of the process that runs it (in memory, /dev/shm,
where the system has one; the truth CSVs are not needed: the simulator's
arrays are at hand), removed when the trial ends; the archive is recorded
into memory and replayed from its bytes: no archive is written, nothing is
written anywhere else, and a Dask worker needs no shared file system. A
listener keeps each epoch's decision per method after t_a; the simulator's
own arrays give each epoch's injected anomaly kind. Only the test seeds are
scored: the train seed never is.

The trials of one seed (scripted, and at each drift rate of the sweep) differ
only in the follower's acoustic log: they are prepared together
(`prepare_trials`, `SeedCache`): the navigation logs are written once
(`samples.writer.log_files`' `like`) and a log of the same bytes is decoded
once (`recorders.record.ReusedLogs`); each archive is the bytes `record`
writes alone, which the tests check.

On Dask (`run_trials`) a trial is two tasks, `prepare_trials` (simulate and
record one seed's trials: the archives' bytes come back) and `score_prepared`
(replay), so the trials are prepared while the train seeds train; the train
seeds go first. Detectors trained on the train seed's set are the same in
every test trial, so each process trains them once and copies them
(`replay.stack.training_window.reuse_training`): the figures are those of
training them in every trial, which the tests check array for array.

Training (`TRAINING_MODES`, the runner's `StackConfig.training_source`):
with "given" (the default) the train seed is replayed first and every test
trial's detectors are trained on what the train seed's were
(`RunResults.training_set`: its window's epochs and, for the new methods, its
hybrid database), not on the test trial's own window; "both" trains on the
two together; "own" trains every test trial on its own window (0 to t_a), and
the train seed is then not run at all. Either way the test trials' windows
are never scored.

Figures per method, pooled over the test seeds (one ROC over every test
epoch, one error distribution over every GPS fix after t_a):

* `auc`, `fnr_at_fpr_1|2|5`: open loop, from `Detector.scores` on the
  features of the unisolated ACKF (`replay.stack.scoring`); FNR = 1 - the
  best recall at FPR <= target.
* `recall_by_kind`: closed loop, the method's own decisions: among epochs
  labelled anomalous (|Z_gps - Z| > T1) whose range carried an injected
  anomaly of that kind, the share flagged. An epoch of a kind whose error
  stays under T1 (the start of a drift) is a normal epoch, as the labels say.
  `dropout` is always None: a dropout is a ping with no reply, so there is no
  epoch to flag or miss (the next reply is an ordinary range). A kind with no
  anomalous epoch gets None too.
* `error_p50_m`, `error_p90_m`: horizontal error against the follower's GPS.
* `Evaluation.closed_loop_fpr` (the text table's `fpr_closed`, not in the
  JSON, whose shape is fixed): the share flagged of the epochs labelled
  normal, closed loop: what the recalls per kind cost.

Detecting methods are the ones whose run has open-loop scores; the others
(dead reckoning, CKF, ACKF) get errors only. Method names come from the run
configuration, so new methods appear here by themselves.

The drift sweep re-simulates the test seeds with every scripted drift set to
each rate (`Scenario.with_drift_rate`) and gives each detecting method's
closed-loop drift recall per rate, with the count of anomalous drift epochs
behind it.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from formats.mcap_reader import ArchiveReader
from formats.units import NS
from recorders.manifest import load_manifest
from recorders.record import RecordingSummary, ReusedLogs, record
from replay.engine.config import RunConfig
from replay.errors import UserError
from replay.events import EpochResult, ErrorSample, Fix, Listener
from replay.run.pipeline import RunOutcome, replay_archive
from replay.stack.scoring import error_stats, recall_at_fpr, roc_auc, roc_curve
from replay.stack.training import TRAINING_SOURCES, TrainingSet
from replay.stack.training_window import TrainedCache, reuse_training
from samples.anomalies import KIND_CODES
from samples.scenario import ANOMALY_KINDS, Scenario, ScenarioError
from samples.simulator import SimulatedTrial, simulate_trial
from samples.writer import log_files, write_files

if TYPE_CHECKING:
    from distributed import Client, Future

FPR_TARGETS: tuple[int, ...] = (1, 2, 5)
"""FNR is reported at these open-loop false-positive rates (%)."""
DEFAULT_DRIFT_RATES: tuple[float, ...] = (0.1, 0.2, 0.3, 0.5, 1.0)
"""Drift rates (m/s) of the default sweep: from drifts that stay under T1 over 70 s to fast ones."""
TRAINING_MODES: tuple[str, ...] = TRAINING_SOURCES
"""How test trials get their detectors trained (see the module docstring); "given" by default."""
MATCH_TOLERANCE_S = 0.5
"""A replayed epoch is the simulator's epoch of the same link within this time (pings 2.4 s apart)."""
NO_KIND = -1
"""Kind code of a replayed epoch the simulator has no epoch for (never counted in a kind)."""
SCRATCH_IN_MEMORY = "/dev/shm"
"""Where a trial's logs and archive go while it runs, when the system has it: a memory file system."""
_TRAINED_HERE = TrainedCache()
"""The detectors this process trained on a given set (a Dask worker keeps them from one trial to the next)."""


@dataclass(frozen=True)
class TrialSpec:
    """One trial to simulate and replay: the seed, its drift rate (None: the scenario's), length and scenario."""

    seed: int
    drift_rate_mps: float | None = None
    duration_s: float | None = None
    base: Scenario = field(default_factory=Scenario)

    def scenario(self) -> Scenario:
        """The scenario of this trial: the base one with the length and drift rate applied."""
        s = self.base.with_options(self.duration_s, None)
        return s if self.drift_rate_mps is None else s.with_drift_rate(self.drift_rate_mps)


@dataclass
class TrialScores:
    """What one replayed trial contributes to the figures: compact arrays, picklable for Dask."""

    spec: TrialSpec
    methods: tuple[str, ...]
    detecting: tuple[str, ...]
    flagged: dict[str, np.ndarray]      # method -> closed-loop decision per scored epoch
    labels: dict[str, np.ndarray]       # method -> label per scored epoch (1, 0; unknown dropped)
    kinds: dict[str, np.ndarray]        # method -> injected kind code per scored epoch (KIND_CODES, NO_KIND)
    open_labels: dict[str, np.ndarray]  # method -> open-loop labels
    open_scores: dict[str, np.ndarray]  # method -> open-loop scores
    errors: dict[str, np.ndarray]       # method -> horizontal errors (m) at GPS fixes after t_a
    unmatched: int = 0                  # scored epochs the simulator had no epoch for
    wall_s: float = 0.0
    cpu_s: float = 0.0                  # this process's CPU time for the trial (not slowed by other load)


class _EpochLog(Listener):
    """Keeps, after t_a, each epoch's (follower, leader, time, flagged, label) per method and the errors."""

    def __init__(self, training_end_s: float) -> None:
        self.training_end_s = training_end_s
        self.rows: dict[str, list[tuple[str, str, float, bool, int]]] = {}
        self.error_m: dict[str, list[float]] = {}

    def epoch(self, follower: str, results: list[EpochResult], leader_fix: Fix | None) -> None:
        """Remember one scored epoch's decision of every method (the engine's window: after t_a, label known)."""
        for r in results:
            if r.time_s > self.training_end_s and r.label >= 0:
                self.rows.setdefault(r.method, []).append((follower, r.leader, r.time_s, bool(r.flagged),
                                                           int(r.label)))

    def errors(self, follower: str, samples: list[ErrorSample]) -> None:
        """Remember the horizontal errors after t_a (the engine's scoring window)."""
        for s in samples:
            if s.t_s >= self.training_end_s:
                self.error_m.setdefault(s.method, []).append(s.error_m)


def epoch_kinds(sim_follower: np.ndarray, sim_leader: np.ndarray, sim_t: np.ndarray, sim_kind: np.ndarray,
                follower: np.ndarray, leader: np.ndarray, t: np.ndarray,
                tolerance_s: float = MATCH_TOLERANCE_S) -> np.ndarray:
    """The simulator's kind code of each replayed epoch: the nearest epoch of the same link within tolerance.

    NO_KIND where the link has no simulated epoch that close.
    """
    out = np.full(len(t), NO_KIND, dtype=np.int16)
    t = np.asarray(t, float)
    for f, ld in {(str(a), str(b)) for a, b in zip(follower, leader)}:
        mine = np.flatnonzero((follower == f) & (leader == ld))
        theirs = np.flatnonzero((sim_follower == f) & (sim_leader == ld))
        if theirs.size == 0:
            continue
        order = theirs[np.argsort(sim_t[theirs], kind="stable")]
        st = np.asarray(sim_t, float)[order]
        hi = np.clip(np.searchsorted(st, t[mine]), 0, st.size - 1)
        lo = np.clip(hi - 1, 0, st.size - 1)
        nearest = np.where(np.abs(st[lo] - t[mine]) <= np.abs(st[hi] - t[mine]), lo, hi)
        close = np.abs(st[nearest] - t[mine]) <= tolerance_s
        out[mine[close]] = np.asarray(sim_kind)[order[nearest[close]]]
    return out


def _archive_offset_s(archive: bytes, trial: SimulatedTrial) -> float:
    """Seconds from the simulated trial's start to the archive's first message (replay times count from it)."""
    with ArchiveReader(archive) as reader:
        start = reader.summary().start_ns
    return 0.0 if start is None else (start - trial.start_ns) / NS


def refused_records(summary: RecordingSummary) -> int:
    """The records `record` did not archive over every log: unparsed, bad checksums and values out of range."""
    return summary.skipped  # the recorder counts every refusal, value checks included, as skipped


def _scratch(seed: int) -> tempfile.TemporaryDirectory[str]:
    """A temporary directory for one trial's logs: in memory (/dev/shm) where the system has one."""
    memory = SCRATCH_IN_MEMORY if os.path.isdir(SCRATCH_IN_MEMORY) and os.access(SCRATCH_IN_MEMORY, os.W_OK) else None
    return tempfile.TemporaryDirectory(prefix=f"auvreplay-evaluate-{seed}-", dir=memory)


@dataclass
class SeedCache:
    """What one seed's trials share, prepared one after another: the first trial and its log files (its
    navigation logs are the others' when their navigation is the same) and every log recorded so far."""

    like: tuple[SimulatedTrial, dict[str, bytes]] | None = None
    logs: ReusedLogs = field(default_factory=dict)


def _record_trial(spec: TrialSpec, root: Path, reuse: SeedCache | None = None
                  ) -> tuple[SimulatedTrial, bytes, float]:
    """Simulate one trial, write its manifest and logs under `root` and record them into memory: the trial, the
    archive's bytes, the offset. With `reuse`, what an earlier trial of the seed wrote and decoded is taken."""
    trial = simulate_trial(spec.scenario(), spec.seed)
    # the manifest and the logs only: the truth CSVs come from the arrays, not from files
    files = log_files(trial, reuse.like if reuse is not None else None)
    write_files(files, root)
    if reuse is not None and reuse.like is None:
        reuse.like = (trial, files)
    buffer = io.BytesIO()
    # one process per trial: the harness runs trials side by side instead
    summary = record(load_manifest(root / "trial.toml"), buffer, workers=1,
                     reuse=reuse.logs if reuse is not None else None)
    archive = buffer.getvalue()
    refused = refused_records(summary)
    if refused:
        # a simulated log is valid by construction: a refused record is a simulator bug that would
        # silently take a sensor out of the filters (a negative heading std once took every follower INS)
        raise UserError(f"seed {spec.seed}: record refused {refused} simulated records (unparsed, bad "
                        "checksum or out of range); a trial with refused records is not scored")
    return trial, archive, _archive_offset_s(archive, trial)


def _replay(archive: bytes, config: RunConfig, listeners: Sequence[Listener],
            training_set: TrainingSet | None) -> RunOutcome:
    """Replay one trial's archive from its bytes, nothing written and no navigation review (never read here);
    detectors trained on a given set are trained once per process."""
    given = training_set is not None and config.stack.training_source == "given"
    with reuse_training(_TRAINED_HERE) if given else contextlib.nullcontext():
        return replay_archive(archive, config, write_output=False, listeners=listeners, training_set=training_set,
                              nav_review=False)


def _closed_loop(spec: TrialSpec, config: RunConfig, listeners: Sequence[Listener] = (),
                 training_set: TrainingSet | None = None,
                 reuse: SeedCache | None = None) -> tuple[SimulatedTrial, RunOutcome, float]:
    """Simulate, write, record and replay one trial (logs in a scratch directory): the trial, the run, the offset."""
    with _scratch(spec.seed) as tmp:
        trial, archive, offset_s = _record_trial(spec, Path(tmp), reuse)
    return trial, _replay(archive, config, listeners, training_set), offset_s


def training_set_of(spec: TrialSpec, config: RunConfig) -> TrainingSet:
    """What the detectors of the train seed's run trained on (its own window), every follower's rows together."""
    own = replace(config, stack=replace(config.stack, training_source="own"))
    _, outcome, _ = _closed_loop(spec, own)
    sets = [outcome.results[f].training_set for f in sorted(outcome.results)]
    found = [s for s in sets if s is not None]
    if not found:
        raise UserError(f"train seed {spec.seed}: its run never reached the end of the training window "
                        f"({config.stack.training_window_s:g} s), so there is nothing to train on")
    out = found[0]
    for s in found[1:]:
        out = out.concat(s)
    return out


@dataclass
class PreparedTrial:
    """A trial simulated and recorded, not yet replayed: its archive's bytes and the simulator's epochs."""

    spec: TrialSpec
    archive: bytes
    offset_s: float
    epochs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]   # follower, leader, t_s, injected kind code
    wall_s: float
    cpu_s: float


def _epochs(trial: SimulatedTrial) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r = trial.ranges
    return r.follower, r.leader, r.t_s, r.injected


def prepare_trial(spec: TrialSpec, reuse: SeedCache | None = None) -> PreparedTrial:
    """Simulate and record one trial (what needs no training set): a task that runs while the train seed trains."""
    wall0, cpu0 = time.monotonic(), time.process_time()
    with _scratch(spec.seed) as tmp:
        trial, archive, offset_s = _record_trial(spec, Path(tmp), reuse)
    return PreparedTrial(spec, archive, offset_s, _epochs(trial), time.monotonic() - wall0,
                         time.process_time() - cpu0)


def prepare_trials(specs: Sequence[TrialSpec]) -> list[PreparedTrial]:
    """`prepare_trial` of several trials in turn, sharing what they can (`SeedCache`: one seed's sweep)."""
    reuse = SeedCache()
    return [prepare_trial(spec, reuse) for spec in specs]


def _nth(prepared: Sequence[PreparedTrial], i: int) -> PreparedTrial:
    """One trial of a `prepare_trials` task (a Dask task of its own, run where the list is)."""
    return prepared[i]


def score_prepared(prepared: PreparedTrial, config: RunConfig,
                   training_set: TrainingSet | None = None) -> TrialScores:
    """Replay a prepared trial (trained as `config.stack.training_source` says); its scores after t_a."""
    wall0, cpu0 = time.monotonic(), time.process_time()
    log = _EpochLog(config.stack.training_window_s)
    outcome = _replay(prepared.archive, config, [log], training_set)
    return _scores(prepared.spec, config, outcome, log, prepared.epochs, prepared.offset_s,
                   prepared.wall_s + time.monotonic() - wall0, prepared.cpu_s + time.process_time() - cpu0)


def evaluate_trial(spec: TrialSpec, config: RunConfig, training_set: TrainingSet | None = None,
                   reuse: SeedCache | None = None) -> TrialScores:
    """One trial through the real pipeline (trained as `config.stack.training_source` says); its scores after t_a.

    `reuse`: the logs recorded before (`prepare_trials`), for trials of the same seed one after another."""
    wall0, cpu0 = time.monotonic(), time.process_time()
    log = _EpochLog(config.stack.training_window_s)
    trial, outcome, offset_s = _closed_loop(spec, config, [log], training_set, reuse)
    return _scores(spec, config, outcome, log, _epochs(trial), offset_s, time.monotonic() - wall0,
                   time.process_time() - cpu0)


def _scores(spec: TrialSpec, config: RunConfig, outcome: RunOutcome, log: _EpochLog,
            epochs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], offset_s: float, wall_s: float,
            cpu_s: float) -> TrialScores:
    """A replayed trial's decisions, labels, kinds, open-loop scores and errors after t_a, per method."""
    sim_follower, sim_leader, sim_t, sim_kind = epochs
    methods = tuple(config.stack.methods)
    detecting = tuple(m for m in methods if any(m in res.open_loop for res in outcome.results.values()))
    flagged, labels, kinds = {}, {}, {}
    unmatched = 0
    for m in methods:
        rows = log.rows.get(m, [])
        fol = np.array([x[0] for x in rows], dtype=object)
        led = np.array([x[1] for x in rows], dtype=object)
        t = np.array([x[2] for x in rows], dtype=float) + offset_s
        flagged[m] = np.array([x[3] for x in rows], dtype=bool)
        labels[m] = np.array([x[4] for x in rows], dtype=np.int8)
        kinds[m] = epoch_kinds(sim_follower, sim_leader, sim_t, sim_kind, fol, led, t)
        unmatched = max(unmatched, int(np.sum(kinds[m] == NO_KIND)))
    open_labels, open_scores = {}, {}
    for m in detecting:
        ol = [res.open_loop[m] for res in outcome.results.values() if m in res.open_loop]
        open_labels[m] = np.concatenate([o["label"].astype(np.int8) for o in ol])
        open_scores[m] = np.concatenate([o["score"].astype(float) for o in ol])
    errors = {m: np.asarray(log.error_m.get(m, []), dtype=float) for m in methods}
    return TrialScores(spec, methods, detecting, flagged, labels, kinds, open_labels, open_scores, errors,
                       unmatched, wall_s, cpu_s)


# ---------------------------------------------------------------------------- figures

def _pool(parts: Sequence[np.ndarray], dtype: Any) -> np.ndarray:
    return np.concatenate([np.asarray(p, dtype=dtype) for p in parts]) if parts else np.empty(0, dtype=dtype)


def recall_by_kind(flagged: np.ndarray, labels: np.ndarray, kinds: np.ndarray) -> dict[str, float | None]:
    """Per anomaly kind, the share flagged of the anomalous epochs of that kind; None when there are none.

    `dropout` is None always: a dropout leaves no epoch (see the module docstring).
    """
    flagged, labels, kinds = np.asarray(flagged, bool), np.asarray(labels), np.asarray(kinds)
    out: dict[str, float | None] = {}
    for kind in ANOMALY_KINDS:
        code = KIND_CODES.get(kind)
        sel = (labels == 1) & (kinds == code) if code is not None else np.zeros(len(labels), bool)
        out[kind] = float(flagged[sel].mean()) if sel.any() else None
    return out


def method_figures(trials: Sequence[TrialScores], method: str) -> dict[str, Any]:
    """One method's figures pooled over trials: AUC, FNR at FPR targets, recall by kind, error p50/p90."""
    detecting = any(method in t.detecting for t in trials)
    row: dict[str, Any] = {"auc": None, **{f"fnr_at_fpr_{p}": None for p in FPR_TARGETS}}
    if detecting:
        fpr, tpr, _ = roc_curve(_pool([t.open_labels[method] for t in trials if method in t.open_labels], np.int8),
                                _pool([t.open_scores[method] for t in trials if method in t.open_scores], float))
        row["auc"] = roc_auc(fpr, tpr)
        for p in FPR_TARGETS:
            rec = recall_at_fpr(fpr, tpr, p / 100.0)
            row[f"fnr_at_fpr_{p}"] = None if rec is None else 1.0 - rec
        row["recall_by_kind"] = recall_by_kind(_pool([t.flagged[method] for t in trials], bool),
                                               _pool([t.labels[method] for t in trials], np.int8),
                                               _pool([t.kinds[method] for t in trials], np.int16))
    else:
        row["recall_by_kind"] = {kind: None for kind in ANOMALY_KINDS}
    stats = error_stats(_pool([t.errors.get(method, np.empty(0)) for t in trials], float))
    row["error_p50_m"], row["error_p90_m"] = stats["error_p50_m"], stats["error_p90_m"]
    return row


def closed_loop_fpr(trials: Sequence[TrialScores], method: str) -> float | None:
    """The share of a detecting method's scored epochs labelled normal that it flagged (None: not detecting)."""
    if not any(method in t.detecting for t in trials):
        return None
    flagged = _pool([t.flagged[method] for t in trials], bool)
    normal = _pool([t.labels[method] for t in trials], np.int8) == 0
    return float(flagged[normal].mean()) if normal.any() else None


def drift_sweep(trials_by_rate: Mapping[float, Sequence[TrialScores]]) -> list[dict[str, Any]]:
    """Per drift rate and detecting method: closed-loop drift recall and the anomalous drift epochs behind it."""
    out: list[dict[str, Any]] = []
    code = KIND_CODES["drift"]
    for rate, trials in trials_by_rate.items():
        methods = list(dict.fromkeys(m for t in trials for m in t.detecting))
        for m in methods:
            flagged = _pool([t.flagged[m] for t in trials], bool)
            sel = (_pool([t.labels[m] for t in trials], np.int8) == 1) & \
                (_pool([t.kinds[m] for t in trials], np.int16) == code)
            out.append({"rate_mps": float(rate), "method": m,
                        "recall": float(flagged[sel].mean()) if sel.any() else None, "epochs": int(sel.sum())})
    return out


# ---------------------------------------------------------------------------- the plan and its run

@dataclass(frozen=True)
class Evaluation:
    """What `evaluate` found: the JSON object's content, and how long it took."""

    seeds: tuple[int, ...]
    train_seed: int
    training: str
    methods: dict[str, dict[str, Any]]
    sweep: list[dict[str, Any]]
    trials: int
    unmatched: int
    wall_s: float
    cpu_s: float                        # CPU time summed over the scored trials
    workers: str
    notes: list[str] = field(default_factory=list)
    closed_loop_fpr: dict[str, float | None] = field(default_factory=dict)   # per method; not in to_json

    def to_json(self) -> dict[str, Any]:
        """The `evaluate --json` object (module docstring; None for what is undefined)."""
        return _clean({"seeds": list(self.seeds), "train_seed": self.train_seed, "methods": self.methods,
                       "drift_sweep": self.sweep})


def _clean(obj: Any) -> Any:
    """JSON-safe: numpy scalars to Python, NaN to None."""
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(float(obj)) else None
    return obj


def split_seeds(seeds: Sequence[int], train_seed: int | None) -> tuple[int, list[int]]:
    """(train seed, test seeds): the train seed defaults to the first and is never a test seed."""
    if not seeds:
        raise UserError("--seeds: no seeds given")
    train = seeds[0] if train_seed is None else train_seed
    test = [s for s in seeds if s != train]
    if not test:
        raise UserError(f"--seeds: nothing left to test once train seed {train} is held out")
    return train, test


Progress = Callable[[int, int], None]      # (done, total)


@dataclass(frozen=True)
class TrialGroup:
    """Trials replayed under one configuration: the train seed's (None: each trains on its own), then the tests."""

    config: RunConfig
    train: TrialSpec | None
    specs: tuple[TrialSpec, ...]


def same_seed(specs: Sequence[TrialSpec]) -> list[list[int]]:
    """The specs' indices by trial but for the drift rate (seed, length, scenario), in order of first appearance."""
    sets: list[list[int]] = []
    firsts: list[TrialSpec] = []
    for i, spec in enumerate(specs):
        plain = replace(spec, drift_rate_mps=None)
        k = next((j for j, f in enumerate(firsts) if f == plain), None)
        if k is None:
            firsts.append(plain)
            sets.append([i])
        else:
            sets[k].append(i)
    return sets


def run_trials(groups: Sequence[TrialGroup], client: Client | None = None,
               progress: Progress | None = None) -> list[list[TrialScores]]:
    """Every group's test trials scored, in order: on the Dask client, else one by one here.

    On Dask a trial is two tasks: `prepare_trials` (simulate and record one seed's trials of the group,
    no training needed) and `score_prepared` (replay, once its group's training set is there). Every
    train seed is submitted first, then each seed's tasks: the workers start on the train seeds, and
    while one trains the other prepares trials, so no worker waits for a training set. Dask runs the
    ready task submitted first, so prepared trials are replayed before more are prepared (memory: a few
    seeds' archives). Here, a seed's logs are kept from its first trial to its last (`evaluate_trial`'s
    `reuse`).
    """
    total = sum(len(g.specs) + (g.train is not None) for g in groups)
    done = 0
    if client is None:
        out: list[list[TrialScores]] = []
        for g in groups:
            given = training_set_of(g.train, g.config) if g.train is not None else None
            if g.train is not None:
                done += 1
                if progress is not None:
                    progress(done, total)
            sets = same_seed(g.specs)
            last = {s[-1]: k for k, s in enumerate(sets)}
            kept: dict[int, SeedCache] = {}
            which = {i: k for k, s in enumerate(sets) for i in s}
            scored = []
            for i, spec in enumerate(g.specs):
                reuse = kept.setdefault(which[i], SeedCache()) if len(sets[which[i]]) > 1 else None
                scored.append(evaluate_trial(spec, g.config, given, reuse))
                if i in last:
                    kept.pop(last[i], None)
                done += 1
                if progress is not None:
                    progress(done, total)
            out.append(scored)
        return out
    # dask only when a client is used (a heavy optional import)
    from distributed import as_completed

    trained: list[Future | None] = [client.submit(training_set_of, g.train, g.config, pure=False)
                                    if g.train is not None else None for g in groups]
    futures: list[list[Future]] = []
    for g, train_future in zip(groups, trained):
        scores: dict[int, Future] = {}
        for indices in same_seed(g.specs):
            prepared = client.submit(prepare_trials, [g.specs[i] for i in indices], pure=False)
            for n, i in enumerate(indices):
                scores[i] = client.submit(score_prepared, client.submit(_nth, prepared, n, pure=False), g.config,
                                          train_future, pure=False)
        futures.append([scores[i] for i in range(len(g.specs))])
    where = {f.key: (k, i) for k, group in enumerate(futures) for i, f in enumerate(group)}
    results: list[list[TrialScores | None]] = [[None] * len(group) for group in futures]
    watched = [f for f in trained if f is not None] + [f for group in futures for f in group]
    for done, fut in enumerate(as_completed(watched), 1):
        if fut.key in where:
            k, i = where[fut.key]
            results[k][i] = fut.result()
            fut.release()
        elif fut.status == "error":
            fut.result()      # raises the train seed's error here, as the in-process loop does
        if progress is not None:
            progress(done, total)
    return [[t for t in group if t is not None] for group in results]


def evaluate(seeds: Sequence[int], config: RunConfig, train_seed: int | None = None,
             drift_rates: Sequence[float] = DEFAULT_DRIFT_RATES, duration_s: float | None = None,
             training: str = "given", client: Client | None = None, progress: Progress | None = None,
             scenario: Scenario | None = None) -> Evaluation:
    """Simulate and replay the test seeds (and the sweep's) of a scenario (default: the sample trial's); score them.

    See the module docstring.
    """
    base = scenario if scenario is not None else Scenario()
    if training not in TRAINING_MODES:
        raise UserError(f"training {training!r}: expected one of {', '.join(TRAINING_MODES)}")
    if duration_s is not None and not duration_s > 0:
        raise UserError("--duration must be > 0")
    if any(not (math.isfinite(r) and r >= 0) for r in drift_rates):
        raise UserError("--drift-rate: rates must be finite numbers >= 0 (m/s)")
    train, test = split_seeds(list(seeds), train_seed)
    wall0 = time.monotonic()
    rates = list(dict.fromkeys(float(r) for r in drift_rates))
    specs = [TrialSpec(s, None, duration_s, base) for s in test]
    specs += [TrialSpec(s, rate, duration_s, base) for rate in rates for s in test]
    config = replace(config, stack=replace(config.stack, training_source=training))
    train_spec = TrialSpec(train, None, duration_s, base) if training != "own" else None
    try:
        trials = run_trials([TrialGroup(config, train_spec, tuple(specs))], client, progress)[0]
    except ScenarioError as exc:
        raise UserError(f"scenario: {exc}") from None
    main = trials[:len(test)]
    by_rate = {rate: trials[len(test) * (1 + k): len(test) * (2 + k)] for k, rate in enumerate(rates)}
    methods = {m: method_figures(main, m) for m in config.stack.methods}
    unmatched = sum(t.unmatched for t in trials)
    notes = [f"{unmatched} scored epochs had no simulated epoch within {MATCH_TOLERANCE_S} s (no kind)"] \
        if unmatched else []
    where = "here, one trial at a time" if client is None else \
        f"Dask, {len(client.scheduler_info().get('workers', {}))} workers"
    return Evaluation(tuple(test), train, training, methods, drift_sweep(by_rate),
                      len(trials) + (train_spec is not None), unmatched,
                      time.monotonic() - wall0, sum(t.cpu_s for t in trials), where, notes,
                      {m: closed_loop_fpr(main, m) for m in config.stack.methods})


__all__ = ["DEFAULT_DRIFT_RATES", "FPR_TARGETS", "TRAINING_MODES", "Evaluation", "PreparedTrial", "SeedCache",
           "TrialGroup", "TrialScores", "TrialSpec", "closed_loop_fpr", "drift_sweep", "epoch_kinds", "evaluate",
           "evaluate_trial", "method_figures", "prepare_trial", "prepare_trials", "recall_by_kind", "refused_records",
           "run_trials", "same_seed", "score_prepared", "split_seeds", "training_set_of"]
