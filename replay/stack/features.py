"""Range-epoch features that do not depend on a filter following the anomaly (issue 16).

Paper A's features (f1, f2, f3) come from the ACKF's innovation; for a scalar
range they are one statistic (f3 = R·max(1, f2), f1 = sqrt(f2·P_zz)) and the
ACKF follows a slow drift, so none of them sees it. These do not involve the
filter, and are the same for every method of a run:

- ``repeat_count``: consecutive identical slant ranges from this leader
  (a stale modem repeats its last value);
- ``dr_residual_m``: the range minus the range predicted from pure dead
  reckoning, relative to its median over the leader's last
  ``median_window_s`` (60 s) of epochs (DR error wanders slowly; the median
  takes it out, an anomaly stands out of it);
- ``leader_consistency_m``: this leader's ``dr_residual_m`` minus the mean
  of the other leaders' latest ones (within the window): a fault on one
  acoustic link shows on it alone, a DR error on every link;
- ``usbl_residual_m``: the range minus the range from the USBL-anchored
  position (the last USBL fixes of the follower, blended, carried forward by
  dead reckoning), NaN without a fix younger than ``usbl_max_age_s``;
- ``lag_residual_m``: the range minus the range from the reference
  filter's estimate of ``lag_s`` (60 s) ago carried forward by the
  dead-reckoned displacement since (NaN for the first lag, and always NaN
  unless ``drift_source`` is "lag" or anfis_hybrid takes it). The reference
  is an ACKF run by the runner beside the methods, which leaves out epochs
  with a repeated range, f2 above the chi-square gate or
  |lag_residual_m| above ``reference_gate_m`` (capped at
  ``reference_cap`` consecutive epochs per leader): it follows a slow
  drift only until the drift passes the gate, and the estimate of a minute
  ago has not absorbed a drift younger than that. Over a minute dead
  reckoning drifts only metres, where its absolute error over the mission
  reaches tens of metres and rotates with the geometry (which is what
  makes ``dr_residual_m`` wander about ±10 m per 100 s);
- ``exclusion_residual_m``: the range minus the range predicted by the
  ACKF that uses dead reckoning and only the OTHER leaders' ranges
  (replay.stack.exclusion; NaN with one leader or without the filters,
  which run only when ``drift_source`` is "exclusion" or anfis_hybrid takes
  an exclusion input: on held-out seeds they did not beat the lag residual);
- ``drift_residual_m``: with ``FeatureConfig.drift_source`` "model" (the
  default) the range against the DR error model of ``lag_s`` ago carried
  forward (`replay.stack.dr_error_model`: DR error, heading error and DVL
  scale error, fed the USBL fixes too; its current innovation for the
  first ``lag_s`` and while a USBL fix younger than ``lag_s`` exists,
  since fixes keep the filter off a drift; the share k·r of its range-scale
  state, an error of the range against the truth, included); with "stiff" the innovation of the `StiffReference` (a
  2-D random walk of the DR error, the default before 95521e9, which takes the
  USBL fixes too); otherwise ``usbl_residual_m`` where finite, else
  ``exclusion_residual_m`` or ``lag_residual_m`` (``drift_source``), else
  ``dr_residual_m``. What the drift CUSUM sums and ``drift_reference`` tests;
- ``drift_z``: the drift residual standardized by the mission's own recent
  past. With ``scale_by_model`` (the default, drift source "model") x is
  first scaled to the range noise by the model's predicted sigma,
  x·r / sqrt(var), so what the model says widens the residual (a held DR
  step without bottom lock) raises no alarm by itself (issue 26:
  docs/detection.md section 5); then
  (x - median) / max(1.4826 MAD, ``scale_floor_m``) over the drift
  residuals of EVERY leader (``scale_pooled``, the default) of the last
  ``scale_pooled_window_s`` (900 s) that are older than ``lag_s`` (60 s)
  and not from a repeated range, NaN with fewer than ``scale_min_samples``
  of them. The reference is one filter of the follower's DR error, so
  its residual's spread is the mission's, not a leader's: pooled, the stale
  ranges of one leader do not inflate it (a per-leader scale did, and halved
  drift_reference's recall on the stiff reference). Old enough not to hold
  a young drift; long, because over seeds 0-19 a longer pool separated
  drift from normal better (stiff reference: drift recall at 0.3 m/s at
  2 % FPR 0.47, 0.61, 0.75 for 300, 600, 900 s). With ``scale_pooled`` False: per leader over ``scale_window_s``
  (300 s), repeated ranges included (the form before 4b6fc32). The model's
  range-scale share k·r (a sound-speed error) is added after the median,
  in x's units, and is not in the values the median is taken over, so the
  mission's median does not take a sound-speed bias away (issue 26:
  docs/detection.md section 5);
- ``exclusion_z``: ``exclusion_residual_m`` standardized the same way (its
  offset is the follower's DR error across the other links' lines of
  sight, which changes slowly along the mission);
- ``drift_cusum_m``: max(S+, S-) of a two-sided CUSUM(k, h) of the drift
  residual per leader, restarting after each of its own alarms;
- ``model_innovation_m``: the range minus the DR error model's current
  prediction, before this range's update (NaN without the model). A
  repeated range never updates the model (and its range-scale share k·r
  is left out: a k pulled by other links' biases, times r, pushed normal
  stale ranges past T1), so on a stale run this is the
  stale value against where the leader is now: the range error that
  the label thresholds, predicted (``stale_aware`` tests it;
  docs/detection.md section 5).

Why a model of the DR error of a minute ago sees a slow drift (issue 16):
the ACKF's process noise (1 m/sqrt(s)) lets it move ~2 m between two ranges
of a leader, so it takes a 0.3 m/s drift (1.4 m per 4.8 s) as motion and
its innovation stays at the range noise. The follower's DR error grows much
more slowly, and mostly through the heading error turning each DVL step
(1.5 deg bias plus a walk in the scenario): the DR error model predicts it
as the vehicle turns, and the state of ``lag_s`` ago, carried forward over
the DR displacement, holds none of a younger drift. Over seeds 0-19, after
t_a, its residual on normal ranges has a MAD-sigma of 3.8 m (the range
noise is 3 m) and a 0.3 m/s drift's anomalous epochs a median of 15.3 m;
the 98 % quantile of the normal residuals flags 91 % of them. The stiff
reference (``drift_source`` "stiff", a 2-D random walk of 3e-4 m²/s) had
6.0 m and 16.6 m, and flagged 51 %: it lagged the heading error's ramp by
minutes, and a 2-D random walk with the heading state but no lag (3.5 m
spread) took in half of the drift (median 8.8 m, 46 %).

`FeatureTracker` keeps O(1) state per leader: each call costs the same
whatever the mission length.
"""

