"""The DR error model (replay.stack.dr_error_model): against a per-step matrix filter, and on a turning track."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.geodesy import metric_scales_scalar
from replay.stack.config import FeatureConfig
from replay.stack.dr_error_model import DrErrorModel, DrErrorParams
from replay.stack.features import EXTRA_FEATURES, FeatureTracker, range_to

HEADING_WALK = math.radians(0.03)


def transition(sum_perp: tuple[float, float], sum_disp: tuple[float, float]) -> np.ndarray:
    """F of DR steps summing to (n, e): d gains psi·(-e, n) + s·(n, e), sum_perp = (-e, n), sum_disp = (n, e)."""
    f = np.eye(4)
    f[0, 2], f[1, 2] = sum_perp
    f[0, 3], f[1, 3] = sum_disp
    return f


def model(q: float = 1e-2, walk: float = HEADING_WALK, scale_walk: float = 1e-4, lag_s: float = 60.0,
          gate: float = 4.0, gate_cap: int = 10) -> DrErrorModel:
    return DrErrorModel(DrErrorParams(q, walk, scale_walk, 3.0, (1.0, 2.0), math.radians(3.0), 0.01, lag_s, gate,
                                      gate_cap))


class StepwiseModel:
    """The slow obvious filter: F·P·Fᵀ + Q at every DR step, every state kept for the lagged prediction."""

    def __init__(self, q: float, walk: float, scale_walk: float, lag_s: float, gate: float, gate_cap: int) -> None:
        self.q = np.array([q, q, walk ** 2, scale_walk ** 2])
        self.x = np.zeros(4)
        self.p = np.diag([1.0, 4.0, math.radians(3.0) ** 2, 1e-4])
        self.lag_s, self.gate, self.gate_cap = lag_s, gate, gate_cap
        self.history: list[tuple[float, np.ndarray, np.ndarray, int]] = []     # t, x, P, steps taken by then
        self.steps: list[tuple[float, float, float]] = []
        self.left_out = 0

    def step(self, dt: float, n: float, e: float, held: float = 0.0, turn: float = 0.0) -> None:
        """One DR step; ``held`` the position variance of a held step, ``turn`` the heading variance of a turn."""
        f = transition((-e, n), (n, e))
        noise = np.diag(self.q * dt + np.array([held, held, turn, 0.0]))
        self.x = f @ self.x
        self.p = f @ (self.p + noise) @ f.T
        self.steps.append((dt, n, e, held, turn))

    def range(self, t: float, z: float, north: float, east: float,
              repeated: bool) -> tuple[float, float, float, float]:
        r = math.hypot(north, east)
        h = -np.array([north, east, 0.0, 0.0]) / np.array([r, r, 1.0, 1.0])
        v = z - r - h @ self.x
        vl = sl = math.nan
        old = [s for s in self.history if s[0] <= t - self.lag_s]
        if old:
            _, x, p, k = old[-1]
            for dt, n, e, held, turn in self.steps[k:]:
                f = transition((-e, n), (n, e))
                x, p = f @ x, f @ (p + np.diag(self.q * dt + np.array([held, held, turn, 0.0]))) @ f.T
            vl = z - r - h @ x
            sl = h @ p @ h + 9.0
        gated = math.isfinite(vl) and abs(vl) > self.gate * math.sqrt(sl)
        s = h @ self.p @ h + 9.0
        if not repeated and gated and self.left_out < self.gate_cap:
            self.left_out += 1
        elif not repeated:
            self.left_out = 0
            k = self.p @ h / s
            self.x = self.x + k * v
            self.p = (np.eye(4) - np.outer(k, h)) @ self.p
        self.history.append((t, self.x.copy(), self.p.copy(), len(self.steps)))
        return float(v), float(s), float(vl), float(sl)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(0.2, 3.0), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.integers(0, 3),
                          st.floats(-300, 300), st.floats(-300, 300), st.floats(-30, 30), st.booleans()),
                min_size=1, max_size=60),
       st.floats(1e-4, 1e-1), st.booleans())
def test_the_lazy_model_is_the_per_step_filter(events: list[tuple[float, float, float, int, float, float, float,
                                                                     bool]], q: float, walks: bool) -> None:
    """Ranges after runs of DR steps: innovation and lagged residual as the per-step filter gives them.

    Exact without heading and scale walks (a position random walk commutes
    with F); with them the lazy filter adds an interval's noise at its start,
    a difference of q_psi·dt·displacement² that stays within 2 %.
    """
    walk, scale_walk = (HEADING_WALK, 1e-4) if walks else (0.0, 0.0)
    fast, slow = model(q, walk, scale_walk, lag_s=10.0, gate_cap=2), StepwiseModel(q, walk, scale_walk, 10.0, 4.0, 2)
    t = 0.0
    for dt, vn, ve, nsteps, north, east, err, repeated in events:
        for _ in range(nsteps):
            t += dt
            fast.step(dt, vn * dt, ve * dt)
            slow.step(dt, vn * dt, ve * dt)
        if math.hypot(north, east) < 1.0:
            continue
        z = math.hypot(north, east) + err
        got = fast.range(t, "leader1", z, north, east, repeated)
        want = slow.range(t, z, north, east, repeated)
        tol = dict(rel=1e-9, abs=1e-9) if not walks else dict(rel=2e-2, abs=0.05)
        assert got.innovation_m == pytest.approx(want[0], **tol)
        assert got.innovation_var_m2 == pytest.approx(want[1], **tol)
        if math.isnan(want[2]):
            assert math.isnan(got.lagged_m) and math.isnan(got.lagged_var_m2)
        else:
            assert got.lagged_m == pytest.approx(want[2], **tol)
            assert got.lagged_var_m2 == pytest.approx(want[3], **tol)
        if not walks:
            np.testing.assert_allclose(fast.x, slow.x, atol=1e-9)
            np.testing.assert_allclose(fast.p, slow.p, rtol=1e-9, atol=1e-12)


HOLD_Q, GRACE = 0.01, 2.0


def held_variance(age_s: float, dt: float) -> float:
    """The obvious held variance of one step ending at age_s: the integral of q·(a - grace)² over the step."""
    a = np.linspace(max(age_s - dt, GRACE), age_s, 20001)
    if age_s <= GRACE:
        return 0.0
    return float(np.trapezoid(HOLD_Q * (a - GRACE) ** 2, a))


class DeviationStepwise:
    """The slow obvious filter with the deviation states: psi(h) = psi + a1 sin h + b1 cos h + a2 sin 2h + b2 cos 2h.

    8 states (d_n, d_e, psi, s, a1, b1, a2, b2); every DR step F = I + G, G's column of a heading term being
    that term at the step's heading times (-e, n). Held steps add their position variance at each step.
    """

    def __init__(self, q: float, sigma: float) -> None:
        self.q = np.array([q, q, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        self.x = np.zeros(8)
        self.p = np.diag([1.0, 4.0, math.radians(3.0) ** 2, 1e-4] + [sigma ** 2] * 4)
        self.history: list[tuple[float, np.ndarray, np.ndarray, int]] = []
        self.steps: list[np.ndarray] = []

    def step(self, dt: float, n: float, e: float, h: float, held: float) -> None:
        f = np.eye(8)
        terms = [1.0, 0.0, math.sin(h), math.cos(h), math.sin(2 * h), math.cos(2 * h)]
        for k, c in zip((2, 4, 5, 6, 7), (terms[0], *terms[2:])):
            f[0, k], f[1, k] = -e * c, n * c
        f[0, 3], f[1, 3] = n, e
        noise = np.diag(self.q * dt + np.array([held, held, 0, 0, 0, 0, 0, 0]))
        self.x = f @ self.x
        self.p = f @ (self.p + noise) @ f.T
        self.steps.append(np.concatenate([f.ravel(), noise.ravel()]))

    def range(self, t: float, z: float, north: float, east: float, lag_s: float) -> tuple[float, float, float, float]:
        r = math.hypot(north, east)
        h = np.zeros(8)
        h[:2] = -np.array([north, east]) / r
        v = z - r - h @ self.x
        s = h @ self.p @ h + 9.0
        vl = sl = math.nan
        old = [st_ for st_ in self.history if st_[0] <= t - lag_s]
        if old:
            _, x, p, k = old[-1]
            for packed in self.steps[k:]:
                f, noise = packed[:64].reshape(8, 8), packed[64:].reshape(8, 8)
                x, p = f @ x, f @ (p + noise) @ f.T
            vl, sl = z - r - h @ x, h @ p @ h + 9.0
        k = self.p @ h / s
        self.x = self.x + k * v
        self.p = (np.eye(8) - np.outer(k, h)) @ self.p
        self.history.append((t, self.x.copy(), self.p.copy(), len(self.steps)))
        return float(v), float(s), float(vl), float(sl)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(0.2, 3.0), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.integers(0, 3),
                          st.booleans(), st.floats(-math.pi, math.pi), st.floats(-300, 300), st.floats(-300, 300),
                          st.floats(-30, 30)),
                min_size=1, max_size=60))
def test_held_steps_and_the_deviation_states_are_the_per_step_filter(
        events: list[tuple[float, float, float, int, bool, float, float, float, float]]) -> None:
    """Without bottom lock the DVL's last velocity is carried on (a held step): the position variance grows as
    q·(age - grace)³/3. The compass deviation's states turn each step by the deviation at its heading. Both
    as the per-step 8-state filter gives them, exactly: a position variance and constant states commute with
    the lazy propagation (no gate: the errors stay within 30 m of a far leader)."""
    sigma = math.radians(1.5)
    fast = DrErrorModel(DrErrorParams(1e-2, 0.0, 0.0, 3.0, (1.0, 2.0), math.radians(3.0), 0.01, 10.0, 1e9, 0,
                                      HOLD_Q, GRACE, sigma))
    slow = DeviationStepwise(1e-2, sigma)
    t, age = 0.0, 0.0
    for dt, vn, ve, nsteps, hold, heading, north, east, err in events:
        for _ in range(nsteps):
            t += dt
            age = age + dt if hold else 0.0
            fast.step(dt, vn * dt, ve * dt, age, heading)
            slow.step(dt, vn * dt, ve * dt, heading, held_variance(age, dt))
        if math.hypot(north, east) < 1.0:
            continue
        z = math.hypot(north, east) + err
        got = fast.range(t, "leader1", z, north, east, False)
        want = slow.range(t, z, north, east, 10.0)
        tol = dict(rel=1e-6, abs=1e-6)
        assert got.innovation_m == pytest.approx(want[0], **tol)
        assert got.innovation_var_m2 == pytest.approx(want[1], **tol)
        if math.isnan(want[2]):
            assert math.isnan(got.lagged_m)
        else:
            assert got.lagged_m == pytest.approx(want[2], **tol)
            assert got.lagged_var_m2 == pytest.approx(want[3], **tol)
    fast._propagate()   # the steps after the last range are still pending (lazy)
    np.testing.assert_allclose(fast.x, slow.x, atol=1e-6)
    np.testing.assert_allclose(fast.p, slow.p, rtol=1e-6, atol=1e-9)


def test_a_held_minute_widens_the_prediction_by_its_velocity_walk() -> None:
    """60 s without a DVL sample: the predicted range variance grows by q·(60 - grace)³/3 (about 650 m² at the
    default 0.01 m²/s³), none of it within the grace."""
    fast = DrErrorModel(DrErrorParams(0.0, 0.0, 0.0, 3.0, (1.0, 1.0), 0.0, 0.0, 60.0, 4.0, 10, HOLD_Q, GRACE))
    for k in range(60):
        fast.step(1.0, 1.5, 0.0, float(k + 1))
    got = fast.range(60.0, "leader1", 500.0, 500.0, 0.0, False)
    assert got.innovation_var_m2 == pytest.approx(1.0 + 9.0 + HOLD_Q * 58.0 ** 3 / 3.0, rel=1e-9)
    within = DrErrorModel(DrErrorParams(0.0, 0.0, 0.0, 3.0, (1.0, 1.0), 0.0, 0.0, 60.0, 4.0, 10, HOLD_Q, GRACE))
    for _ in range(60):
        within.step(1.0, 1.5, 0.0, 1.0)
    assert within.range(60.0, "leader1", 500.0, 500.0, 0.0, False).innovation_var_m2 == pytest.approx(10.0)


def test_a_turn_widens_the_heading_error_by_its_walk() -> None:
    """A quarter turn since the last range: the heading error's variance gains turn²·(pi/2), which turns the
    whole displacement: the predicted range's variance, now and from the lagged state, gains
    turn²·(pi/2)·(h·(-sum e, sum n))²; the mean prediction is unchanged."""
    def run(turn: float) -> tuple[Any, float, float]:
        m = DrErrorModel(DrErrorParams(1e-2, HEADING_WALK, 1e-4, 3.0, (1.0, 1.0), math.radians(3.0), 0.01, 30.0, 4.0,
                                       10, 0.0, 2.0, 0.0, turn))
        m.step(1.0, 0.0, 0.0, 0.0, 0.0)
        m.range(1.0, "leader1", 500.0, 500.0, 0.0, False)
        sn = se = 0.0
        for k in range(1, 61):
            h = min(k, 30) / 30.0 * math.pi / 2.0
            sn, se = sn + 1.5 * math.cos(h), se + 1.5 * math.sin(h)
            m.step(1.0, 1.5 * math.cos(h), 1.5 * math.sin(h), 0.0, h)
        return m.range(61.0, "leader1", 500.0, 500.0 - sn, -se, False), sn, se
    base, _, _ = run(0.0)
    got, sn, se = run(math.radians(1.0))
    r = math.hypot(500.0 - sn, se)
    h0, h1 = -(500.0 - sn) / r, se / r
    extra = math.radians(1.0) ** 2 * math.pi / 2 * (h0 * -se + h1 * sn) ** 2
    assert extra > 1.0
    assert got.lagged_var_m2 - base.lagged_var_m2 == pytest.approx(extra, rel=1e-9)
    assert got.innovation_var_m2 - base.innovation_var_m2 == pytest.approx(extra, rel=1e-9)
    assert (got.lagged_m, got.innovation_m) == pytest.approx((base.lagged_m, base.innovation_m), rel=1e-12)


def _turning_track(duration_s: float, bias_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """1 Hz DR displacements of a follower turning through a full circle every 400 s, and its DR error.

    DR rotates each true step by the heading bias: error = DR - truth.
    """
    t = np.arange(1.0, duration_s + 1.0)
    heading = 2.0 * np.pi * t / 400.0
    true_step = 1.5 * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    b = math.radians(bias_deg)
    rot = np.array([[math.cos(b), -math.sin(b)], [math.sin(b), math.cos(b)]])
    dr_step = true_step @ rot.T
    truth = np.cumsum(true_step, axis=0)
    return t, dr_step, np.cumsum(dr_step, axis=0) - truth


def _leaders(k: int) -> np.ndarray:
    return np.array([[400.0, -300.0], [-350.0, 500.0]])[k % 2]


def _run(ref: DrErrorModel, duration_s: float, bias_deg: float, drift_from_s: float = math.inf,
         rate_mps: float = 0.3) -> list[tuple[float, float, float]]:
    """Noise-free ranges every 2.4 s alternately to two fixed leaders; leader 1's ramps from drift_from_s."""
    t, dr_step, err = _track = _turning_track(duration_s, bias_deg)
    dr = np.cumsum(dr_step, axis=0)
    out = []
    next_ping, k = 2.4, 0
    for i, ti in enumerate(t):
        ref.step(1.0, *dr_step[i])
        if ti < next_ping:
            continue
        next_ping += 2.4
        rel = dr[i] - _leaders(k)          # DR position minus leader
        truth = dr[i] - err[i] - _leaders(k)
        z = float(np.hypot(*truth))
        drift = rate_mps * (ti - drift_from_s) if (k % 2 == 0 and ti >= drift_from_s) else 0.0
        res = ref.range(float(ti), f"leader{k % 2 + 1}", z + drift, float(rel[0]), float(rel[1]), False)
        out.append((float(ti), res.innovation_m, res.lagged_m))
        k += 1
    return out


