"""One follower's pipeline: archive messages in, DR samples and range epochs to the stack runner.

Events are queued and released `lag_s` behind the stream, so that a range
epoch can use the ranged leader's position interpolated at the ranging time
(from its INS, else its GPS) and the GPS truth on both sides of it. The
queue holds only those few seconds, so memory does not grow with the trial.
"""

from __future__ import annotations

import heapq
import math
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from replay.engine.config import RunConfig
from replay.engine.layout import FollowerPlan
from replay.engine.tracks import Track
from replay.events import EpochResult, ErrorSample, Fix
from replay.stack.filters.ckf import State2
from replay.stack.model import horizontal_distance_scalar
from replay.stack.runner import CooperativeRunner, RunnerOptions, Start
from replay.stack.training import TrainingSet

DEG = math.pi / 180.0
# ErrorSample(...) without the NamedTuple's Python-level __new__: one per method at every follower GPS fix
_new_tuple = tuple.__new__
BODY_FRD, EARTH_NED = 1, 2  # auvreplay.DvlVelocity.Frame


@dataclass
class VehicleTracks:
    """Recent GPS and INS positions of one vehicle."""

    gps: Track = field(default_factory=lambda: Track(keep_s=120.0))
    ins: Track = field(default_factory=lambda: Track(keep_s=120.0))

    def position(self, t_s: float, max_gap_s: float) -> Fix | None:
        """Position at t from the INS if it covers t, else from GPS."""
        return self.ins.at(t_s, max_gap_s) or self.gps.at(t_s, max_gap_s)