from __future__ import annotations

import math
import statistics
from collections import deque

from formats.geodesy import metric_scales_scalar
from replay.stack.config import DRIFT_SOURCES, ConfigError, FeatureConfig
from replay.stack.cusum import Cusum
from replay.stack.dr_error_model import DrErrorModel, DrErrorParams
from replay.stack.exclusion import LeaderExclusion

PAPER_FEATURES: tuple[str, ...] = ("f1", "f2", "f3")
EXTRA_FEATURES: tuple[str, ...] = (
    "repeat_count", "dr_residual_m", "leader_consistency_m", "usbl_residual_m", "lag_residual_m",
    "drift_residual_m", "drift_cusum_m", "exclusion_residual_m", "drift_z", "exclusion_z", "model_innovation_m",
)
FEATURE_NAMES: tuple[str, ...] = PAPER_FEATURES + EXTRA_FEATURES
"""Every feature of a range epoch, in the order of a feature vector and of ``TrainingSet.features``."""
NAN = float("nan")


def range_to(lat: float, lon: float, depth_m: float, leader_lat: float, leader_lon: float,
             leader_depth_m: float) -> float:
    """Horizontal range (m) with common radii at the mid latitude and mean depth (docs/design.md section 7)."""
    b, a = metric_scales_scalar(0.5 * (lat + leader_lat), 0.5 * (depth_m + leader_depth_m))
    return math.hypot(b * (lat - leader_lat), a * (lon - leader_lon))