def test_the_model_learns_a_heading_bias_that_a_random_walk_cannot_follow() -> None:
    """A 2 deg heading bias on a turning track: the model's residuals vanish, its heading state finds the bias."""
    ref = model()
    rows = np.array(_run(ref, 1600.0, 2.0))
    late = rows[rows[:, 0] > 800.0]
    assert np.max(np.abs(late[:, 1])) < 0.5
    assert np.max(np.abs(late[:, 2])) < 1.0
    # DR rotated by +2 deg: d grows as +psi·perp(step), the state's psi is the bias
    assert math.degrees(ref.x[2]) == pytest.approx(2.0, abs=0.2)
    assert abs(ref.x[3]) < 2e-3


def test_the_lagged_residual_holds_a_minute_of_drift_the_current_state_starts_to_take() -> None:
    """A 0.3 m/s ramp on one link for 60 s: the lagged residual is the ramp; the ranges are gated out of the update."""
    onset = 1500.0
    rows = np.array(_run(model(), 1560.0, 2.0, drift_from_s=onset))
    leader1 = rows[(rows[:, 0] >= onset + 20.0) & (np.arange(len(rows)) % 2 == 0)]
    ramp = 0.3 * (leader1[:, 0] - onset)
    np.testing.assert_allclose(leader1[:, 2], ramp, atol=1.0)
    # once past the gate (4 sigma of a few metres) the ranges stay out of the update: no pull on the state
    assert np.all(np.abs(leader1[:, 1]) > 0.6 * ramp)


