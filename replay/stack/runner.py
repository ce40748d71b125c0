"""The side-by-side runner: every method of the stack driven push-style on the same data.

Usage (docs/design.md section 2, convention 7: the engine pushes samples from an archive,
the reproduction from the simulator's arrays)::

    runner = CooperativeRunner(config, "follower", ["leader1", "leader2"], Start(t0, lat0, lon0))
    runner.dead_reckon(t_s, forward_mps, lateral_mps, heading_rad, depth_m)   # each DVL/INS sample
    runner.range_epoch(t_s, leader, leader_lat_rad, leader_lon_rad, leader_depth_m,
                       slant_range_m, truth_range_m)                          # -> one EpochResult per method
    results = runner.finish()

Methods (``config.methods``, read from the method table `replay.stack.methods`):
``dead_reckoning`` (DR only), ``ckf``, ``ackf`` (no detection) and one ACKF
per detecting method, with isolation.

The runner is handed its collaborators (`RunnerParts`), the way a tracker is
given its initiator, deleter, associator and updater, and wires them:

- `replay.stack.training_window.TrainingWindow` collects the training window
  and trains every detector once, at the first sample after t_a (the hybrid
  database in `replay.stack.hybrid_database`);
- the `replay.stack.features.FeatureTracker` (built by
  `replay.stack.tracking`) gives each epoch's filter-independent features,
  only when a configured method reads them: otherwise every epoch's
  EXTRA_FEATURES, and those columns of ``training_set``, are NaN;
- `replay.stack.isolation.Isolation` isolates a flagged range (capped per
  leader) or uses a compensation detector's corrected range; detectors are
  reset after every alarm;
- `replay.stack.open_loop.OpenLoopScores` keeps the ``ackf`` method's
  features after t_a for the ROC curves (``ackf`` runs internally even when
  not requested);
- `replay.stack.history.History` keeps the tracks and epochs (or not).

Inputs that cannot be used are rejected and counted in ``rejected`` by
reason, never raised: non-finite values, ranges <= 0, time going backwards
(DR steps with Δt <= 0), unknown leaders, a leader on top of the follower.
"""

from __future__ import annotations

import copy
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from replay.events import NAN, EpochResult, RunResults, Track
from replay.stack.config import StackConfig
from replay.stack.detectors.base import Decision, Detector
from replay.stack.detectors.chi_square import chi_square_threshold
from replay.stack.features import EXTRA_FEATURES, FEATURE_NAMES, PAPER_FEATURES, FeatureTracker
from replay.stack.filters.ckf import (
    RangeInnovation,
    State2,
    dr_displacement,
    dr_predict_moved,
    position_update,
    range_innovation,
    range_update,
)
from replay.stack.history import History
from replay.stack.isolation import Isolation, Ranging
from replay.stack.labels import UNKNOWN, label_one
from replay.stack.methods import method
from replay.stack.model import metric_scales_scalar, slant_to_horizontal
from replay.stack.open_loop import OpenLoopScores
from replay.stack.runner_options import RunnerOptions, Start, default_training_threads
from replay.stack.running_threshold import RunningThreshold
from replay.stack.tracking import runner_tracker
from replay.stack.training_window import TrainingWindow

__all__ = ["CooperativeRunner", "EpochResult", "RunResults", "RunnerOptions", "RunnerParts", "Start", "Track",
           "default_training_threads"]

_NO_EXTRA: tuple[float, ...] = (NAN,) * len(EXTRA_FEATURES)
_NO_DECISION = Decision(False, NAN, NAN)     # what a method that does not decide reports (frozen: shared)
_REPEAT, _LAG = EXTRA_FEATURES.index("repeat_count"), EXTRA_FEATURES.index("lag_residual_m")


@dataclass
class _Method:
    """Mutable per-method state inside the runner."""

    name: str
    kind: str
    state: State2
    features: tuple[str, ...] = PAPER_FEATURES   # the columns its detector reads (the method table's)
    detectors: dict[str, Detector | None] = field(default_factory=dict)   # per leader, once trained
    running: bool = False            # decides against a running threshold (replay.stack.running_threshold)
    threshold: RunningThreshold | None = None   # ... every leader's epochs together, from its first decision