class StiffReference:
    """A 2-D Kalman filter of the follower's DR error (DR minus truth, north-east metres) on ranges and fixes.

    State d with covariance P; between epochs P grows by q·dt (a random
    walk). A range z to a leader at horizontal distance r from the dead
    reckoned position, along the unit vector u from the leader, predicts
    z ≈ r - u·d: the innovation v = z - r + u·d with variance u P uᵀ + R.
    A repeated range is not used (at most ``cap`` in a row per leader); a
    USBL fix measures d directly. No gate on the innovation: a gate that
    leaves out normal ranges lets the filter fall behind the DR error.
    """

    def __init__(self, q_m2_per_s: float, range_sigma_m: float, p0_m: tuple[float, float], cap: int) -> None:
        """Start at d = 0 with P = diag(p0_m)²."""
        self.q = float(q_m2_per_s)
        self.r_var = float(range_sigma_m) ** 2
        self.cap = int(cap)
        self.d = [0.0, 0.0]
        self.p = [float(p0_m[0]) ** 2, 0.0, float(p0_m[1]) ** 2]     # nn, ne, ee
        self._skipped: dict[str, int] = {}

    def propagate(self, dt_s: float) -> None:
        """The random walk over dt_s seconds."""
        self.p[0] += self.q * dt_s
        self.p[2] += self.q * dt_s

    def range(self, leader: str, z_m: float, north_m: float, east_m: float, repeated: bool) -> float:
        """The innovation (m) of range z from DR, the follower minus the leader at (north_m, east_m); then update."""
        r = math.hypot(north_m, east_m)
        if not r > 0.0:
            return NAN
        un, ue = north_m / r, east_m / r
        pnn, pne, pee = self.p
        v = z_m - r + un * self.d[0] + ue * self.d[1]
        skipped = self._skipped.get(leader, 0)
        if repeated and skipped < self.cap:
            self._skipped[leader] = skipped + 1
            return v
        self._skipped[leader] = 0
        # H = -u: P Hᵀ = -(P u), S = u P uᵀ + R
        pun, pue = pnn * un + pne * ue, pne * un + pee * ue
        s = un * pun + ue * pue + self.r_var
        kn, ke = -pun / s, -pue / s
        self.d[0] += kn * v
        self.d[1] += ke * v
        # P - K (H P) with H P = -(u P)
        self.p = [pnn + kn * pun, pne + kn * pue, pee + ke * pue]
        return v

    def fix(self, north_m: float, east_m: float, cov_m2: tuple[float, float, float]) -> None:
        """A position fix: d measured as (north_m, east_m), DR minus the fix, with covariance (nn, ne, ee) m²."""
        pnn, pne, pee = self.p
        snn, sne, see = pnn + cov_m2[0], pne + cov_m2[1], pee + cov_m2[2]
        det = snn * see - sne * sne
        if not det > 0.0:
            return
        inn, ine, iee = see / det, -sne / det, snn / det
        # K = P S⁻¹
        k11, k12 = pnn * inn + pne * ine, pnn * ine + pne * iee
        k21, k22 = pne * inn + pee * ine, pne * ine + pee * iee
        rn, re = north_m - self.d[0], east_m - self.d[1]
        self.d[0] += k11 * rn + k12 * re
        self.d[1] += k21 * rn + k22 * re
        # (I - K) P, symmetric
        self.p = [pnn - (k11 * pnn + k12 * pne), pne - (k11 * pne + k12 * pee), pee - (k21 * pne + k22 * pee)]