def _tracker_run(source: str, drift_from_s: float) -> np.ndarray:
    """FeatureTracker on a turning track with a 2 deg heading bias, noise-free ranges to two fixed leaders.

    Rows (t, leader index, drift_residual_m); leader 1's range ramps at 0.3 m/s from drift_from_s.
    """
    lat0, lon0, depth = math.radians(45.7), math.radians(126.6), 2.0
    b, a = metric_scales_scalar(lat0, depth)
    leaders = [(lat0 + 400.0 / b, lon0 - 300.0 / a, 1.5), (lat0 - 350.0 / b, lon0 + 500.0 / a, 1.5)]
    tracker = FeatureTracker(replace(FeatureConfig(), drift_source=source), ("leader1", "leader2"), (lat0, lon0))
    truth = [lat0, lon0]
    bias = math.radians(2.0)
    rows, k, next_ping = [], 0, 2.4
    for i in range(1, 1601):
        t = float(i)
        heading = 2.0 * math.pi * t / 400.0
        tracker.propagate(1.0, 1.5, 0.0, heading + bias, depth)
        bt, at = metric_scales_scalar(truth[0], depth)
        truth[0] += 1.5 * math.cos(heading) / bt
        truth[1] += 1.5 * math.sin(heading) / at
        if t < next_ping:
            continue
        next_ping += 2.4
        geo = leaders[k % 2]
        z = range_to(truth[0], truth[1], depth, *geo)
        z += 0.3 * (t - drift_from_s) if (k % 2 == 0 and t >= drift_from_s) else 0.0
        features = tracker.epoch(t, f"leader{k % 2 + 1}", z + 0.123 * k, z, depth, geo)
        rows.append((t, k % 2, features[EXTRA_FEATURES.index("drift_residual_m")]))
        k += 1
    return np.array(rows)


