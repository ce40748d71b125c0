"""The side-by-side runner: every method of the stack driven push-style on the same data.

Usage (docs/design.md section 2, convention 7: the engine pushes samples from an archive,
the reproduction from the simulator's arrays)::

    runner = CooperativeRunner(config, follower="follower", leaders=["leader1", "leader2"],
                               start_time_s=t0, initial_lat_rad=lat0, initial_lon_rad=lon0)
    runner.dead_reckon(t_s, forward_mps, lateral_mps, heading_rad, depth_m)   # each DVL/INS sample
    runner.range_epoch(t_s, leader, leader_lat_rad, leader_lon_rad, leader_depth_m,
                       slant_range_m, truth_range_m)                          # -> one EpochResult per method
    results = runner.finish()

Methods (``config.methods``): ``dead_reckoning`` (DR only), ``ckf``, ``ackf``
(no detection) and one ACKF per detecting method, with isolation.

Training: during the window ``start < t <= t_a = start + training_window_s``
every detecting method runs its own ACKF without isolation and collects, per
epoch with GPS truth, the features (f1, f2, f3), the signed range error
Z - Z_gps and the label. At the first sample after t_a each detector is
trained: with ``config.anfis.model == "per_leader"`` one instance per leader
on that leader's epochs; with ``"shared"`` one instance on every leader's
epochs, then copied per leader so that detectors with memory (the dual
threshold's CUSUM) keep one memory per acoustic link. The choice applies to
every trained detector, not only ANFIS. A detector that cannot be trained
(no labelled epochs, or its training fails) is disabled, reported in
``RunResults.training_errors``, and its method runs as a plain ACKF.

After t_a a flagged epoch is isolated (A.33-A.35) unless the leader's cap of
consecutive isolations is reached; past the cap it is used with R* and
counted as capped. A compensation detector's correction replaces isolation:
the range Z - correction is used. Detectors are reset after every alarm.

Inputs that cannot be used are rejected and counted in ``rejected`` by
reason, never raised: non-finite values, ranges <= 0, time going backwards
(DR steps with Δt <= 0), unknown leaders, a leader on top of the follower.

Open-loop ROC scores: every trained detector also scores, after the run,
the features of the ``ackf`` method (no isolation, so the same features for
every detector) with ``Detector.scores``; ``ackf`` runs internally even when
not requested.

The filter-independent features (``replay.stack.features``) are computed
only when a configured method decides on them (a method-table entry
whose ``features`` go beyond (f1, f2, f3)): otherwise every
epoch's EXTRA_FEATURES, and those columns of ``training_set``, are NaN.
"""

from __future__ import annotations

import copy
import math
import os
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from itertools import chain

import numpy as np

from replay.events import NAN, EpochResult, RunResults, Track
from replay.stack.config import ConfigError, StackConfig
from replay.stack.detectors.base import Decision, Detector
from replay.stack.detectors.chi_square import chi_square_threshold
from replay.stack.exclusion import LeaderExclusion
from replay.stack.features import (
    EXTRA_FEATURES,
    FEATURE_NAMES,
    PAPER_FEATURES,
    FeatureTracker,
)
from replay.stack.filters.ckf import (
    RangeInnovation,
    State2,
    dr_predict,
    isolation_action,
    position_update,
    range_innovation,
    range_update,
)
from replay.stack.injection import inject_link
from replay.stack.labels import UNKNOWN, label_one
from replay.stack.methods import DetectorFactory, method
from replay.stack.model import (
    cov_radians_to_metres,
    metric_scales_scalar,
    slant_to_horizontal,
)
from replay.stack.training import RECORDED, TRAINING_SOURCES, TrainingSet

_NO_EXTRA: tuple[float, ...] = (NAN,) * len(EXTRA_FEATURES)
_NO_DECISION = Decision(False, NAN, NAN)     # what a method that does not decide reports (frozen: shared)
_REPEAT, _LAG = EXTRA_FEATURES.index("repeat_count"), EXTRA_FEATURES.index("lag_residual_m")

@dataclass
class _Method:
    """Mutable per-method state inside the runner."""

    name: str
    kind: str
    state: State2
    wide: bool = False      # decides on every FEATURE_NAMES column (the new methods), not (f1, f2, f3)
    features: tuple[str, ...] = PAPER_FEATURES   # the columns its detector reads (the method table's)
    pooled: bool = False    # trained on every leader's rows together (the method table's pooled_training)
    threaded: bool = False  # trained on a thread beside its like (the method table's threaded_training)
    detectors: dict[str, Detector | None] = field(default_factory=dict)
    streak: Counter = field(default_factory=Counter)
    capped: int = 0