class FeatureTracker:
    """Pure dead reckoning, the USBL anchor and per-leader memory: the EXTRA_FEATURES of each range epoch."""

    def __init__(self, config: FeatureConfig, leaders: tuple[str, ...], position: tuple[float, float],
                 exclusion: LeaderExclusion | None = None, range_sigma_m: float = 3.0,
                 p0_m: tuple[float, float] = (1.0, 1.0)) -> None:
        """Start dead reckoning at the initial position (lat, lon in rad); no USBL anchor yet.

        ``exclusion``: the leader-exclusion filters, or none. ``range_sigma_m`` and
        ``p0_m`` (the stack's r_m and p0_m) set the stiff reference's R and P0.
        """
        if config.drift_source not in DRIFT_SOURCES:
            raise ConfigError(f"features.drift_source must be one of {DRIFT_SOURCES}, got {config.drift_source!r}")
        self.config = config
        self.exclusion = exclusion
        self.stiff = StiffReference(config.stiff_q_m2_per_s, range_sigma_m, p0_m, config.stiff_cap) \
            if config.drift_source == "stiff" else None
        self.model = DrErrorModel(DrErrorParams(
            config.model_q_m2_per_s, math.radians(config.model_heading_walk_deg_per_sqrt_s),
            config.model_scale_walk_per_sqrt_s, range_sigma_m, p0_m, math.radians(config.model_heading_sigma_deg),
            config.model_scale_sigma, config.lag_s, config.model_gate_sigma, config.model_gate_cap,
            config.model_hold_q_m2_per_s3, config.model_hold_grace_s,
            math.radians(config.model_deviation_sigma_deg), math.radians(config.model_turn_deg_per_sqrt_rad),
            config.model_range_scale_sigma, config.model_deviation_link_gate,
        )) if config.drift_source == "model" else None
        self._range_sigma_m = float(range_sigma_m)
        self.dr = [float(position[0]), float(position[1])]
        self.anchor: list[float] | None = None
        self.anchor_t = -math.inf
        self._last_slant: dict[str, float] = {}
        self._repeats = dict.fromkeys(leaders, 0)
        self._window: dict[str, deque[tuple[float, float]]] = {ld: deque() for ld in leaders}
        self._latest: dict[str, tuple[float, float]] = {}       # leader -> (t, dr_residual)
        self._cusum = {ld: Cusum(config.cusum_k_m, config.cusum_h_m) for ld in leaders}
        self._history: dict[tuple[str, str], deque[tuple[float, float]]] = {}   # (series, leader) -> (t, x)
        self._lagged: deque[tuple[float, float, float, float, float]] = deque()   # t, reference, dr at t

    def propagate(self, dt_s: float, forward_mps: float, lateral_mps: float, heading_rad: float,
                  depth_m: float, age_s: float = 0.0) -> None:
        """Carry dead reckoning and the anchor forward by one DR step (A.1, radii at the start of the step).

        ``age_s``: the age at the step's end of the DR sample whose velocity it carries (the DR error model's
        held steps).
        """
        if self.exclusion is not None:
            self.exclusion.propagate(dt_s, forward_mps, lateral_mps, heading_rad, depth_m)
        if self.stiff is not None:
            self.stiff.propagate(dt_s)
        c, s = math.cos(heading_rad), math.sin(heading_rad)
        north = dt_s * (forward_mps * c - lateral_mps * s)
        east = dt_s * (forward_mps * s + lateral_mps * c)
        if self.model is not None:
            self.model.step(dt_s, north, east, age_s, heading_rad)
        for p in (self.dr, self.anchor):
            if p is not None:
                b, a = metric_scales_scalar(p[0], depth_m)
                p[0] += north / b
                p[1] += east / a

    def fix(self, t_s: float, lat_rad: float, lon_rad: float,
            cov_rad2: tuple[float, float, float] | None = None) -> None:
        """A USBL fix of the follower: the anchor moves to it (blended with a fresh anchor, `usbl_blend`).

        ``cov_rad2`` (p11, p12, p22 in rad²) also updates the exclusion filters.
        """
        if self.exclusion is not None and cov_rad2 is not None:
            self.exclusion.fix(lat_rad, lon_rad, *cov_rad2)
        if cov_rad2 is not None:
            b, a = metric_scales_scalar(lat_rad, 0.0)
            d_m = (b * (self.dr[0] - lat_rad), a * (self.dr[1] - lon_rad))
            cov_m2 = (cov_rad2[0] * b * b, cov_rad2[1] * b * a, cov_rad2[2] * a * a)
            if self.stiff is not None:
                self.stiff.fix(*d_m, cov_m2)
            if self.model is not None:
                self.model.fix(t_s, *d_m, cov_m2)
        if self.anchor is None or t_s - self.anchor_t > self.config.usbl_max_age_s:
            self.anchor = [float(lat_rad), float(lon_rad)]
        else:
            w = self.config.usbl_blend
            self.anchor[0] += w * (lat_rad - self.anchor[0])
            self.anchor[1] += w * (lon_rad - self.anchor[1])
        self.anchor_t = float(t_s)

    def epoch(self, t_s: float, leader: str, slant_m: float, z_m: float, depth_m: float,
              geo: tuple[float, float, float], reference: tuple[float, float] | None = None) -> tuple[float, ...]:
        """The EXTRA_FEATURES of one range epoch (horizontal range z, leader lat, lon, depth in geo).

        ``reference`` is the reference filter's estimate (lat, lon) before this
        epoch's update, remembered for ``lag_residual_m`` (None: no lagged residual).
        """
        cfg = self.config
        lag = self._lag_residual(t_s, z_m, depth_m, geo, reference)
        scaled = innovation = NAN
        post = 0.0
        self._repeats[leader] = self._repeats[leader] + 1 if self._last_slant.get(leader) == slant_m else 0
        self._last_slant[leader] = slant_m
        e = z_m - range_to(self.dr[0], self.dr[1], depth_m, *geo)
        win = self._window[leader]
        while win and win[0][0] < t_s - cfg.median_window_s:
            win.popleft()
        d = e - statistics.median(v for _, v in win) if win else 0.0
        win.append((t_s, e))
        self._latest[leader] = (t_s, d)
        others = [v for ld, (t, v) in self._latest.items() if ld != leader and t >= t_s - cfg.median_window_s]
        consistency = d - sum(others) / len(others) if others else 0.0
        usbl = NAN
        if self.anchor is not None and t_s - self.anchor_t <= cfg.usbl_max_age_s:
            usbl = z_m - range_to(self.anchor[0], self.anchor[1], depth_m, *geo)
        excl = NAN
        if self.exclusion is not None:
            excl = self.exclusion.epoch(leader, z_m, geo, depth_m, self._repeats[leader] > 0)
        lat, lon, ldepth = geo
        b, a = metric_scales_scalar(0.5 * (self.dr[0] + lat), 0.5 * (depth_m + ldepth))
        rel = (b * (self.dr[0] - lat), a * (self.dr[1] - lon))
        if self.model is not None:
            innovation, drift, scaled, post = self._model_drift(t_s, leader, z_m, rel)
        elif self.stiff is not None:
            drift = self.stiff.range(leader, z_m, *rel, self._repeats[leader] > 0)
        else:
            second = excl if cfg.drift_source == "exclusion" else lag
            drift = usbl if math.isfinite(usbl) else second if math.isfinite(second) else d
        up, down, _ = self._cusum[leader].step(drift)
        pool = ("drift", "*") if cfg.scale_pooled else ("drift", leader)
        return (float(self._repeats[leader]), d, consistency, usbl, lag, drift, max(up, down), excl,
                self._standardized(t_s, pool, scaled if math.isfinite(scaled) else drift,
                                   keep=not (cfg.scale_pooled and self._repeats[leader] > 0),
                                   window_s=cfg.scale_pooled_window_s if cfg.scale_pooled else None, post=post),
                self._standardized(t_s, ("excl", leader), excl) if self.exclusion is not None else NAN, innovation)

    def _model_drift(self, t_s: float, leader: str, z_m: float, rel: tuple[float, float]) -> tuple[float, ...]:
        """The DR error model's view of one range: (its innovation, the drift residual, that residual in metres at
        the range noise alone (NaN: not scaled by the model), the range-scale share put back after the median)."""
        cfg, model = self.config, self.model
        assert model is not None
        scaled = NAN
        post = 0.0
        res = model.range(t_s, leader, z_m, *rel, self._repeats[leader] > 0)
        # the current innovation before the first lagged state (lag_s into the run), and while a USBL fix
        # younger than lag_s holds the filter: the lagged state has not seen that fix, and fixes keep the
        # filter off a drift (dev seeds 1-9 with fixes: FNR at 2 % 0.051 against the lagged one's 0.071)
        fresh_fix = t_s - model.last_fix_s <= cfg.lag_s
        lagged = math.isfinite(res.lagged_m) and not fresh_fix
        drift = res.lagged_m if lagged else res.innovation_m
        var = res.lagged_var_m2 if lagged else res.innovation_var_m2
        if cfg.scale_by_model and var > 0.0:
            # in metres at the range noise alone: the pooled median and MAD then see one spread
            scaled = drift * self._range_sigma_m / math.sqrt(var)
        if res.scale_m != 0.0:
            # the range-scale state's share k·r is an error of the range against the truth (what the label
            # thresholds), not of the DR: the model's prediction leaves it out of the residual, and it is put
            # back in after the mission's median, in the residual's units, so drift_z does not normalize a
            # sound-speed bias away (docs/detection.md section 5); the stale test's innovation stays without it
            shown = self._range_sigma_m / math.sqrt(var) if cfg.scale_by_model and var > 0.0 else 1.0
            post = res.scale_m * shown
            scaled = drift * shown
            drift = drift + res.scale_m
        return res.innovation_m, drift, scaled, post

    def _standardized(self, t_s: float, key: tuple[str, str], x: float, keep: bool = True,
                      window_s: float | None = None, post: float = 0.0) -> float:
        """x against the median and MAD of its series' (key) values aged lag_s to window_s; NaN if few.

        ``window_s`` None: ``scale_window_s``. ``keep`` False: x is standardized
        but not remembered (a repeated range in the pooled series).
        """
        cfg = self.config
        window = cfg.scale_window_s if window_s is None else window_s
        hist = self._history.setdefault(key, deque())
        while hist and hist[0][0] < t_s - window:
            hist.popleft()
        cutoff = t_s - cfg.lag_s
        old = [v for t, v in hist if t <= cutoff]
        if keep and math.isfinite(x):
            hist.append((t_s, x))
        if len(old) < cfg.scale_min_samples or not math.isfinite(x):
            return NAN
        med = statistics.median(old)
        mad = statistics.median(abs(v - med) for v in old)
        return (x + post - med) / max(1.4826 * mad, cfg.scale_floor_m)

    def _lag_residual(self, t_s: float, z_m: float, depth_m: float, geo: tuple[float, float, float],
                      reference: tuple[float, float] | None) -> float:
        """z minus the range from the reference of lag_s ago plus the DR displacement since; NaN without one."""
        lagged, cutoff = self._lagged, t_s - self.config.lag_s
        while len(lagged) > 1 and lagged[1][0] <= cutoff:
            lagged.popleft()
        out = NAN
        if lagged and lagged[0][0] <= cutoff:
            _, ref_lat, ref_lon, dr_lat, dr_lon = lagged[0]
            out = z_m - range_to(ref_lat + self.dr[0] - dr_lat, ref_lon + self.dr[1] - dr_lon, depth_m, *geo)
        if reference is not None:
            lagged.append((t_s, reference[0], reference[1], self.dr[0], self.dr[1]))
        return out