def test_the_feature_trackers_default_drift_residual_is_the_lagged_model() -> None:
    """Default drift_source "model": flat under a heading bias, the ramp under a drift; the stiff form lags the bias.

    The circle keeps the heading bias's DR error within a few metres, which
    the stiff random walk follows only minutes late.
    """
    rows = _tracker_run("model", drift_from_s=1540.0)
    before = rows[(rows[:, 0] > 800.0) & (rows[:, 0] < 1540.0)]
    assert np.max(np.abs(before[:, 2])) < 1.0
    drift = rows[(rows[:, 0] >= 1560.0) & (rows[:, 1] == 0)]
    np.testing.assert_allclose(drift[:, 2], 0.3 * (drift[:, 0] - 1540.0), atol=1.0)
    stiff = _tracker_run("stiff", drift_from_s=math.inf)
    stiff_before = stiff[(stiff[:, 0] > 800.0) & (stiff[:, 0] < 1540.0), 2]
    assert np.max(np.abs(stiff_before)) > 3.0 * np.max(np.abs(before[:, 2]))


def test_with_a_fresh_usbl_fix_the_drift_residual_is_the_current_innovation(monkeypatch: pytest.MonkeyPatch) -> None:
    """The lagged state has not seen a fix younger than lag_s: while one exists the current innovation is used."""
    lat0, lon0, depth = math.radians(45.7), math.radians(126.6), 2.0
    b, a = metric_scales_scalar(lat0, depth)
    leaders = [(lat0 + 400.0 / b, lon0 - 300.0 / a, 1.5), (lat0 - 350.0 / b, lon0 + 500.0 / a, 1.5)]
    tracker = FeatureTracker(FeatureConfig(), ("leader1", "leader2"), (lat0, lon0))
    assert tracker.model is not None
    seen = []
    model_range = tracker.model.range

    def spy(*args):
        seen.append(model_range(*args))
        return seen[-1]

    monkeypatch.setattr(tracker.model, "range", spy)
    fix_until = 400.0
    for k in range(1, 300):
        t = 2.4 * k
        tracker.propagate(2.4, 0.0, 0.0, 0.3, depth)      # at rest, where the fixes put it (none is gated)
        if t <= fix_until:
            tracker.fix(t, lat0, lon0, (1e-12, 0.0, 1e-12))
        geo = leaders[k % 2]
        z = range_to(lat0, lon0, depth, *geo) + 5.0 * math.sin(k)
        drift = tracker.epoch(t, f"leader{k % 2 + 1}", z, z, depth, geo)[EXTRA_FEATURES.index("drift_residual_m")]
        res = seen[-1]
        # the range-scale state's share k·r is put back: the residual is the range's error against the truth
        if t - fix_until <= 60.0:            # a fix within lag_s (60 s): the current innovation
            assert drift == res.innovation_m + res.scale_m
        elif t > 60.0:                       # no fresh fix, a lagged state: the lagged residual
            assert drift == res.lagged_m + res.scale_m and drift != res.innovation_m + res.scale_m