class FollowerPipeline:
    """Queues one follower's samples and drives its CooperativeRunner in time order."""

    def __init__(self, plan: FollowerPlan, config: RunConfig, tracks: dict[str, VehicleTracks],
                 on_epoch: Callable[[str, list[EpochResult], Fix], None],
                 on_estimates: Callable[[str, float, Mapping[str, tuple[float, ...]]], None],
                 on_error: Callable[[str, list[ErrorSample]], None], training_set: TrainingSet | None = None):
        """One follower's queue; `training_set` is handed to its runner (StackConfig.training_source).

        `on_epoch` hears each epoch's results with the ranged leader's position the epoch used.
        """
        self.plan, self.config, self.tracks = plan, config, tracks
        self.training_set = training_set
        self.on_epoch, self.on_estimates, self.on_error = on_epoch, on_estimates, on_error
        self.runner: CooperativeRunner | None = None
        self.counts: Counter = Counter()
        self._queue: list[tuple[float, int, str, tuple[Any, ...]]] = []
        self._seq = 0
        self._heading: tuple[float, float] | None = None   # (t_s, heading deg)
        self._depth = 0.0
        self._prev: tuple[float, list[State2]] | None = None      # the last step's time and states
        self._pending_gps: list[Fix] = []
        self._last_output_s = -math.inf

    # -- intake ----------------------------------------------------------------
    def push_event(self, t_s: float, kind: str, payload: tuple[Any, ...]) -> None:
        """Queue one event ("dr", "range", "fix" or "gps") for release in time order."""
        self._push(t_s, kind, payload)

    def queue_head_s(self) -> float:
        """The time of the earliest queued event (inf when none)."""
        return self._queue[0][0] if self._queue else math.inf

    def first_epoch_s(self) -> float:
        """The time of the earliest queued range or position fix (inf when none): the events that read tracks."""
        return min((ev[0] for ev in self._queue if ev[2] == "range" or ev[2] == "fix"), default=math.inf)

    def _push(self, t_s: float, kind: str, payload: tuple[Any, ...]) -> None:
        self._seq += 1
        heapq.heappush(self._queue, (t_s, self._seq, kind, payload))

    def on_ins(self, t_s: float, msg: Any) -> None:
        """Follower INS: remember heading and depth for the DVL samples that follow."""
        if math.isfinite(msg.heading_deg):
            self._heading = (t_s, msg.heading_deg)
        if math.isfinite(msg.depth_m):
            self._depth = msg.depth_m

    def on_dvl(self, t_s: float, msg: Any) -> None:
        """A DVL sample becomes a DR event (body-frame forward/lateral speed, heading, depth)."""
        payload = self.dr_payload(t_s, msg.valid, msg.velocity_x_mps, msg.velocity_y_mps, msg.frame, self._heading,
                                  self._depth)
        if payload is not None:
            self._push(t_s, "dr", payload)

    def dr_payload(self, t_s: float, valid: Any, vx: float, vy: float, frame: Any,
                   last_heading: tuple[float, float] | None, depth: float
                   ) -> tuple[float, float, float, float] | None:
        """A DVL sample's DR event (forward, lateral, heading rad, depth) with the INS heading and depth before it;
        None (counted) when it cannot be used. The rule of `on_dvl`, for a block's columns too."""
        if not valid or not (math.isfinite(vx) and math.isfinite(vy)):
            self.counts["dvl_invalid"] += 1
            return None
        last = last_heading
        heading = last[1] if last is not None and t_s - last[0] <= self.config.engine.max_gap_s else None
        if frame == EARTH_NED:
            theta = heading * DEG if heading is not None else 0.0
            vn, ve = vx, vy
            fwd, lat = vn * math.cos(theta) + ve * math.sin(theta), -vn * math.sin(theta) + ve * math.cos(theta)
        elif frame == BODY_FRD:
            if heading is None:
                self.counts["dvl_without_heading"] += 1
                return None
            theta, fwd, lat = heading * DEG, vx, vy
        else:
            self.counts["dvl_frame_unusable"] += 1
            return None
        return (fwd, lat, theta, depth)

    def on_range(self, t_s: float, msg: Any) -> None:
        """An acoustic range from a leader becomes a range event."""
        if msg.source not in self.plan.leaders:
            self.counts["range_from_unknown_leader"] += 1
            return
        slant = msg.range_m
        if not math.isfinite(slant) and math.isfinite(msg.travel_time_s):
            speed = msg.sound_speed_mps if math.isfinite(msg.sound_speed_mps) and msg.sound_speed_mps > 0 else 1500.0
            slant = msg.travel_time_s * speed
        self._push(t_s, "range", (msg.source, slant))

    def on_position_fix(self, t_s: float, lat_rad: float, lon_rad: float, cov_nn_m2: float, cov_ne_m2: float,
                        cov_ee_m2: float) -> None:
        """A position fix of this follower (a USBL epoch's fix) becomes a position-update event."""
        self._push(t_s, "fix", (lat_rad, lon_rad, cov_nn_m2, cov_ne_m2, cov_ee_m2))

    def on_gps(self, t_s: float, fix: Fix) -> None:
        """A follower GPS fix: the reference for position errors."""
        self._push(t_s, "gps", (fix,))

    # -- release ---------------------------------------------------------------
    def due(self, until_s: float) -> bool:
        """True when `release(until_s)` would process an event."""
        return bool(self._queue) and self._queue[0][0] <= until_s

    def release(self, until_s: float) -> None:
        """Process every queued event with time <= until_s, in time order."""
        while self._queue and self._queue[0][0] <= until_s:
            t_s, _, kind, payload = heapq.heappop(self._queue)
            if kind == "gps":
                self._pending_gps.append(payload[0])
                continue
            runner = self.runner if self.runner is not None else self._start(t_s)
            if runner is None:
                self.counts[f"{kind}_before_initial_fix"] += 1
                continue
            if kind == "dr":
                if runner.dead_reckon(t_s, *payload):
                    self._after_step(runner, t_s)
            elif kind == "fix":
                if runner.position_fix(t_s, *payload):
                    self._after_step(runner, t_s, force=True)
            else:
                self._range(runner, t_s, *payload)

    def _start(self, t_s: float) -> CooperativeRunner | None:
        """The runner, started at the follower's own position at t; None while it has none."""
        own = self.tracks[self.plan.name]
        fix = own.gps.at(t_s, self.config.engine.max_gap_s) or own.ins.at(t_s, self.config.engine.max_gap_s)
        if fix is None:
            return None
        self.runner = CooperativeRunner(
            self.config.stack, self.plan.name, self.plan.leaders, Start(0.0, fix.lat_rad, fix.lon_rad, self._depth),
            RunnerOptions(keep_history=False, training_set=self.training_set))
        self._prev = (0.0, self.runner.reported_states())
        return self.runner

    def _range(self, runner: CooperativeRunner, t_s: float, leader: str, slant_m: float) -> None:
        gap = self.config.engine.max_gap_s
        pos = self.tracks[leader].position(t_s, gap)
        if pos is None:
            self.counts["range_without_leader_position"] += 1
            return
        truth = math.nan
        own, other = self.tracks[self.plan.name].gps.at(t_s, gap), self.tracks[leader].gps.at(t_s, gap)
        if own is not None and other is not None:
            truth = horizontal_distance_scalar(own.lat_rad, own.lon_rad, other.lat_rad, other.lon_rad)
        results = runner.range_epoch(t_s, leader, pos.lat_rad, pos.lon_rad, pos.depth_m, slant_m, truth)
        if results:
            self.on_epoch(self.plan.name, results, pos)
            self._after_step(runner, t_s, force=True)

    def _after_step(self, runner: CooperativeRunner, t_s: float, force: bool = False) -> None:
        """Errors at GPS fixes between the last two estimates; estimates out at most once a second."""
        now = runner.reported_states()      # per DR sample: states, not a dict of positions
        if self._pending_gps:
            prev_t, prev = self._prev if self._prev is not None else (t_s, now)
            names = runner.reported_names
            samples: list[ErrorSample] = []
            keep: list[Fix] = []
            for fix in self._pending_gps:
                if fix.t_s > t_s:
                    keep.append(fix)
                    continue
                if fix.t_s < prev_t:
                    continue  # before the runner started
                w = 0.0 if t_s == prev_t else (fix.t_s - prev_t) / (t_s - prev_t)
                for method, est, p in zip(names, now, prev):
                    lat = p[0] + w * (est[0] - p[0])
                    lon = p[1] + w * (est[1] - p[1])
                    samples.append(_new_tuple(ErrorSample, (
                        fix.t_s, method, horizontal_distance_scalar(lat, lon, fix.lat_rad, fix.lon_rad))))
            self._pending_gps = keep
            if samples:
                self.on_error(self.plan.name, samples)
        self._prev = (t_s, now)
        if force or t_s - self._last_output_s >= 1.0:
            self._last_output_s = t_s
            self.on_estimates(self.plan.name, t_s, runner.estimates())

    def finish(self) -> None:
        """Release everything still queued."""
        self.release(math.inf)