@dataclass(frozen=True)
class RunnerParts:
    """The collaborators a runner is handed: training, feature tracking, isolation, ROC scoring, history."""

    trainer: TrainingWindow
    features: FeatureTracker | None
    isolation: Isolation
    open_loop: OpenLoopScores
    history: History

    @classmethod
    def build(cls, config: StackConfig, leaders: Sequence[str], start: Start,
              options: RunnerOptions) -> RunnerParts:
        """The stack's own collaborators for a runner (ConfigError or ValueError for a bad training source)."""
        return cls(TrainingWindow(config, leaders, start, options), runner_tracker(config, leaders, start),
                   Isolation(config.isolation_cap, config.r_m ** 2), OpenLoopScores(), History(options.keep_history))


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


class CooperativeRunner:
    """Runs every configured method side by side on pushed DR samples and range epochs."""

    def __init__(self, config: StackConfig, follower: str, leaders: Sequence[str], start: Start,
                 options: RunnerOptions | None = None, parts: RunnerParts | None = None) -> None:
        """Start every method at ``start`` with P0 = diag(p0_m)² (m², converted to rad²).

        ``parts`` are the collaborators; by default `RunnerParts.build` makes
        the stack's own from ``config`` and ``options`` (which only they read).
        """
        self.parts = parts if parts is not None else RunnerParts.build(config, leaders, start,
                                                                       options or RunnerOptions())
        self.config = config
        self.follower = follower
        self.leaders = tuple(leaders)
        self.start_time_s = float(start.time_s)
        self.training_end_s = self.parts.trainer.end_s
        self._r_var = config.r_m ** 2
        b, a = metric_scales_scalar(start.lat_rad, start.depth_m)
        s0 = State2(float(start.lat_rad), float(start.lon_rad),
                    (config.p0_m[0] / b) ** 2, 0.0, (config.p0_m[1] / a) ** 2)
        names = list(dict.fromkeys(config.methods))
        self._reported = tuple(names)
        self._entries = [method(n) for n in names]
        if any(e.detects for e in self._entries) and "ackf" not in names:
            self._entries.append(method("ackf"))    # the open-loop feature source for ROC curves
        running = config.running_threshold_gain > 0.0
        self._methods = [_Method(e.name, e.filter, s0, e.features or PAPER_FEATURES,
                                 running=running and e.calibrated) for e in self._entries]
        self._ackf = next((m for m in self._methods if m.kind == "ackf"), None)
        # the gated ACKF the lagged residual starts from (replay.stack.features); never reported
        self._reference: _Method | None = None
        if self.parts.features is not None and (config.features.drift_source == "lag"
                                                or "lag_residual_m" in config.hybrid_inputs):
            self._reference = _Method("reference", "reference", s0)
            self._methods.append(self._reference)
        self._reported_methods = [m for m in self._methods if m.name in self._reported]
        self._gate_f2 = chi_square_threshold(config.chi_square_alpha)
        self._t = self._t_dr = self.start_time_s
        self._depth = float(start.depth_m)
        self._last_dr: tuple[float, float, float] = (0.0, 0.0, 0.0)   # forward, lateral, heading
        self._updated: dict[tuple[State2, RangeInnovation, bool], State2] = {}   # this epoch's updates
        self._groups: list[list[_Method]] | None = None    # the methods by equal state (_propagate)
        self.rejected: Counter = Counter()
        self.clamped_ranges = 0
        self.position_fixes = 0
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
        self.parts.trainer.keep("dr", (t_s, forward_mps, lateral_mps, heading_rad, depth_m))
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
        geo = (float(leader_lat_rad), float(leader_lon_rad), float(leader_depth_m))
        reason = self._epoch_problem(t_s, leader, *geo, slant_range_m)
        if reason:
            self.rejected[reason] += 1
            return []
        self._maybe_train(t_s)
        if t_s > self._t:
            self._propagate(t_s)     # the last DR sample's velocities carry to the ranging instant
        z, clamped = slant_to_horizontal(slant_range_m, self._depth, geo[2])
        ep = Ranging(t_s, leader, z, geo, self._depth)
        innovations = self._innovations(ep)
        if innovations is None:
            self.rejected["degenerate_geometry"] += 1
            return []
        self.clamped_ranges += clamped
        self.parts.trainer.keep("range", (t_s, leader, *geo, slant_range_m, truth_range_m))
        truth = truth_range_m if math.isfinite(truth_range_m) else NAN
        label = label_one(z, truth, self.config.t1_m)
        extra = self._extra(ep, slant_range_m)
        out = [self._method_epoch(m, inn, ep, truth, label, extra) for m, inn in zip(self._methods, innovations)]
        self._groups = None     # the updates set states
        self._record()
        if t_s > self.training_end_s:
            self.parts.open_loop.add(out, extra)
        reported = [r for r in out if r.method in self._reported]
        self.parts.history.add_epochs(reported)
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
        self.parts.trainer.keep("fix", (t_s, lat_rad, lon_rad, nn, ne, ee))
        if t_s > self._t:
            self._propagate(t_s)
        b, a = metric_scales_scalar(lat_rad, self._depth)
        r11, r12, r22 = nn / (b * b), ne / (b * a), ee / (a * a)
        if self.parts.features is not None:
            self.parts.features.fix(t_s, lat_rad, lon_rad, (r11, r12, r22))
        for m in self._methods:
            if m.kind != "dr":
                m.state = position_update(m.state, lat_rad, lon_rad, r11, r12, r22) or m.state
        self._groups = None
        self.position_fixes += 1
        self._record()
        return True

    def finish(self) -> RunResults:
        """Collect epochs, tracks, open-loop scores and counters into a RunResults."""
        trainer, reported = self.parts.trainer, self._reported
        scored = [(m.name, m.features, m.detectors) for m in self._methods
                  if m.kind == "detect" and m.name in reported]
        training_set = trainer.training_set
        if training_set is not None and self.config.training_source == "own":
            # its own normal epochs after t_a go with it: a run trained on it calibrates thresholds on them
            training_set = training_set.with_calibration(self.parts.open_loop.normal_features())
        return RunResults(
            methods=reported, leaders=self.leaders, start_time_s=self.start_time_s,
            training_end_s=self.training_end_s, epochs=self.parts.history.epochs(),
            tracks=self.parts.history.tracks([m.name for m in self._methods], reported),
            open_loop=self.parts.open_loop.scores(scored), rejected=dict(self.rejected),
            capped={m.name: self.parts.isolation.capped[m.name] for m in self._methods if m.name in reported},
            clamped_ranges=self.clamped_ranges, trained=trainer.trained,
            training_errors=dict(trainer.errors), position_fixes=self.position_fixes,
            training_set=training_set, thresholds=copy.deepcopy(trainer.thresholds),
            training_notes=dict(trainer.notes),
        )

    @property
    def trained(self) -> bool:
        """True once the detectors were trained (first sample after t_a)."""
        return self.parts.trainer.trained

    @property
    def training_errors(self) -> dict[str, str]:
        """Why a detector could not be trained, by "method/leader" (or "method/all")."""
        return self.parts.trainer.errors

    def estimates(self) -> dict[str, tuple[float, float, float, float, float]]:
        """Each reported method's current estimate: lat, lon (rad), covariance nn, ne, ee (m²)."""
        out: dict[str, tuple[float, float, float, float, float]] = {}
        made: dict[int, tuple[float, float, float, float, float]] = {}   # methods of one state share its tuple
        for m in self._reported_methods:
            s = m.state
            value = made.get(id(s))
            if value is None:
                value = made[id(s)] = (s.lat, s.lon, *_cov_m2(s, self._depth))
            out[m.name] = value
        return out

    def positions(self) -> dict[str, tuple[float, float]]:
        """Each reported method's current lat, lon (rad): `estimates` without the covariances."""
        return {m.name: (m.state.lat, m.state.lon) for m in self._reported_methods}

    def reported_states(self) -> list[State2]:
        """Each reported method's current state, in the order of `reported_names` (`positions` without a dict)."""
        return [m.state for m in self._reported_methods]

    @property
    def reported_names(self) -> tuple[str, ...]:
        """The reported methods in the order of `reported_states` (and of `positions`)."""
        return tuple(m.name for m in self._reported_methods)

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

    def _innovations(self, ep: Ranging) -> list[RangeInnovation] | None:
        """Each method's innovation of the range (one per distinct state, see _propagate); None if one has none."""
        seen: dict[State2, RangeInnovation | None] = {}
        innovations = []
        for m in self._methods:
            if m.state not in seen:
                seen[m.state] = range_innovation(m.state, ep.z, ep.geo, ep.depth_m, self._r_var)
            innovations.append(seen[m.state])
        self._updated.clear()
        usable = [inn for inn in innovations if inn is not None]
        return usable if len(usable) == len(innovations) else None

    def _extra(self, ep: Ranging, slant_m: float) -> tuple[float, ...]:
        """The epoch's filter-independent features (EXTRA_FEATURES; NaN without a feature tracker)."""
        if self.parts.features is None:
            return _NO_EXTRA
        ref_m = self._reference
        ref = (ref_m.state.lat, ref_m.state.lon) if ref_m is not None else None
        return self.parts.features.epoch(ep.t_s, ep.leader, slant_m, ep.z, ep.depth_m, ep.geo, ref)

    def _propagate(self, t_s: float) -> None:
        """Time update of every method from the current time to t_s with the last DR sample."""
        dt = t_s - self._t
        fwd, lat_v, hdg = self._last_dr
        # methods whose filters have not diverged (every ACKF inside the training window, a detector
        # that has not isolated yet) hold equal states: each distinct state is predicted once. The groups
        # stay until an update sets states (range_epoch, position_fix): a prediction depends on values only
        groups = self._groups if self._groups is not None else self._group_states()
        north, east = dr_displacement(dt, fwd, lat_v, hdg)
        moved = dr_predict_moved([g[0].state for g in groups], dt, north, east, self._depth, self.config.q_m_per_s)
        for g, nxt in zip(groups, moved):
            for m in g:
                m.state = nxt
        if self.parts.features is not None:
            # the age of the DR sample carried: beyond a few seconds the DVL has lost bottom lock (model)
            self.parts.features.propagate(dt, fwd, lat_v, hdg, self._depth, t_s - self._t_dr)
        self._t = t_s

    def _group_states(self) -> list[list[_Method]]:
        """The methods by equal state, in method order (each group's first member first)."""
        by_state: dict[State2, list[_Method]] = {}
        for m in self._methods:
            by_state.setdefault(m.state, []).append(m)
        self._groups = list(by_state.values())
        return self._groups

    def _record(self) -> None:
        """Remember every method's estimate at the current time for the tracks."""
        if self.parts.history.keep:
            self.parts.history.record(self._t, self._depth, [m.state for m in self._methods])

    def _method_epoch(self, m: _Method, inn: RangeInnovation, ep: Ranging, truth: float, label: int,
                      extra: tuple[float, ...] = _NO_EXTRA) -> EpochResult:
        """Apply one method's update rule to the epoch and describe the outcome.

        Paper A's detectors decide on (f1, f2, f3); the new ones on the
        columns of their method-table entry's ``features``.
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
            action = self.parts.isolation.gate(m.name, ep.leader, gate, self.config.features.reference_cap)
        elif m is self._ackf and ep.t_s <= self.training_end_s and label != UNKNOWN:
            self.parts.trainer.rows.append((ep.t_s, ep.leader, f1, f2, f3, *extra, ep.z - truth, label))
        elif m.kind == "detect" and ep.t_s > self.training_end_s and (det := m.detectors.get(ep.leader)) is not None:
            decision = det.decide(_columns(m, f1, f2, f3, extra))
            if m.running:       # the closed-loop decision only: open-loop scores are the detector's own
                if m.threshold is None:
                    m.threshold = RunningThreshold.for_detector(self.config, float(getattr(det, "threshold", NAN)))
                decision = m.threshold.decide(decision)
            if decision.flagged:
                det.reset()
            action, used_inn, compensated = self.parts.isolation.act(m.name, m.state, decision, inn, ep)
        if action in ("update", "capped"):
            key = (m.state, used_inn, m.kind != "ckf")
            nxt = self._updated.get(key)
            if nxt is None:
                nxt = self._updated[key] = range_update(m.state, used_inn, self._r_var, adaptive=m.kind != "ckf")
            m.state = nxt
        nn, ne, ee = _cov_m2(m.state, self._depth)
        return EpochResult(
            ep.t_s, ep.leader, m.name, decision.flagged, decision.score, decision.threshold, f1, f2, f3, label,
            action == "isolate", action == "capped", compensated, ep.z - decision.correction_m * compensated,
            inn.z_hat, m.state.lat, m.state.lon, nn, ne, ee, truth, *extra)

    def _maybe_train(self, t_s: float) -> None:
        """Train every detector once, at the first sample after t_a (see replay.stack.training_window)."""
        if not self.parts.trainer.due(t_s):
            return
        trained = self.parts.trainer.train(self._entries)
        for m in self._methods:
            if m.name in trained:
                m.detectors = trained[m.name]