def _settled(gate_cap: int = 10) -> tuple[DrErrorModel, DrErrorModel]:
    """Two identical models (no heading or scale walk, so lazy propagation is exact) after 200 s of ranges."""
    pair = (model(walk=0.0, scale_walk=0.0, lag_s=10.0, gate_cap=gate_cap),
            model(walk=0.0, scale_walk=0.0, lag_s=10.0, gate_cap=gate_cap))
    for i in range(1, 201):
        for m in pair:
            m.step(1.0, 1.0, 0.5)
            if i % 3 == 0:
                m.range(float(i), "leader1", math.hypot(300.0, 200.0) + 0.5 * math.sin(i), 300.0, 200.0, False)
    return pair


def test_a_stale_run_of_any_length_never_enters_the_model() -> None:
    """40 repeats of a range 30 m off (past the gate cap of 10): the state is that of a model given no range at all.

    Under the shared cap before issue 26 the 11th repeat entered the update.
    """
    stale, twin = _settled(gate_cap=10)
    for i in range(201, 321):
        stale.step(1.0, 1.0, 0.5)
        twin.step(1.0, 1.0, 0.5)
        if i % 3 == 0:
            stale.range(float(i), "leader1", math.hypot(300.0, 200.0) + 30.0, 300.0, 200.0, True)
    twin.range(321.0, "leader2", math.nan, 300.0, 200.0, False)     # propagates, no update (z not finite)
    stale.range(321.0, "leader2", math.nan, 300.0, 200.0, False)
    np.testing.assert_allclose(stale.x, twin.x, atol=1e-9)
    np.testing.assert_allclose(stale.p, twin.p, rtol=1e-9, atol=1e-12)
    # the same run, fresh: it is gated for gate_cap ranges and then taken
    fresh, _ = _settled(gate_cap=10)
    for i in range(201, 321):
        fresh.step(1.0, 1.0, 0.5)
        if i % 3 == 0:
            fresh.range(float(i), "leader1", math.hypot(300.0, 200.0) + 30.0, 300.0, 200.0, False)
    assert abs(fresh.x[0] - twin.x[0]) + abs(fresh.x[1] - twin.x[1]) > 5.0


