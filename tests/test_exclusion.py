"""Leader-exclusion residual (replay.stack.exclusion) and the runner's lean open-loop pass of the hybrid database."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.config import StackConfig
from replay.stack.exclusion import ExclusionParams, LeaderExclusion
from replay.stack.features import EXTRA_FEATURES
from replay.stack.hybrid_database import HybridDatabase
from replay.stack.runner import CooperativeRunner, RunnerOptions, RunnerParts, Start
from replay.stack.tracking import feature_tracker, leader_exclusion
from replay.stack.training import RECORDED
from tests.test_runner import A0, B0, LAT, LON, make_trial, run_trial

LEADERS = ("leader1", "leader2", "leader3")
EXCLUSION = replace(StackConfig().features, drift_source="exclusion")   # the filters run only when used


def _exclusion() -> LeaderExclusion:
    return LeaderExclusion(LEADERS, (LAT, LON, 4.0), ExclusionParams((5.0, 5.0), (0.2, 0.2), 3.0, 1e9, 20))


def _push(exc: LeaderExclusion, ranges: list[tuple[str, float, tuple[float, float, float]]]) -> list[float]:
    out = []
    for leader, z, geo in ranges:
        exc.propagate(2.5, 1.5, 0.0, 0.3, 4.0)
        out.append(exc.epoch(leader, z, geo, 4.0, repeated=False))
    return out


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.floats(-30.0, 30.0), st.integers(0, 2))
def test_a_fault_on_one_link_shifts_only_its_own_residual(seed: int, offset: float, faulty: int) -> None:
    """The filter excluding j never sees j's ranges: adding d to j's ranges adds exactly d to j's residuals.

    (No gating here: with the gate the other filters would also leave j's bad ranges out.)
    """
    rng = np.random.default_rng(seed)
    geos = [(LAT + rng.uniform(-800, 800) / B0, LON + rng.uniform(-800, 800) / A0, 0.0) for _ in LEADERS]
    ranges = [(LEADERS[k % 3], rng.uniform(200.0, 900.0), geos[k % 3]) for k in range(30)]
    bad = [(ld, z + offset if ld == LEADERS[faulty] else z, g) for ld, z, g in ranges]
    clean_exc, bad_exc = _exclusion(), _exclusion()
    clean, shifted = _push(clean_exc, ranges), _push(bad_exc, bad)
    for (ld, _, _), c, s in zip(ranges, clean, shifted):
        if ld == LEADERS[faulty]:
            assert math.isclose(s - c, offset, abs_tol=1e-9)
    assert bad_exc.states[LEADERS[faulty]] == clean_exc.states[LEADERS[faulty]]


def test_exclusion_residual_follows_a_drift_the_other_link_corrects_dead_reckoning() -> None:
    """On the runner's trial (DR biased): a 0.3 m/s drift on leader1 moves its exclusion residual by most of it.

    Leader2's residual moves less: its exclusion filter takes leader1's drifting ranges until the gate
    leaves them out (the contamination two leaders cannot avoid).
    """
    trial = make_trial(3, stale=())
    drift = [(t, ld, la, lo, d, math.hypot(math.sqrt(max(s * s - 16.0, 0.0)) + 0.3 * max(0.0, t - 400.0), 4.0)
              if ld == "leader1" and t >= 400.0 else s, tr) for t, ld, la, lo, d, s, tr in trial.epochs]
    cfg = StackConfig(methods=("ackf", "cusum_drift"), training_window_s=300.0, features=EXCLUSION)

    def residuals(epochs: list) -> dict[str, np.ndarray]:
        _, out = run_trial(replace(trial, epochs=epochs), cfg)
        return {ld: np.array([(r[0].time_s, r[0].exclusion_residual_m) for r in out if r and r[0].leader == ld])
                for ld in ("leader1", "leader2")}

    clean, drifted = residuals(trial.epochs), residuals(drift)
    change = {ld: drifted[ld][:, 1] - clean[ld][:, 1] for ld in clean}
    t = {ld: clean[ld][:, 0] for ld in clean}
    assert all(np.isfinite(clean[ld][t[ld] > 50.0, 1]).all() for ld in clean)
    assert np.array_equal(change["leader1"][t["leader1"] < 400.0], np.zeros(int((t["leader1"] < 400.0).sum())))
    late1 = change["leader1"][(t["leader1"] > 450.0) & (t["leader1"] < 500.0)]   # 15-30 m of drift
    late2 = change["leader2"][(t["leader2"] > 450.0) & (t["leader2"] < 500.0)]
    assert np.median(late1) > 10.0
    assert np.median(np.abs(late2)) < 0.6 * np.median(late1)


def test_one_leader_has_no_exclusion_residual() -> None:
    exc = LeaderExclusion(("leader1",), (LAT, LON, 4.0), ExclusionParams((5.0, 5.0), (0.2, 0.2), 3.0, 10.0, 20))
    assert math.isnan(exc.epoch("leader1", 300.0, (LAT + 300 / B0, LON, 0.0), 4.0, False))


def test_lean_open_loop_copy_equals_an_ackf_only_runner() -> None:
    """The hybrid database's pass gives the rows a runner holding only ``ackf`` would (the slow reference)."""
    cfg = StackConfig(methods=("ackf", "cusum_drift"), training_window_s=300.0, features=EXCLUSION)
    runner, _ = run_trial(make_trial(4), cfg)
    window = runner.parts.trainer.window
    start, leaders = Start(0.0, LAT, LON, 4.0), ("leader1", "leader2")
    n = sum(kind == "range" for kind, _ in window)
    rng = np.random.default_rng(0)
    slant = np.array([a[5] for kind, a in window if kind == "range"]) + rng.normal(0.0, 5.0, n)
    replied = rng.random(n) > 0.1
    lean = HybridDatabase(cfg, leaders, start).copy_rows(window, slant, replied)
    only_ackf = replace(cfg, methods=("ackf",))
    # the child runs no new method, so it would have no feature tracker: it is handed the one the lean pass builds
    parts = replace(RunnerParts.build(only_ackf, leaders, start, RunnerOptions(keep_history=False)),
                    features=feature_tracker(cfg, leaders, start))
    child = CooperativeRunner(only_ackf, "follower", leaders, start, parts=parts)
    k = 0
    for kind, args in window:
        if kind == "dr":
            child.dead_reckon(*args)
        else:
            if replied[k]:
                t, leader, lat, lon, depth, _, truth = args
                child.range_epoch(t, leader, lat, lon, depth, float(slant[k]), truth)
            k += 1
    child_rows = child.parts.trainer.rows
    assert len(lean) == len(child_rows) > 50
    np.testing.assert_array_equal(np.array([r[2:] for r in lean], float), np.array([r[2:] for r in child_rows], float))
    assert [r[:2] for r in lean] == [r[:2] for r in child_rows]
    assert np.isfinite(np.array([r[2 + 3 + EXTRA_FEATURES.index("exclusion_residual_m")] for r in lean])).mean() > 0.9
    assert RECORDED == ""


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.5, 20.0), st.floats(-50.0, 50.0) | st.just(math.nan)), min_size=1,
                max_size=150))