def default_training_threads() -> int:
    """Threads for AQPSO-GA training at t_a: $AUVREPLAY_TRAINING_THREADS, else the machine's cores up to 4."""
    env = os.environ.get("AUVREPLAY_TRAINING_THREADS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    return max(1, min(4, os.cpu_count() or 1))


def _columns(m: _Method, f1: float, f2: float, f3: float, extra: tuple[float, ...]) -> np.ndarray:
    """An epoch's features as the method's detector reads them (its table entry's columns)."""
    if m.features == PAPER_FEATURES:
        return np.array([f1, f2, f3])
    full = np.array([f1, f2, f3, *extra])
    return full if m.features == FEATURE_NAMES else full[[FEATURE_NAMES.index(n) for n in m.features]]


def _cov_m2(s: State2, depth_m: float) -> tuple[float, float, float]:
    """North-east covariance (nn, ne, ee) in m² of a radian state."""
    b, a = metric_scales_scalar(s.lat, depth_m)
    return s.p11 * b * b, s.p12 * b * a, s.p22 * a * a


def _finite(*values: float) -> bool:
    """True when every value is a finite number (a NaN or inf anywhere makes the sum non-finite)."""
    return math.isfinite(sum(values))


def _rows_to_set(rows: Sequence[tuple], kinds: str | Sequence[str]) -> TrainingSet:
    """A TrainingSet of runner rows (t, leader, features..., Z - Z_gps, label) with their kinds."""
    f = len(FEATURE_NAMES)
    feats = np.array([r[2:2 + f] for r in rows], dtype=float).reshape(-1, f)
    kind_col = np.full(len(rows), kinds, dtype=object) if isinstance(kinds, str) else np.array(kinds, dtype=object)
    return TrainingSet(feats, np.array([r[2 + f] for r in rows], dtype=float),
                       np.array([r[3 + f] for r in rows], dtype=np.int8),
                       np.array([r[1] for r in rows], dtype=object), FEATURE_NAMES, kind_col)


def _threshold_report(det: Detector | None) -> dict[str, float]:
    """A trained detector's named thresholds (its ``thresholds`` mapping, else its ``threshold`` as "used")."""
    named = getattr(det, "thresholds", None)
    if isinstance(named, dict):
        return {str(k): float(v) for k, v in named.items()}
    thr = getattr(det, "threshold", None)
    return {"used": float(thr)} if isinstance(thr, (int, float)) else {}


class CooperativeRunner:
    """Runs every configured method side by side on pushed DR samples and range epochs."""

    def __init__(
        self, config: StackConfig, follower: str, leaders: Sequence[str], start_time_s: float,
        initial_lat_rad: float, initial_lon_rad: float, initial_depth_m: float = 0.0,
        factories: Mapping[str, DetectorFactory] | None = None, keep_history: bool = True,
        training_threads: int | None = None, training_set: TrainingSet | None = None,
    ) -> None:
        """Start every method at the initial position with P0 = diag(p0_m)² (m², converted to rad²).

        With ``keep_history=False`` (the replay engine over long archives) the
        runner keeps no tracks and no epochs, so its memory does not grow with
        the mission; the caller takes them from `range_epoch` and `estimates`.
        Only the compact open-loop features after t_a are kept for the ROC.
        ``training_threads`` (default `default_training_threads()`) trains the
        AQPSO-GA models at t_a side by side; the results are the same for any count.
        ``training_set`` (another run's ``RunResults.training_set``) is trained on
        instead of the own window (``config.training_source == "given"``) or
        besides it (``"both"``); ValueError when the source needs a set and has
        none, or the set's features are not `FEATURE_NAMES`.
        """
        if config.training_source not in TRAINING_SOURCES:
            raise ConfigError(f"unknown training_source {config.training_source!r}; expected one of "
                             f"{', '.join(TRAINING_SOURCES)}")
        if config.training_source != "own" and training_set is None:
            raise ValueError(f"training_source {config.training_source!r} needs a training_set")
        if training_set is not None and training_set.feature_names != FEATURE_NAMES:
            raise ValueError(f"the given training set's features {training_set.feature_names} are not "
                             f"{FEATURE_NAMES}")
        self._given = training_set
        self.config = config
        self.follower = follower
        self.leaders = tuple(leaders)
        self.start_time_s = float(start_time_s)
        self.training_end_s = self.start_time_s + config.training_window_s
        self._factories = dict(factories or {})     # overrides of the method table's factories (tests)
        self.keep_history = keep_history
        self.training_threads = default_training_threads() if training_threads is None else max(1, training_threads)
        self._r_var = config.r_m ** 2
        b, a = metric_scales_scalar(initial_lat_rad, initial_depth_m)
        s0 = State2(float(initial_lat_rad), float(initial_lon_rad),
                    (config.p0_m[0] / b) ** 2, 0.0, (config.p0_m[1] / a) ** 2)
        names = list(dict.fromkeys(config.methods))
        self._reported = tuple(names)
        entries = [method(n) for n in names]
        if any(e.detects for e in entries) and "ackf" not in names:
            entries.append(method("ackf"))    # the open-loop feature source for ROC curves
        self._methods = [_Method(e.name, e.filter, s0, e.wide, e.features or PAPER_FEATURES, e.pooled_training,
                                 e.threaded_training) for e in entries]
        self._ackf = next((m for m in self._methods if m.kind == "ackf"), None)
        self._needs_database = any(e.wide for e in entries)
        # the gated ACKF the lagged residual starts from (replay.stack.features); never reported
        self._reference: _Method | None = None
        if self._needs_database and (config.features.drift_source == "lag"
                                     or "lag_residual_m" in config.hybrid_inputs):
            self._reference = _Method("reference", "reference", s0)
            self._methods.append(self._reference)
        self._gate_f2 = chi_square_threshold(config.chi_square_alpha)
        self._initial = (float(initial_lat_rad), float(initial_lon_rad), float(initial_depth_m))
        # the filter-independent features are an input of the new methods only: without one of them
        # configured the tracker is not run and an epoch's EXTRA_FEATURES are NaN (it cost ~5 % of a replay)
        self._features: FeatureTracker | None = None
        if self._needs_database:
            self._features = FeatureTracker(config.features, self.leaders, float(initial_lat_rad),
                                            float(initial_lon_rad), self._exclusion(), config.r_m, config.p0_m)
        # (t, leader, features..., Z - Z_gps, label) of the ackf method inside the window, with GPS truth
        self._train_rows: list[tuple] = []
        # the window's inputs in order, replayed with injected anomalies for the hybrid database
        self._window: list[tuple[str, tuple]] = []
        self.training_set: TrainingSet | None = None
        self.thresholds: dict[str, dict[str, dict[str, float]]] = {}
        self.training_notes: dict[str, str] = {}
        self._t = self.start_time_s
        self._t_dr = self.start_time_s
        self._depth = float(initial_depth_m)
        self._last_dr: tuple[float, float, float] = (0.0, 0.0, 0.0)   # forward, lateral, heading
        self._trained = False
        self._updated: dict[tuple[State2, RangeInnovation, bool], State2] = {}   # this epoch's updates
        self.rejected: Counter = Counter()
        self.clamped_ranges = 0
        self.position_fixes = 0
        self.training_errors: dict[str, str] = {}
        self._epochs: list[EpochResult] = []
        self._open_features: list[tuple] = []  # (t, leader, label, features...) of ackf after t_a
        self._track_t: list[float] = []
        self._track_depth: list[float] = []
        self._track_states: list[State2] = []        # len(methods) per record, flattened at finish
        self._record()

    # ------------------------------------------------------------ pushing

    def dead_reckon(self, t_s: float, forward_mps: float, lateral_mps: float, heading_rad: float,
                    depth_m: float) -> bool:
        """Advance every method by one DR sample (A.1, A.7-A.11); False when the sample was rejected."""
        # plain floats: numpy scalars would make every scalar operation downstream several times slower
        t_s, forward_mps, lateral_mps = float(t_s), float(forward_mps), float(lateral_mps)
        heading_rad, depth_m = float(heading_rad), float(depth_m)
        if not _finite(t_s, forward_mps, lateral_mps, heading_rad, depth_m):
            self.rejected["dr_non_finite"] += 1
            return False
        if not (t_s > self._t_dr and t_s >= self._t):
            self.rejected["dr_time_step_not_positive"] += 1
            return False
        self._maybe_train(t_s)
        if self._needs_database and t_s <= self.training_end_s:
            self._window.append(("dr", (t_s, forward_mps, lateral_mps, heading_rad, depth_m)))
        self._last_dr = (forward_mps, lateral_mps, heading_rad)
        self._depth = depth_m
        self._t_dr = t_s
        if t_s > self._t:     # equal when a range epoch already propagated to this instant
            self._propagate(t_s)
            self._record()
        return True

    def range_epoch(
        self, t_s: float, leader: str, leader_lat_rad: float, leader_lon_rad: float,
        leader_depth_m: float, slant_range_m: float, truth_range_m: float = NAN,
    ) -> list[EpochResult]:
        """Process one range to a leader with every method; [] when the epoch was rejected."""
        t_s, slant_range_m, truth_range_m = float(t_s), float(slant_range_m), float(truth_range_m)
        leader_lat_rad, leader_lon_rad = float(leader_lat_rad), float(leader_lon_rad)
        leader_depth_m = float(leader_depth_m)
        reason = self._epoch_problem(t_s, leader, leader_lat_rad, leader_lon_rad, leader_depth_m,
                                     slant_range_m)
        if reason:
            self.rejected[reason] += 1
            return []
        self._maybe_train(t_s)
        if t_s > self._t:
            self._propagate(t_s)     # the last DR sample's velocities carry to the ranging instant
        z, clamped = slant_to_horizontal(slant_range_m, self._depth, leader_depth_m)
        geo = (leader_lat_rad, leader_lon_rad, leader_depth_m)
        seen: dict[State2, RangeInnovation | None] = {}
        innovations = []
        for m in self._methods:     # one innovation per distinct state (see _propagate)
            if m.state not in seen:
                seen[m.state] = range_innovation(m.state, z, geo, self._depth, self._r_var)
            innovations.append(seen[m.state])
        self._updated.clear()
        usable = [inn for inn in innovations if inn is not None]
        if len(usable) < len(innovations):
            self.rejected["degenerate_geometry"] += 1
            return []
        self.clamped_ranges += clamped
        if self._needs_database and t_s <= self.training_end_s:
            self._window.append(("range", (t_s, leader, leader_lat_rad, leader_lon_rad, leader_depth_m,
                                           slant_range_m, truth_range_m)))
        truth = truth_range_m if math.isfinite(truth_range_m) else NAN
        label = label_one(z, truth, self.config.t1_m)
        ref_m = self._reference
        ref = (ref_m.state.lat, ref_m.state.lon) if ref_m is not None else None
        extra = (self._features.epoch(t_s, leader, slant_range_m, z, self._depth, geo, ref)
                 if self._features is not None else _NO_EXTRA)
        out = [self._method_epoch(m, inn, t_s, leader, z, geo, truth, label, extra)
               for m, inn in zip(self._methods, usable)]
        self._record()
        if t_s > self.training_end_s:
            self._open_features.extend((r.time_s, r.leader, r.label, r.f1, r.f2, r.f3, *extra)
                                       for r in out if r.method == "ackf")
        reported = [r for r in out if r.method in self._reported]
        if self.keep_history:
            self._epochs.extend(reported)
        return reported

    def position_fix(self, t_s: float, lat_rad: float, lon_rad: float, cov_nn_m2: float, cov_ne_m2: float,
                     cov_ee_m2: float) -> bool:
        """Update every filter (not dead reckoning) with a position fix, e.g. a KMCDF USBL fix; False if rejected.

        The fix's north-east covariance (m²) becomes rad² with the radii at the
        fix. Counted in ``position_fixes``; a fix no filter could use (not
        finite, covariance not positive definite, time going backwards) is
        counted in ``rejected`` instead.
        """
        t_s, lat_rad, lon_rad = float(t_s), float(lat_rad), float(lon_rad)
        nn, ne, ee = float(cov_nn_m2), float(cov_ne_m2), float(cov_ee_m2)
        if not _finite(t_s, lat_rad, lon_rad, nn, ne, ee):
            self.rejected["fix_non_finite"] += 1
            return False
        if not (nn > 0.0 and ee > 0.0 and nn * ee > ne * ne):
            self.rejected["fix_covariance_not_positive"] += 1
            return False
        if t_s < self._t:
            self.rejected["fix_time_backwards"] += 1
            return False
        self._maybe_train(t_s)
        if self._needs_database and t_s <= self.training_end_s:
            self._window.append(("fix", (t_s, lat_rad, lon_rad, nn, ne, ee)))
        if t_s > self._t:
            self._propagate(t_s)
        b, a = metric_scales_scalar(lat_rad, self._depth)
        r11, r12, r22 = nn / (b * b), ne / (b * a), ee / (a * a)
        if self._features is not None:
            self._features.fix(t_s, lat_rad, lon_rad, (r11, r12, r22))
        for m in self._methods:
            if m.kind != "dr":
                m.state = position_update(m.state, lat_rad, lon_rad, r11, r12, r22) or m.state
        self.position_fixes += 1
        self._record()
        return True

    def finish(self) -> RunResults:
        """Collect epochs, tracks, open-loop scores and counters into a RunResults."""
        columns = {name: np.array([getattr(e, name) for e in self._epochs]) for name in EpochResult._fields}
        if not self._epochs:
            columns = {name: np.empty(0) for name in EpochResult._fields}
        return RunResults(
            methods=self._reported, leaders=self.leaders, start_time_s=self.start_time_s,
            training_end_s=self.training_end_s, epochs=columns, tracks=self._tracks(),
            open_loop=self._open_loop(), rejected=dict(self.rejected),
            capped={m.name: m.capped for m in self._methods if m.name in self._reported},
            clamped_ranges=self.clamped_ranges, trained=self._trained,
            training_errors=dict(self.training_errors), position_fixes=self.position_fixes,
            training_set=self.training_set, thresholds=copy.deepcopy(self.thresholds),
            training_notes=dict(self.training_notes),
        )

    @property
    def trained(self) -> bool:
        """True once the detectors were trained (first sample after t_a)."""
        return self._trained

    def estimates(self) -> dict[str, tuple[float, float, float, float, float]]:
        """Each reported method's current estimate: lat, lon (rad), covariance nn, ne, ee (m²)."""
        return {m.name: (m.state.lat, m.state.lon, *_cov_m2(m.state, self._depth))
                for m in self._methods if m.name in self._reported}

    def positions(self) -> dict[str, tuple[float, float]]:
        """Each reported method's current lat, lon (rad): `estimates` without the covariances."""
        return {m.name: (m.state.lat, m.state.lon) for m in self._methods if m.name in self._reported}

    def detectors(self, method: str) -> dict[str, Detector | None]:
        """The trained detector per leader of a detecting method ({} before t_a); for views and tests."""
        return next((dict(m.detectors) for m in self._methods if m.name == method), {})

    # ------------------------------------------------------------ internals

    def _epoch_problem(self, t_s: float, leader: str, lat: float, lon: float, depth: float,
                       slant: float) -> str:
        """Why an epoch cannot be used, or '' when it can."""
        if leader not in self.leaders:
            return "unknown_leader"
        if not _finite(t_s, lat, lon, depth, slant):
            return "range_non_finite"
        if not slant > 0.0:
            return "range_not_positive"
        if t_s < self._t:
            return "range_time_backwards"
        return ""

    def _propagate(self, t_s: float) -> None:
        """Time update of every method from the current time to t_s with the last DR sample."""
        dt = t_s - self._t
        fwd, lat_v, hdg = self._last_dr
        q = self.config.q_m_per_s
        # methods whose filters have not diverged (every ACKF inside the training window, a detector
        # that has not isolated yet) hold equal states: each distinct state is predicted once
        done: dict[State2, State2] = {}
        for m in self._methods:
            nxt = done.get(m.state)
            if nxt is None:
                nxt = done[m.state] = dr_predict(m.state, dt, fwd, lat_v, hdg, self._depth, q)
            m.state = nxt
        if self._features is not None:
            self._features.propagate(dt, fwd, lat_v, hdg, self._depth)
        self._t = t_s

    def _record(self) -> None:
        """Remember every method's estimate at the current time for the tracks."""
        if not self.keep_history:
            return
        self._track_t.append(self._t)
        self._track_depth.append(self._depth)
        self._track_states.extend([m.state for m in self._methods])

    def _method_epoch(self, m: _Method, inn: RangeInnovation, t_s: float, leader: str, z: float,
                      geo: tuple[float, float, float], truth: float, label: int,
                      extra: tuple[float, ...] = _NO_EXTRA) -> EpochResult:
        """Apply one method's update rule to the epoch and describe the outcome.

        Paper A's detectors decide on (f1, f2, f3); the new ones (``wide``) on
        every feature of `FEATURE_NAMES`.
        """
        f1, f2, f3 = inn.features
        decision = _NO_DECISION
        action, used_inn, compensated = "update", inn, False
        if m.kind == "dr":
            f1 = f2 = f3 = NAN
            action = "none"
        elif m.kind == "reference":
            gate = (extra[_REPEAT] > 0 or f2 > self._gate_f2
                    or abs(extra[_LAG]) > self.config.features.reference_gate_m)   # NaN compares False
            action, m.streak[leader] = isolation_action(gate, m.streak[leader], self.config.features.reference_cap)
        elif m is self._ackf and t_s <= self.training_end_s and label != UNKNOWN:
            self._train_rows.append((t_s, leader, f1, f2, f3, *extra, z - truth, label))
        elif m.kind == "detect" and t_s > self.training_end_s and (det := m.detectors.get(leader)) is not None:
            decision = det.decide(_columns(m, f1, f2, f3, extra))
            action, used_inn, compensated = self._act(m, det, decision, inn, leader, z, geo)
        if action in ("update", "capped"):
            key = (m.state, used_inn, m.kind != "ckf")
            nxt = self._updated.get(key)
            if nxt is None:
                nxt = self._updated[key] = range_update(m.state, used_inn, self._r_var, adaptive=m.kind != "ckf")
            m.state = nxt
        nn, ne, ee = _cov_m2(m.state, self._depth)
        return EpochResult(
            t_s, leader, m.name, decision.flagged, decision.score, decision.threshold, f1, f2, f3, label,
            action == "isolate", action == "capped", compensated, z - decision.correction_m * compensated,
            inn.z_hat, m.state.lat, m.state.lon, nn, ne, ee, truth, *extra)

    def _act(self, m: _Method, det: Detector, decision: Decision, inn: RangeInnovation, leader: str,
             z: float, geo: tuple[float, float, float]) -> tuple[str, RangeInnovation, bool]:
        """Isolation with cap, or compensation, for a detecting method's decision."""
        if decision.flagged:
            det.reset()
        if decision.flagged and decision.correction_m != 0.0 and math.isfinite(decision.correction_m):
            m.streak[leader] = 0
            fixed = range_innovation(m.state, z - decision.correction_m, geo, self._depth, self._r_var)
            return "update", fixed if fixed is not None else inn, fixed is not None
        action, m.streak[leader] = isolation_action(decision.flagged, m.streak[leader],
                                                    self.config.isolation_cap)
        m.capped += action == "capped"
        return action, inn, False

    def _maybe_train(self, t_s: float) -> None:
        """Train every detector once, at the first sample after t_a (AQPSO-GA models on threads)."""
        if self._trained or t_s <= self.training_end_s:
            return
        self._trained = True
        ts = self._assemble_training_set()
        self.training_set = ts
        jobs = [(m, key, data) for m in self._methods if m.kind == "detect"
                for key, data in self._training_sets(m, ts)]
        # AQPSO-GA evaluates whole populations, where numpy and LAPACK release the GIL: two such
        # models train ~1.5x faster side by side. The other trainers are many small numpy calls
        # that only contend for the GIL (3x slower each on threads), so they run here, in turn.
        # Each job has its own data and seed: results do not depend on the threads.
        outcomes: list[tuple[Detector | None, str] | None] = [None] * len(jobs)
        heavy = [i for i, job in enumerate(jobs) if job[0].threaded]
        if self.training_threads > 1 and len(heavy) > 1:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(min(self.training_threads, len(heavy))) as pool:
                futures = {i: pool.submit(self._train_one, jobs[i][0], jobs[i][2]) for i in heavy}
            for i, future in futures.items():
                outcomes[i] = future.result()
        for i, (m, _, data) in enumerate(jobs):
            if outcomes[i] is None:
                outcomes[i] = self._train_one(m, data)
        done = [o for o in outcomes if o is not None]     # every job has its outcome by now
        for (m, key, _), (det, error) in zip(jobs, done, strict=True):
            if error:
                self.training_errors[f"{m.name}/{key}"] = error
            if key == "all":        # shared: one model, a copy per leader (memory per acoustic link)
                m.detectors = {ld: copy.deepcopy(det) if det is not None else None for ld in self.leaders}
            else:
                m.detectors[key] = det
        for m in self._methods:
            if m.kind == "detect":
                self.thresholds[m.name] = {ld: _threshold_report(det) for ld, det in m.detectors.items()
                                           if det is not None}
        for name, per_leader in self.thresholds.items():
            if per_leader:
                self.training_notes[f"{name}/thresholds"] = "; ".join(
                    f"{ld}: " + ", ".join(f"{k} {v:.3g}" for k, v in named.items())
                    for ld, named in per_leader.items())

    def _assemble_training_set(self) -> TrainingSet:
        """The rows every detector trains on, by ``config.training_source`` (see the module doc)."""
        source = self.config.training_source
        if source == "given" and self._given is not None:
            self.training_notes["source"] = f"given: {len(self._given)} rows"
            return self._given
        own = _rows_to_set(self._train_rows, RECORDED)
        recorded = len(own)
        if self._needs_database:
            own = own.concat(self._hybrid_database())
        note = f"own window: {recorded} rows, hybrid database: {len(own) - recorded} rows"
        if source == "both" and self._given is not None:
            self.training_notes["source"] = note + f", given: {len(self._given)} rows"
            return own.concat(self._given)
        self.training_notes["source"] = note
        return own

    def _hybrid_database(self) -> TrainingSet:
        """Paper A's hybrid database: the window replayed open loop (ackf) with anomalies injected into copies.

        Each copy injects `config.injection`'s kinds at their shares into every
        leader's ranges (`replay.stack.injection.inject_link`), then pushes the
        window's DR samples, fixes and ranges in their order through a fresh
        runner holding only the ackf method; its epochs with GPS truth are the
        rows, labelled from the truth like recorded ones (A.27).
        """
        cfg = self.config.injection
        ranges = [args for kind, args in self._window if kind == "range"]
        if not ranges or cfg.copies <= 0:
            return TrainingSet.empty(FEATURE_NAMES)
        t = np.array([r[0] for r in ranges], dtype=float)
        leaders = np.array([r[1] for r in ranges], dtype=object)
        slant = np.array([r[5] for r in ranges], dtype=float)
        parts: list[TrainingSet] = []
        counts: Counter[str] = Counter()
        for c in range(cfg.copies):
            new_slant, replied = slant.copy(), np.ones(slant.size, dtype=bool)
            kinds = np.full(slant.size, "normal", dtype=object)
            for j, ld in enumerate(self.leaders):
                idx = np.flatnonzero(leaders == ld)
                rng = np.random.default_rng([cfg.seed, c, j])
                new_slant[idx], replied[idx], kinds[idx] = inject_link(t[idx], slant[idx], cfg, rng)
            counts.update(kinds.tolist())
            rows = self._open_loop_copy(new_slant, replied)
            by_epoch = dict(zip(zip(t.tolist(), leaders.tolist()), kinds.tolist()))
            parts.append(_rows_to_set(rows, [by_epoch[(r[0], r[1])] for r in rows]))
        total = sum(counts.values())
        self.training_notes["database"] = f"{cfg.copies} copies of {slant.size} epochs: " + ", ".join(
            f"{kind} {n} ({n / total:.1%})" for kind, n in sorted(counts.items()))
        out = parts[0]
        for p in parts[1:]:
            out = out.concat(p)
        return out

    def _exclusion(self) -> LeaderExclusion | None:
        """Fresh leader-exclusion filters at the initial position when a new method uses them, else None.

        Used when the drift residual is the exclusion residual or anfis_hybrid
        takes it; otherwise the features stay NaN and the two extra filters
        cost nothing (held out, seeds 100-109 trained on 0, they did not help).
        """
        c = self.config
        wanted = c.features.drift_source == "exclusion" or bool(
            {"exclusion_residual_m", "exclusion_z"} & set(c.hybrid_inputs))
        if not (self._needs_database and wanted):
            return None
        return LeaderExclusion(self.leaders, *self._initial, c.p0_m, c.q_m_per_s, c.r_m, self._gate_f2,
                               c.features.exclusion_cap, c.features.exclusion_gate_m)

    def _open_loop_copy(self, slant_m: np.ndarray, replied: np.ndarray) -> list[tuple]:
        """The window's inputs replayed through one ACKF without isolation, with the given ranges: its rows.

        The same arithmetic, in the same order, as a runner holding only the
        ``ackf`` method (tests/test_detection_methods.py checks it against
        one), without the per-method bookkeeping; epochs whose range was not
        ``replied`` are left out. Rows as ``_train_rows``: (t, leader,
        features..., Z - Z_gps, label) of the epochs with GPS truth.
        """
        cfg = self.config
        lat0, lon0, depth = self._initial
        b, a = metric_scales_scalar(lat0, depth)
        state = State2(lat0, lon0, (cfg.p0_m[0] / b) ** 2, 0.0, (cfg.p0_m[1] / a) ** 2)
        tracker = FeatureTracker(cfg.features, self.leaders, lat0, lon0, self._exclusion(), cfg.r_m, cfg.p0_m)
        t_now, fwd, lat_v, hdg = self.start_time_s, 0.0, 0.0, 0.0
        q, r_var, t1 = cfg.q_m_per_s, self._r_var, cfg.t1_m
        rows: list[tuple] = []
        k = 0
        for kind, args in self._window:
            if kind == "dr":
                t_s, fwd, lat_v, hdg, depth = args
            elif kind == "fix":
                t_s = args[0]
            else:
                k += 1
                if not replied[k - 1]:
                    continue
                t_s = args[0]
            if t_s > t_now:
                state = dr_predict(state, t_s - t_now, fwd, lat_v, hdg, depth, q)
                tracker.propagate(t_s - t_now, fwd, lat_v, hdg, depth)
                t_now = t_s
            if kind == "fix":
                _, lat, lon, nn, ne, ee = args
                b, a = metric_scales_scalar(lat, depth)
                cov = (nn / (b * b), ne / (b * a), ee / (a * a))
                tracker.fix(t_s, lat, lon, cov)
                state = position_update(state, lat, lon, *cov) or state
            elif kind == "range":
                _, leader, llat, llon, ldepth, _, truth = args
                slant = float(slant_m[k - 1])
                z, _ = slant_to_horizontal(slant, depth, ldepth)
                geo = (llat, llon, ldepth)
                inn = range_innovation(state, z, geo, depth, r_var)
                if inn is None:
                    continue
                truth = truth if math.isfinite(truth) else NAN
                label = label_one(z, truth, t1)
                extra = tracker.epoch(t_s, leader, slant, z, depth, geo, None)
                if label != UNKNOWN:
                    rows.append((t_s, leader, *inn.features, *extra, z - truth, label))
                state = range_update(state, inn, r_var, adaptive=True)
        return rows

    def _training_sets(self, m: _Method, ts: TrainingSet) -> list[tuple[str, TrainingSet]]:
        """(leader or "all", its rows) to train for one method (see module doc).

        Paper A's detectors get the recorded rows only, as published; the new
        ones every row, the hybrid database included.
        """
        sub = (ts if m.wide else ts.recorded()).with_features(m.features)
        if self.config.anfis.model == "shared" or m.pooled:
            return [("all", sub)]
        return [(ld, sub.for_leader(ld)) for ld in self.leaders]

    def _train_one(self, m: _Method, ts: TrainingSet) -> tuple[Detector | None, str]:
        """One detector trained on the given rows (the method's feature columns), or (None, why not)."""
        if len(ts) == 0:
            return None, "no labelled epochs in the training window"
        factory = self._factories.get(m.name) or method(m.name).factory
        if factory is None:
            return None, f"{m.name} has no detector factory"
        det = factory(self.config)
        try:
            det.train_on(ts)
        except Exception as exc:  # noqa: BLE001 - a detector that cannot train is disabled, the run goes on
            return None, f"{type(exc).__name__}: {exc}"
        return det, ""

    def _tracks(self) -> dict[str, Track]:
        """Per reported method, its track with covariances in north-east m²."""
        t = np.array(self._track_t)
        depth = np.array(self._track_depth)
        flat = np.fromiter(chain.from_iterable(self._track_states), dtype=float, count=5 * len(self._track_states))
        states = flat.reshape(t.size, len(self._methods), 5)
        out = {}
        for i, m in enumerate(self._methods):
            if m.name not in self._reported:
                continue
            s = states[:, i, :]
            p = np.stack([s[:, 2], s[:, 3], s[:, 3], s[:, 4]], axis=-1).reshape(-1, 2, 2)
            out[m.name] = Track(t, s[:, 0].copy(), s[:, 1].copy(), cov_radians_to_metres(p, s[:, 0], depth))
        return out

    def _open_loop(self) -> dict[str, dict[str, np.ndarray]]:
        """Open-loop scores of each trained detector on the ackf method's features after t_a."""
        src = self._open_features
        leaders = np.array([e[1] for e in src], dtype=object)
        wide_all = np.array([e[3:] for e in src], dtype=float).reshape(-1, len(FEATURE_NAMES))
        out = {}
        for m in self._methods:
            if m.kind != "detect" or m.name not in self._reported:
                continue
            feats_all = wide_all[:, [FEATURE_NAMES.index(n) for n in m.features]]
            score = np.full(len(src), np.nan)
            for leader, det in m.detectors.items():
                idx = np.nonzero(leaders == leader)[0]
                if det is not None and idx.size:
                    score[idx] = det.scores(feats_all[idx])
            out[m.name] = {"time_s": np.array([e[0] for e in src], dtype=float),
                           "leader": leaders,
                           "label": np.array([e[2] for e in src], dtype=np.int8), "score": score}
        return out