def test_the_gate_cap_still_caps_gated_ranges() -> None:
    """Fresh ranges 30 m off: the first gate_cap leave the state alone, the next enters; repeats do not count."""
    m, _ = _settled(gate_cap=4)
    states = []
    for k, i in enumerate(range(201, 231, 3)):
        m.step(3.0, 3.0, 1.5)
        repeated = k == 2                         # a repeat inside the run neither counts nor updates
        m.range(float(i), "leader1", math.hypot(300.0, 200.0) + 30.0 + 0.1 * k, 300.0, 200.0, repeated)
        states.append(list(m.x))
    # x moves only with the propagation (the heading and scale states turn the steps: ~5e-5 m) until the
    # 5th fresh gated range (the 6th call)
    moved = [abs(states[j][0] - states[j - 1][0]) + abs(states[j][1] - states[j - 1][1]) for j in range(1, 5)]
    assert max(moved) < 1e-3
    assert abs(states[5][0] - states[4][0]) + abs(states[5][1] - states[4][1]) > 1.0


def test_a_fix_beyond_the_gate_is_left_out_until_the_cap() -> None:
    """A USBL fix 200 m off the settled model (issue 26: one moved the state 200 m) is left out, gate_cap in a row.

    A fix agreeing with the model is taken; after gate_cap fixes 200 m off the next is taken (a real jump).
    """
    m, _ = _settled(gate_cap=3)
    for k in range(3):
        before = list(m.x)
        m.fix(201.0 + k, 200.0, -150.0, (4.0, 0.0, 4.0))
        # only the lazy propagation of the last steps moves x (micrometres), never the fix's 250 m
        assert abs(m.x[0] - before[0]) + abs(m.x[1] - before[1]) < 1e-3
        assert m.last_fix_s == -math.inf                               # a gated fix is no fresh fix
    m.fix(204.0, 200.0, -150.0, (4.0, 0.0, 4.0))                       # the 4th in a row: taken
    assert m.last_fix_s == 204.0 and m.x[0] > 100.0        # most of the way to the fix's 200 m
    near, _ = _settled(gate_cap=3)
    near.fix(201.0, near.x[0] + 2.0, near.x[1] - 2.0, (4.0, 0.0, 4.0))
    assert near.last_fix_s == 201.0



class ScaleStepwise:
    """The slow obvious filter with the range-scale state: 5 states (d_n, d_e, psi, s, k), z = r + h·d + k·r."""

    def __init__(self, q: float, sigma: float) -> None:
        self.q = np.array([q, q, 0.0, 0.0, 0.0])
        self.x = np.zeros(5)
        self.p = np.diag([1.0, 4.0, math.radians(3.0) ** 2, 1e-4, sigma ** 2])
        self.history: list[tuple[float, np.ndarray, np.ndarray, int]] = []
        self.steps: list[np.ndarray] = []

    def step(self, dt: float, n: float, e: float) -> None:
        f = np.eye(5)
        f[:4, :4] = transition((-e, n), (n, e))
        self.x = f @ self.x
        self.p = f @ (self.p + np.diag(self.q * dt)) @ f.T
        self.steps.append(np.concatenate([f.ravel(), self.q * dt]))

    def range(self, t: float, z: float, north: float, east: float, lag_s: float) -> tuple[float, ...]:
        r = math.hypot(north, east)
        h = np.array([-north / r, -east / r, 0.0, 0.0, r])
        v, s = z - r - h @ self.x, h @ self.p @ h + 9.0
        vl = sl = math.nan
        old = [st_ for st_ in self.history if st_[0] <= t - lag_s]
        if old:
            _, x, p, k = old[-1]
            for packed in self.steps[k:]:
                f = packed[:25].reshape(5, 5)
                x, p = f @ x, f @ (p + np.diag(packed[25:])) @ f.T
            vl, sl = z - r - h @ x, h @ p @ h + 9.0
        scale = r * self.x[4]
        k = self.p @ h / s
        self.x = self.x + k * v
        self.p = (np.eye(5) - np.outer(k, h)) @ self.p
        self.history.append((t, self.x.copy(), self.p.copy(), len(self.steps)))
        return float(v), float(s), float(vl), float(sl), float(scale)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(0.2, 3.0), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.integers(0, 3),
                          st.floats(-1500, 1500), st.floats(-1500, 1500), st.floats(-30, 30)),
                min_size=1, max_size=60),
       st.floats(1e-4, 0.02))
