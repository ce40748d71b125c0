"""The replay engine: an archive streamed in time order through every method, side by side.

Push-style core (`Engine.push(message)`), with `replay_archive` as the thin
loop over an archive. Per follower a `FollowerPipeline` drives the stack's
`CooperativeRunner`; USBL observations go through KMCDF. What cannot run is
said once per cause (`Engine.notes`), never raised.
"""

from __future__ import annotations

import dataclasses
import math
import time
from array import array
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from formats.mcap_blocks import MessageBlock
from formats.units import NS
from replay.engine.blocks import push_block
from replay.engine.config import RunConfig
from replay.engine.follower import FollowerPipeline, VehicleTracks
from replay.engine.layout import TrialLayout
from replay.engine.tracks import Horizon
from replay.engine.usbl import positioning
from replay.engine.usbl.epochs import UsblEpochBuilder
from replay.events import EpochResult, ErrorSample, Fix, FollowerScores, Listener, RunResults, RunScores, UsblEpoch
from replay.stack.methods import INPUTS, method, method_names
from replay.stack.model import horizontal_offset_m, offset_to_latlon
from replay.stack.positioning.kmcdf import KmcdfParams
from replay.stack.training import TrainingSet

DEG = math.pi / 180.0


class Engine:
    """Streams one trial's messages through the stack (push one message at a time, in time order)."""

    def __init__(self, layout: TrialLayout, config: RunConfig, t0_ns: int, listeners: Sequence[Listener] = (),
                 training_set: TrainingSet | None = None):
        """The engine of one trial; `training_set` (another run's) goes to every follower's runner."""
        self.layout, self.config, self.t0_ns = layout, config, t0_ns
        # a tuple: the hook lists below are taken once, so a listener appended later would miss them
        self.listeners: tuple[Listener, ...] = tuple(listeners)
        # the per-message hooks go only to the listeners that override them (Listener's own do nothing):
        # a results writer, which ignores positions, then costs nothing per INS or GPS message
        self._hear_position = _overriding(self.listeners, "position")
        self._hear_estimates = _overriding(self.listeners, "estimates")
        self._hear_errors = _overriding(self.listeners, "errors")
        # a block's positions go to the listeners that hear positions one by one or as columns
        self._hear_positions = [lis for lis in self.listeners
                                if lis in self._hear_position or lis in _overriding(self.listeners, "positions")]
        self.notes: list[str] = list(layout.notes)
        self.counts: Counter = Counter()
        self.tracks: dict[str, VehicleTracks] = {v: VehicleTracks() for v in layout.roles}
        self.horizon = Horizon()      # how far a block's rows in the tracks are visible (push_block)
        for vt in self.tracks.values():
            vt.gps.horizon = vt.ins.horizon = self.horizon
        self.training_end_s = config.stack.training_window_s
        self.followers: dict[str, FollowerPipeline] = {}
        self._scores: dict[str, FollowerScores] = {}
        for plan in layout.followers:
            self.notes.extend(plan.notes)
            if plan.runnable:
                # each follower runs the configured methods whose inputs it holds (the layout's plan)
                own = dataclasses.replace(config, stack=dataclasses.replace(config.stack, methods=plan.methods))
                self.followers[plan.name] = FollowerPipeline(plan, own, self.tracks, self._on_epoch,
                                                             self._on_estimates, self._on_errors, training_set)
                self._scores[plan.name] = FollowerScores()
        self._trained: set[str] = set()
        self._usbl: UsblEpochBuilder | None = None
        self._origin: tuple[float, float] | None = None
        self._has_gps = any(layout.has(v, "gps") for v in layout.roles)   # the origin: the first GPS fix
        self.usbl_epochs = 0
        self.positioning_errors: dict[str, array] = {m: array("d") for m in method_names("positioning")}
        self.messages = 0
        self.last_s = -math.inf
        self._routes: dict[str, tuple[str | None, Callable[[Engine, str, float, Any], None] | None]] = {}
        self._lag_s = config.engine.lag_s
        self._feeding = bool(config.engine.usbl_update)     # USBL fixes go to the followers' filters
        self._pipes = list(self.followers.items())
        self._pipes_only = [pipe for _, pipe in self._pipes]

    # -- intake ----------------------------------------------------------------
    def push(self, topic: str, log_time_ns: int, msg: Any) -> None:
        """Feed one archive message (log time order)."""
        self.messages += 1
        t_s = (log_time_ns - self.t0_ns) / NS
        if t_s < self.last_s:
            self.counts["out_of_order_messages"] += 1
        else:
            self.last_s = t_s
        route = self._routes.get(topic)
        if route is None:
            route = self._routes[topic] = self._route(topic)
        vehicle, handler = route
        if handler is None or vehicle is None:     # a handled topic always has its vehicle
            if vehicle is None and topic == "/diagnostics":
                for listener in self.listeners:
                    listener.event(t_s, "WARN", f"rejected record: {msg.message}")
            return
        handler(self, vehicle, t_s, msg)
        self._release(self.last_s - self._lag_s)

    def push_block(self, block: MessageBlock) -> None:
        """Feed a block of messages (log time order) with its INS, DVL and GPS topics as columns: what `push`
        would do message by message, with numpy (replay.engine.blocks)."""
        push_block(self, block)

    def _route(self, topic: str) -> tuple[str | None, Callable[[Engine, str, float, Any], None] | None]:
        """(vehicle, handler) of a topic, parsed once per topic: (None, None) for one to skip."""
        if topic == "/diagnostics":
            return None, None
        parts = topic.strip("/").split("/")
        vehicle, sensor = parts[0], "/".join(parts[1:])
        if topic in self.layout.sources:      # another position source: drawn and scored, not fed to the stack
            return vehicle, lambda engine, v, t_s, msg: engine._source(v, sensor, t_s, msg)
        if vehicle not in self.tracks:
            return None, None
        return vehicle, _HANDLERS.get(sensor)

    def _source(self, vehicle: str, source: str, t_s: float, msg: Any) -> None:
        """A position of another source (an INS of its own, a local x/y on an origin, a node report)."""
        if not (math.isfinite(msg.latitude) and math.isfinite(msg.longitude)):
            return
        depth = getattr(msg, "depth_m", 0.0)
        fix = Fix(t_s, msg.latitude * DEG, msg.longitude * DEG, depth if math.isfinite(depth) else 0.0)
        self._first_position(fix)
        for listener in self._hear_position:
            listener.position(vehicle, source, fix)

    def _first_position(self, fix: Fix) -> None:
        """The local frame's origin from the first position of any kind, in a trial without GPS."""
        if self._origin is None and not self._has_gps:
            self._set_origin(fix.lat_rad, fix.lon_rad)

    def _set_origin(self, lat_rad: float, lon_rad: float) -> None:
        """The local frame's origin, said to every listener."""
        self._origin = (lat_rad, lon_rad)
        for listener in self.listeners:
            listener.origin(lat_rad, lon_rad)

    def _gps(self, vehicle: str, t_s: float, msg: Any) -> None:
        if not (math.isfinite(msg.latitude) and math.isfinite(msg.longitude)):
            self.counts["gps_without_position"] += 1
            return
        fix = Fix(t_s, msg.latitude * DEG, msg.longitude * DEG, 0.0)
        self.tracks[vehicle].gps.add(fix)
        for listener in self._hear_position:
            listener.position(vehicle, "gps", fix)
        if self._origin is None:
            self._set_origin(fix.lat_rad, fix.lon_rad)
        if vehicle in self.followers:
            self.followers[vehicle].on_gps(t_s, fix)

    def _ins(self, vehicle: str, t_s: float, msg: Any) -> None:
        if math.isfinite(msg.latitude) and math.isfinite(msg.longitude):
            depth = msg.depth_m if math.isfinite(msg.depth_m) else 0.0
            fix = Fix(t_s, msg.latitude * DEG, msg.longitude * DEG, depth)
            self._first_position(fix)
            self.tracks[vehicle].ins.add(fix)
            for listener in self._hear_position:
                listener.position(vehicle, "ins", fix)
        if vehicle in self.followers:
            self.followers[vehicle].on_ins(t_s, msg)

    def _dvl(self, vehicle: str, t_s: float, msg: Any) -> None:
        if vehicle in self.followers:
            self.followers[vehicle].on_dvl(t_s, msg)

    def _range(self, vehicle: str, t_s: float, msg: Any) -> None:
        if vehicle in self.followers:
            self.followers[vehicle].on_range(t_s, msg)
        else:
            self.counts["range_logged_by_non_follower"] += 1

    def _usbl_obs(self, vehicle: str, t_s: float, msg: Any) -> None:
        if not self.config.engine.kmcdf:
            return
        if self._usbl is None:
            if self._origin is None:
                self.counts["usbl_before_any_gps"] += 1
                return
            e = self.config.engine
            params = KmcdfParams(rho_m=e.kmcdf_rho_m, sigma_phase_rad=e.kmcdf_phase_noise_rad)
            self._usbl = UsblEpochBuilder(self.tracks, self._origin, e.usbl_group_s, params, e.node_max_gap_s,
                                          self._on_usbl_batch, self._usbl_truth)
        self._usbl.add(t_s, msg)

    # -- release and callbacks ---------------------------------------------------
    def _release(self, until_s: float) -> None:
        usbl = self._usbl
        if usbl is not None and self._feeding:
            # fixes go to the followers' queues before they are released past them; an epoch is
            # complete once the stream is usbl_group_s past its first observation
            usbl.flush(min(until_s, self.last_s - self.config.engine.usbl_group_s))
            usbl.position_due(until_s)
        for name, pipe in self._pipes:
            # most messages release nothing; training only happens while events are released
            if pipe.due(until_s):
                pipe.release(until_s)
                self._check_trained(name, pipe)
        if usbl is not None and not self._feeding:
            usbl.flush(until_s - 1.0)

    def _check_trained(self, name: str, pipe: FollowerPipeline) -> None:
        runner = pipe.runner
        if runner is not None and name not in self._trained and getattr(runner, "trained", False):
            self._trained.add(name)
            if not any(method(m).detects for m in pipe.plan.methods):
                return      # nothing was trained: no detector among the methods this follower runs
            for listener in self.listeners:
                listener.event(runner.training_end_s, "INFO", f"{name}: detectors trained at t_a = "
                               f"{runner.training_end_s:.0f} s" + "".join(
                                   f"; {k}: {v}" for k, v in runner.training_errors.items()))
            for listener in self.listeners:
                listener.trained(name, runner, runner.training_end_s)

    def _on_epoch(self, follower: str, results: list[EpochResult], leader_fix: Fix) -> None:
        # the runner trains inside the release that delivers its first epoch past t_a: say so before that epoch
        self._check_trained(follower, self.followers[follower])
        sc = self._scores[follower]
        t = results[0].time_s
        if t > self.training_end_s:
            label = results[0].label
            if label >= 0:
                sc.epochs += 1
                sc.anomalous += label == 1
            for r in results:
                if r.label >= 0:
                    sc.flagged.setdefault(r.method, array("b")).append(bool(r.flagged))
                    sc.labels.setdefault(r.method, array("b")).append(int(r.label))
        # the leader's position the follower ranged against at t (VehicleTracks.position), not looked up again
        for listener in self.listeners:
            listener.epoch(follower, results, leader_fix)

    def _on_estimates(self, follower: str, t_s: float, est: Mapping[str, tuple[float, ...]]) -> None:
        for listener in self._hear_estimates:
            listener.estimates(follower, t_s, est)

    def _on_errors(self, follower: str, samples: list[ErrorSample]) -> None:
        sc = self._scores[follower]
        for s in samples:
            if s.t_s >= self.training_end_s:
                sc.errors.setdefault(s.method, array("d")).append(s.error_m)
        for listener in self._hear_errors:
            listener.errors(follower, samples)

    def _usbl_truth(self, target: str, t_s: float) -> tuple[float, float] | None:
        """The target's GPS east/north at an epoch, read when the epoch closes (tracks keep recent fixes only)."""
        truth = self.tracks.get(target)
        fix = truth.gps.at(t_s, self.config.engine.max_gap_s) if truth is not None else None
        if fix is None or self._origin is None:
            return None
        n, e = horizontal_offset_m(fix.lat_rad, fix.lon_rad, *self._origin)
        return float(e), float(n)

    def _on_usbl_batch(self, epochs: list[UsblEpoch], truths: list[tuple[float, float] | None]) -> None:
        for epoch, truth, positions in zip(epochs, truths, positioning.positions_for_epochs(epochs)):
            self._on_usbl(epoch, truth, positions)

    def _on_usbl(self, epoch: UsblEpoch, truth: tuple[float, float] | None,
                 positions: dict[str, tuple[float, float]]) -> None:
        self.usbl_epochs += 1
        samples: list[ErrorSample] = []
        if truth is not None:
            e, n = truth
            samples = [ErrorSample(epoch.t_s, method, math.hypot(pe - float(e), pn - float(n)))
                       for method, (pe, pn) in positions.items() if math.isfinite(pe) and math.isfinite(pn)]
        if epoch.t_s >= self.training_end_s:   # every method is scored on one window
            for s in samples:
                self.positioning_errors[s.method].append(s.error_m)
        self._feed_fix(epoch, positions)
        for listener in self.listeners:
            listener.usbl(epoch, positions)
            if samples:     # the positioning methods' error series, beside the filters' (views, report)
                listener.errors(epoch.target, samples)

    def _feed_fix(self, epoch: UsblEpoch, positions: dict[str, tuple[float, float]]) -> None:
        """With engine.usbl_update set, the chosen method's fix of a follower goes to its filters."""
        method = self.config.engine.usbl_update
        pipe = self.followers.get(epoch.target) if method else None
        if pipe is None or self._origin is None:
            return
        e, n = positions.get(method, (math.nan, math.nan))
        if not (math.isfinite(e) and math.isfinite(n)):
            self.counts["usbl_fixes_undetermined"] += 1
            return
        cov = epoch.fix.covariance if method == "kmcdf2" else None
        if cov is not None and np.all(np.isfinite(cov)):
            nn, ne, ee = float(cov[1, 1]), float(cov[0, 1]), float(cov[0, 0])   # fix covariance is east, north
        else:
            nn = ee = self.config.engine.usbl_update_sigma_m ** 2
            ne = 0.0
        lat, lon = offset_to_latlon(n, e, *self._origin)
        pipe.on_position_fix(epoch.t_s, lat, lon, nn, ne, ee)
        self.counts["usbl_fixes_to_filters"] += 1

    # -- end ---------------------------------------------------------------------
    def finish(self) -> dict[str, RunResults]:
        """Release everything, finish every runner; returns their RunResults by follower."""
        out = {}
        if self._usbl is not None and self.config.engine.usbl_update:
            self._usbl.flush()     # the last fixes reach the followers before their queues empty
        for name, pipe in self.followers.items():
            pipe.finish()
            self._check_trained(name, pipe)
            if pipe.runner is None:
                self.notes.append(f"follower {name}: never started (no position fix to start from)")
                continue
            out[name] = pipe.runner.finish()
            for listener in self.listeners:
                listener.finished(name, out[name])
        if self._usbl is not None:
            self._usbl.flush()
            self.counts.update(self._usbl.counts)
        return out

    def scores(self) -> RunScores:
        """What the metrics need of the run so far: per-follower scores after t_a, positioning errors, notes."""
        counts = {**dict(self.counts), **{f"{f}:{k}": v for f, p in self.followers.items()
                                          for k, v in p.counts.items()}}
        ran = tuple(m for m in self.config.stack.methods if m not in self.layout.skipped)
        return RunScores(ran, self.training_end_s, dict(self._scores),
                         dict(self.positioning_errors), self.usbl_epochs, list(self.notes), counts, self.skipped())

    def skipped(self) -> dict[str, str]:
        """Every method this trial could not run, with the input it lacked (the layout's, and USBL positioning)."""
        out = dict(self.layout.skipped)
        if self.config.engine.kmcdf and not any(self.layout.has(b, "usbl") for b in self.layout.by_role("buoy")):
            out.update({m: f"needs {INPUTS['usbl']}" for m in method_names("positioning")})
        return out

    @property
    def origin(self) -> tuple[float, float] | None:
        """The local frame's origin (lat, lon rad): the first GPS fix of the trial."""
        return self._origin


def _overriding(listeners: Sequence[Listener], hook: str) -> list[Listener]:
    """The listeners whose class overrides Listener's (empty) `hook`, in their order."""
    base = getattr(Listener, hook)
    return [listener for listener in listeners if getattr(type(listener), hook, base) is not base]


_HANDLERS: dict[str, Callable[[Engine, str, float, Any], None]] = {
    "gps": Engine._gps,
    "ins": Engine._ins,
    "dvl": Engine._dvl,
    "modem/range": Engine._range,
    "usbl": Engine._usbl_obs,
}


def pace(rate: float, t0_wall: float, t_s: float) -> None:
    """Sleep so that trial time t_s is reached at rate x wall time (rate 0: never sleep)."""
    if rate > 0:
        ahead = t_s / rate - (time.monotonic() - t0_wall)
        if ahead > 0:
            time.sleep(ahead)