def test_standardized_residual_matches_its_definition(steps: list[tuple[float, float]]) -> None:
    """drift_z: (x - median) / max(1.4826 MAD, floor) of the finite values aged lag_s..scale_window_s; NaN if few."""
    from replay.stack.config import FeatureConfig
    from replay.stack.features import FeatureTracker

    cfg = FeatureConfig()
    tracker = FeatureTracker(cfg, ("leader1",), (LAT, LON))
    t, seen = 0.0, []
    for dt, x in steps:
        t += dt
        got = tracker._standardized(t, ("drift", "leader1"), x)
        old = [v for s, v in seen if t - cfg.scale_window_s <= s <= t - cfg.lag_s]
        if len(old) < cfg.scale_min_samples or not math.isfinite(x):
            assert math.isnan(got)
        else:
            med = float(np.median(old))
            scale = max(1.4826 * float(np.median(np.abs(np.array(old) - med))), cfg.scale_floor_m)
            assert math.isclose(got, (x - med) / scale, rel_tol=1e-9, abs_tol=1e-9)
        if math.isfinite(x):
            seen.append((t, x))


def test_exclusion_filters_run_only_when_a_method_uses_them() -> None:
    """Default (stiff drift residual): no exclusion filters and NaN features; either switch turns them on."""
    base = StackConfig(methods=("ackf", "cusum_drift"), training_window_s=300.0)
    on = [replace(base, features=EXCLUSION), replace(base, hybrid_inputs=("f2", "exclusion_z"))]
    start = Start(0.0, LAT, LON)
    off_runner = CooperativeRunner(base, "f", ["leader1", "leader2"], start)
    assert off_runner.parts.features is not None and off_runner.parts.features.exclusion is None
    assert leader_exclusion(base, ["leader1", "leader2"], start) is None
    on_runners = [CooperativeRunner(c, "f", ["leader1", "leader2"], start) for c in on]
    assert all(r.parts.features is not None and r.parts.features.exclusion is not None for r in on_runners)
    _, out = run_trial(make_trial(6), base)
    rows = [r[0] for r in out if r]
    assert all(math.isnan(r.exclusion_residual_m) and math.isnan(r.exclusion_z) for r in rows)
    assert np.isfinite([r.drift_residual_m for r in rows if r.time_s > 100.0]).mean() > 0.9