def test_the_range_scale_state_is_the_per_step_filter(events: list[tuple[float, float, float, int, float, float,
                                                                          float]], sigma: float) -> None:
    """With ``range_scale_sigma`` a fifth state k, each range measuring r + h·d + k·r: innovation, lagged
    residual, the scale's share k·r and the state as the per-step 5-state filter gives them, exactly (no walks,
    no gate)."""
    fast = DrErrorModel(DrErrorParams(1e-2, 0.0, 0.0, 3.0, (1.0, 2.0), math.radians(3.0), 0.01, 10.0, 1e9, 0,
                                      range_scale_sigma=sigma))
    slow = ScaleStepwise(1e-2, sigma)
    t = 0.0
    for dt, vn, ve, nsteps, north, east, err in events:
        for _ in range(nsteps):
            t += dt
            fast.step(dt, vn * dt, ve * dt)
            slow.step(dt, vn * dt, ve * dt)
        if math.hypot(north, east) < 1.0:
            continue
        z = math.hypot(north, east) * (1.0 + 0.005) + err
        got = fast.range(t, "leader1", z, north, east, False)
        want = slow.range(t, z, north, east, 10.0)
        tol = dict(rel=1e-6, abs=1e-6)
        assert (got.innovation_m, got.innovation_var_m2, got.scale_m) == pytest.approx(
            (want[0], want[1], want[4]), **tol)
        if math.isnan(want[2]):
            assert math.isnan(got.lagged_m)
        else:
            assert (got.lagged_m, got.lagged_var_m2) == pytest.approx((want[2], want[3]), **tol)
    fast._propagate()
    np.testing.assert_allclose(fast.x, slow.x, atol=1e-6)
    np.testing.assert_allclose(fast.p, slow.p, rtol=1e-6, atol=1e-9)


def test_the_range_scale_state_learns_a_sound_speed_bias() -> None:
    """Every range 0.5 % long (a sound speed 0.5 % high) on the turning track with a 2 deg heading bias: the
    scale state finds 0.005 and the residuals vanish; without it the DR state cannot hold a bias that points
    away from every leader, and the residuals keep metres of it."""
    def run(sigma: float) -> tuple[DrErrorModel, np.ndarray]:
        m = DrErrorModel(DrErrorParams(1e-2, HEADING_WALK, 1e-4, 3.0, (1.0, 2.0), math.radians(3.0), 0.01, 60.0,
                                       4.0, 10, range_scale_sigma=sigma))
        t, dr_step, err = _turning_track(1600.0, 2.0)
        dr = np.cumsum(dr_step, axis=0)
        rows, k, ping = [], 0, 2.4
        for i, ti in enumerate(t):
            m.step(1.0, *dr_step[i])
            if ti < ping:
                continue
            ping += 2.4
            rel = dr[i] - _leaders(k)
            z = 1.005 * float(np.hypot(*(rel - err[i])))
            res = m.range(float(ti), f"leader{k % 2 + 1}", z, float(rel[0]), float(rel[1]), False)
            rows.append((ti, res.innovation_m, res.lagged_m, res.scale_m, float(np.hypot(*rel))))
            k += 1
        return m, np.array(rows)
    with_k, rows = run(0.005)
    late = rows[rows[:, 0] > 800.0]
    assert with_k.x[with_k.ks] == pytest.approx(0.005, abs=3e-4)
    assert np.max(np.abs(late[:, 1])) < 0.5 and np.max(np.abs(late[:, 2])) < 1.0
    # the scale's share of the prediction is k·r, the bias each range carries
    np.testing.assert_allclose(late[:, 3], 0.005 * late[:, 4], atol=0.3)
    without, plain = run(0.0)
    assert without.ks == -1 and np.all(plain[:, 3] == 0.0)
    assert np.max(np.abs(plain[plain[:, 0] > 800.0, 1])) > 1.0


def _deviation_model(gate: float) -> DrErrorModel:
    return DrErrorModel(DrErrorParams(1e-2, HEADING_WALK, 1e-4, 3.0, (1.0, 2.0), math.radians(3.0), 0.01, 60.0,
                                      4.0, 10, deviation_sigma_rad=math.radians(1.0), deviation_link_gate=gate))


def test_a_range_on_a_link_that_stands_out_leaves_the_deviation_states_as_they_are() -> None:
    """With the link gate, a range whose link's running mean of standardized innovations stands out is a
    Schmidt update: x += K·v and P = (I - K·H)·P·(I - K·H)ᵀ + K·R·Kᵀ with the deviation states' rows of the
    optimal K set to 0, so their mean and covariance do not move; the other states take it as before."""
    m = _deviation_model(1.0)
    for k in range(40):
        m.step(1.0, 1.5 * math.cos(k / 10.0), 1.5 * math.sin(k / 10.0), 0.0, k / 10.0)
        if k % 5 == 4:
            m.range(float(k), "leader1", 500.0 + 0.1 * k, 480.0, 120.0, False)
    # a leader 12 m long for a while (one link only: multipath)
    for k in range(40, 80):
        m.step(1.0, 1.5 * math.cos(k / 10.0), 1.5 * math.sin(k / 10.0), 0.0, k / 10.0)
        if k % 5 != 4:
            continue
        m._propagate()
        x0, p0 = np.array(m.x), np.array(m.p)
        north, east = 480.0, 120.0 + k
        r = math.hypot(north, east)
        h = np.zeros(8)
        h[:2] = -north / r, -east / r
        z = r + 12.0
        mean_before = m._link_mean.get("leader1", 0.0)
        got = m.range(float(k), "leader1", z, north, east, False)
        w = got.innovation_m / math.sqrt(got.innovation_var_m2)
        considered = abs(mean_before + 0.2 * (w - mean_before)) > 1.0
        gain = p0 @ h / (h @ p0 @ h + 9.0)
        if considered:
            gain[4:8] = 0.0
        a = np.eye(8) - np.outer(gain, h)
        np.testing.assert_allclose(m.x, x0 + gain * got.innovation_m, atol=1e-9)
        np.testing.assert_allclose(m.p, a @ p0 @ a.T + 9.0 * np.outer(gain, gain), rtol=1e-9, atol=1e-12)
        if considered:
            np.testing.assert_array_equal(np.array(m.x)[4:8], x0[4:8])
            np.testing.assert_array_equal(np.array(m.p)[4:8, 4:8], p0[4:8, 4:8])
    assert m._link_mean["leader1"] > 1.0


def test_the_link_gate_looks_at_how_much_one_link_stands_out_from_the_others() -> None:
    """Two links biased alike (a DR error both see) keep the deviation states learning; one biased link
    alone does not. Without deviation states the gate is off."""
    m = _deviation_model(1.0)
    assert not m._one_link("leader1", 3.0)          # the mean after one range: 0.6
    assert m._one_link("leader1", 3.0)              # 1.08, no other link
    assert not m._one_link("leader2", 2.0)          # 0.4
    for _ in range(6):
        m._one_link("leader2", 2.0)
    assert m._link_mean["leader2"] == pytest.approx(2.0 * (1 - 0.8 ** 7))
    assert not m._one_link("leader1", 3.0)          # 1.46 against the other's 1.58
    assert _deviation_model(0.0).link_gate == 0.0
    plain = DrErrorModel(DrErrorParams(1e-2, HEADING_WALK, 1e-4, 3.0, (1.0, 2.0), math.radians(3.0), 0.01, 60.0,
                                       4.0, 10, deviation_link_gate=1.0))
    assert plain.link_gate == 0.0


def _multipath_run(gate: float) -> tuple[DrErrorModel, np.ndarray]:
    """The turning track (2 deg heading bias), noise-free ranges to two leaders, leader 1's 15 m long over
    600-900 s (multipath): per range t, link, lagged residual and the deviation coefficients' norm (deg)."""
    m = DrErrorModel(DrErrorParams(1e-2, HEADING_WALK, 1e-4, 3.0, (1.0, 2.0), math.radians(3.0), 0.01, 60.0,
                                   4.0, 10, deviation_sigma_rad=math.radians(1.0), deviation_link_gate=gate))
    t, dr_step, err = _turning_track(1200.0, 2.0)
    dr = np.cumsum(dr_step, axis=0)
    rows, k, ping = [], 0, 2.4
    for i, ti in enumerate(t):
        m.step(1.0, *dr_step[i], 0.0, 2.0 * math.pi * float(ti) / 400.0)
        if ti < ping:
            continue
        ping += 2.4
        rel = dr[i] - _leaders(k)
        bias = 15.0 if (k % 2 == 0 and 600.0 <= ti < 900.0) else 0.0
        res = m.range(float(ti), f"leader{k % 2 + 1}", float(np.hypot(*(rel - err[i]))) + bias, float(rel[0]),
                      float(rel[1]), False)
        rows.append((ti, k % 2, res.lagged_m, math.degrees(math.hypot(*m.x[4:8]))))
        k += 1
    return m, np.array(rows)


def test_the_link_gate_keeps_a_one_link_bias_out_of_the_deviation_states() -> None:
    """A 15 m multipath bias on one link for 300 s: the ungated deviation states take it as a heading
    deviation (their coefficients reach 3.1 deg; the track has none), and after it ends the lagged residuals
    still carry 12 m of it; with the link gate the coefficients stay near 1.1 deg and the residuals after it
    within 7.1 m. Before the bias both are the same filter (1.4 m at most, noise-free)."""
    plain, gated = _multipath_run(0.0)[1], _multipath_run(1.0)[1]
    before = (plain[:, 0] > 100.0) & (plain[:, 0] < 600.0)
    np.testing.assert_array_equal(plain[before], gated[before])
    assert np.nanmax(np.abs(plain[before, 2])) < 1.5
    during = (plain[:, 0] >= 600.0) & (plain[:, 0] < 900.0)
    assert plain[during, 3].max() > 3.0
    assert gated[during, 3].max() < 1.2
    late = plain[:, 0] > 1000.0
    assert np.max(np.abs(plain[late, 2])) > 11.5
    assert np.max(np.abs(gated[late, 2])) < 7.5
