"""Issue 16's estimator half: TrainingSet, features, the hybrid database, FPR-target thresholds, the drift CUSUM."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.config import FeatureConfig, InjectionConfig, StackConfig
from replay.stack.cusum import Cusum, alarm_rate, calibrate_h
from replay.stack.detectors.anfis_hybrid import HybridAnfisDetector, fpr_threshold
from replay.stack.detectors.cusum import CusumDriftDetector
from replay.stack.features import FEATURE_NAMES, FeatureTracker, range_to
from replay.stack.injection import inject_link
from replay.stack.training import TrainingSet
from tests.test_runner import LAT, LON, make_trial, run_trial

NEW = ("ackf", "chi_square", "anfis", "cusum_drift", "anfis_hybrid")
CONFIG = StackConfig(methods=NEW, training_window_s=300.0,
                     anfis=replace(StackConfig().anfis, epochs=20))


# ------------------------------------------------------------ TrainingSet

def _set(n: int, leader: str = "leader1") -> TrainingSet:
    rng = np.random.default_rng(n)
    return TrainingSet(rng.normal(size=(n, len(FEATURE_NAMES))), rng.normal(size=n), rng.integers(0, 2, n),
                       [leader] * n, FEATURE_NAMES)


def test_training_set_rows_select_and_concat() -> None:
    a, b = _set(5), _set(3, "leader2")
    both = a.concat(b)
    assert len(both) == 8 and both.kinds.tolist() == [""] * 8
    assert len(both.for_leader("leader2")) == 3
    np.testing.assert_array_equal(both.for_leader("leader1").features, a.features)
    np.testing.assert_array_equal(both.columns(["f2", "repeat_count"]), both.features[:, [1, 3]])
    with pytest.raises(KeyError, match="no feature 'nope'"):
        both.columns(["nope"])
    with pytest.raises(ValueError, match="features differ"):
        a.concat(TrainingSet(np.zeros((1, 3)), [0.0], [0], ["leader1"], ("f1", "f2", "f3")))
    with pytest.raises(ValueError, match="labels has 2 rows"):
        TrainingSet(np.zeros((3, 3)), np.zeros(3), np.zeros(2), ["x"] * 3, ("f1", "f2", "f3"))


def test_runner_trains_on_a_given_set() -> None:
    """"given": the detectors see the other run's rows only (same thresholds); "both": the union."""
    source, _ = run_trial(make_trial(1), CONFIG)
    ts = source.finish().training_set
    assert ts is not None and ts.feature_names == FEATURE_NAMES and (ts.kinds == "").sum() > 50
    assert {"stale", "drift", "outlier", "normal"} <= set(ts.kinds.tolist())
    other = make_trial(2, stale=((200, 240),))
    given, _ = run_trial(other, replace(CONFIG, training_source="given"), training_set=ts)
    res = given.finish()
    assert res.training_set is ts
    for method in ("anfis", "anfis_hybrid", "cusum_drift"):
        assert res.thresholds[method] == source.finish().thresholds[method]
    own, _ = run_trial(other, CONFIG)
    both, _ = run_trial(other, replace(CONFIG, training_source="both"), training_set=ts)
    assert len(both.finish().training_set) == len(own.finish().training_set) + len(ts)
    with pytest.raises(ValueError, match="needs a training_set"):
        run_trial(other, replace(CONFIG, training_source="given"))


# ------------------------------------------------------------ hybrid database

def test_injection_holds_every_kind_at_its_share() -> None:
    cfg = InjectionConfig(stale_share=0.15, drift_share=0.1, outlier_share=0.05, dropout_share=0.04)
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(4.0, 6.0, 400))
    z = 500.0 + 0.3 * t
    out, replied, kinds = inject_link(t, z, cfg, rng)
    for kind, share in (("stale", 0.15), ("drift", 0.1), ("outlier", 0.05), ("dropout", 0.04)):
        assert (kinds == kind).sum() == round(share * t.size), kind
    assert replied.tolist() == (kinds != "dropout").tolist()
    assert np.array_equal(out[kinds == "normal"], z[kinds == "normal"])
    dz = np.abs(out - z)[kinds == "outlier"]
    assert dz.min() >= cfg.outlier_min_m and dz.max() <= cfg.outlier_max_m
    for i in np.flatnonzero(kinds == "stale"):      # a stale range repeats the last one replied before its run
        j = i - 1
        while j >= 0 and kinds[j] == "stale":
            j -= 1
        prev = [k for k in range(j, -1, -1) if replied[k]]
        assert out[i] == (out[prev[0]] if prev else out[i])
    drift = np.flatnonzero(kinds == "drift")
    starts = drift[np.r_[True, np.diff(drift) > 1]]
    for s in starts:                                # each run ramps from 0 at a rate inside the configured range
        run = [s]
        while run[-1] + 1 < t.size and kinds[run[-1] + 1] == "drift":
            run.append(run[-1] + 1)
        if len(run) > 1:
            rate = abs(out[run[-1]] - z[run[-1]]) / (t[run[-1]] - t[s])
            assert out[s] == z[s] and cfg.drift_rate_mps[0] <= rate <= cfg.drift_rate_mps[1]


def test_runner_database_holds_every_kind_at_its_configured_share() -> None:
    inj = InjectionConfig(copies=2, stale_share=0.2, drift_share=0.1, outlier_share=0.05, dropout_share=0.05)
    runner, _ = run_trial(make_trial(4), replace(CONFIG, injection=inj))
    ts = runner.finish().training_set
    recorded = int((ts.kinds == "").sum())
    injected = ts.kinds[ts.kinds != ""]
    per_link = {ld: int((ts.leaders[ts.kinds == ""] == ld).sum()) for ld in ("leader1", "leader2")}
    for kind, share in (("stale", 0.2), ("drift", 0.1), ("outlier", 0.05)):
        want = inj.copies * sum(round(share * n) for n in per_link.values())
        assert (injected == kind).sum() == want, kind
    dropped = inj.copies * sum(round(0.05 * n) for n in per_link.values())
    assert injected.size == inj.copies * recorded - dropped
    assert f"dropout {dropped} " in runner.finish().training_notes["database"]


# ------------------------------------------------------------ features

def test_features_repeat_dr_residual_and_usbl() -> None:
    """Exact DR, exact ranges: residuals 0; a stale range counts repeats and leaves the DR range; a fix anchors."""
    tr = FeatureTracker(FeatureConfig(), ("a", "b"), (LAT, LON))
    leader = (LAT + 0.004, LON + 0.003, 0.0)
    z0 = range_to(LAT, LON, 0.0, *leader)
    first = tr.epoch(0.0, "a", z0, z0, 0.0, leader)
    assert first[:3] == (0.0, 0.0, 0.0) and math.isnan(first[3]) and math.isnan(first[4])
    for k in range(1, 6):
        tr.propagate(1.0, 2.0, 0.0, 0.0, 0.0)       # 2 m/s north
        z = range_to(tr.dr[0], tr.dr[1], 0.0, *leader)
        feats = tr.epoch(float(k), "a", z, z, 0.0, leader)
        assert feats[0] == 0.0 and abs(feats[1]) < 1e-6
    stale = [tr.epoch(5.0 + k, "a", z, z, 0.0, leader) for k in range(1, 4) if not tr.propagate(1.0, 2.0, 0, 0, 0)]
    assert [f[0] for f in stale] == [1.0, 2.0, 3.0]
    assert stale[-1][1] > 4.0                       # the range did not shrink as the follower moved 6 m closer
    tr.fix(9.0, tr.dr[0] + 10.0 / 6.37e6, tr.dr[1])
    z = range_to(tr.dr[0], tr.dr[1], 0.0, *leader)
    usbl = tr.epoch(9.0, "a", z, z, 0.0, leader)[3]
    assert usbl == pytest.approx(z - range_to(tr.anchor[0], tr.anchor[1], 0.0, *leader))
    assert math.isnan(tr.epoch(9.0 + 61.0, "a", z, z, 0.0, leader)[3])     # the anchor is too old


def test_lag_residual_sees_a_drift_the_reference_follows() -> None:
    """With an exact reference and exact DR the lagged prediction is the true range: the residual is the drift."""
    tr = FeatureTracker(FeatureConfig(lag_s=60.0), ("a",), (LAT, LON))
    leader = (LAT + 0.004, LON + 0.003, 0.0)
    lags = []
    for k in range(200):
        tr.propagate(1.0, 1.5, 0.2, 0.3, 0.0)
        z = range_to(tr.dr[0], tr.dr[1], 0.0, *leader)
        drift = 0.3 * max(0.0, k - 120)
        lags.append(tr.epoch(float(k), "a", z + drift, z + drift, 0.0, leader, (tr.dr[0], tr.dr[1]))[4])
    assert all(math.isnan(v) for v in lags[:60])
    np.testing.assert_allclose(lags[60:121], 0.0, atol=1e-6)
    np.testing.assert_allclose(lags[121:181], [0.3 * (k - 120) for k in range(121, 181)], atol=0.05)


# ------------------------------------------------------------ thresholds

@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([0.01, 0.02, 0.05, 0.1]), st.integers(200, 3000))
def test_fpr_threshold_flags_its_target_share(seed: int, target: float, n: int) -> None:
    s = np.random.default_rng(seed).gamma(2.0, 1.0, n)
    thr = fpr_threshold(s, target)
    assert np.sum(s > thr) == math.floor(n * target + 1e-9)


def test_hybrid_anfis_fpr_threshold_gives_the_target_on_training() -> None:
    """Trained on synthetic features, the training FPR of the chosen threshold is the target within sampling error."""
    rng = np.random.default_rng(7)
    n = 1500
    err = np.where(rng.random(n) < 0.1, rng.uniform(10, 40, n), rng.normal(0, 3, n))
    labels = (np.abs(err) > 9).astype(np.int8)
    x = np.full((n, len(FEATURE_NAMES)), np.nan)
    col = FEATURE_NAMES.index
    x[:, col("f2")] = (np.abs(err) + rng.normal(0, 3, n)) ** 2 / 9.0
    x[:, col("repeat_count")] = rng.poisson(0.2, n)
    x[:, col("lag_residual_m")] = err + rng.normal(0, 4, n)
    x[:, col("drift_residual_m")] = x[:, col("lag_residual_m")]     # the default input (since 531fadf)
    x[:, col("drift_cusum_m")] = np.abs(x[:, col("lag_residual_m")])
    for target in (0.02, 0.05):
        det = HybridAnfisDetector(replace(CONFIG, detection_fpr_target=target))
        det.train(x, err, labels)
        assert det.dropped == ("usbl_residual_m",)
        fpr = np.mean(det.scores(x[labels == 0]) > det.threshold)
        assert abs(fpr - target) <= 3 * math.sqrt(target * (1 - target) / (labels == 0).sum())
        assert det.thresholds["used"] == det.threshold and math.isfinite(det.thresholds["3sigma"])
        why = det.explain(x[0])
        assert why.input_names == det.inputs and why.anfis.output == pytest.approx(det.scores(x[:1])[0])


def test_cusum_calibration_reaches_its_alarm_rate() -> None:
    x = np.random.default_rng(2).normal(0.0, 4.0, 4000)
    h = calibrate_h([x], k=4.0, target=0.02, floor=1.0)
    assert alarm_rate(x, 4.0, h) <= 0.02 < alarm_rate(x, 4.0, 0.9 * h)


# ------------------------------------------------------------ CUSUM on a ramp

def ramp_delay(s: float, k: float, h: float) -> int:
    """First epoch N with S_N > h for x_n = s·n (n = 0, 1, ...), derived by hand.

    Increments s·n - k are positive from n0 = floor(k/s) + 1 on, so
    S_N = sum_{n=n0}^{N} (s n - k) = m (s (2 n0 + m - 1) / 2 - k) with
    m = N - n0 + 1 terms: the smallest m with (s/2) m² + B m - h > 0,
    B = s (2 n0 - 1)/2 - k, is floor(root) + 1 of the positive root.
    """
    n0 = math.floor(k / s) + 1
    b = s * (2 * n0 - 1) / 2 - k
    root = (-b + math.sqrt(b * b + 2 * s * h)) / s
    return n0 + math.floor(root)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.05, 5.0), st.floats(0.1, 10.0), st.floats(1.0, 80.0))
def test_cusum_ramp_delay_matches_its_closed_form(s: float, k: float, h: float) -> None:
    c = Cusum(k, h)
    delay = next(n for n in range(100_000) if c.step(s * n)[2])
    want = ramp_delay(s, k, h)
    if delay != want:     # only a tie S_N = h, a rounding hair from the root, may move the alarm by one epoch
        s_n = sum(max(0.0, s * n - k) for n in range(min(delay, want) + 1))
        assert abs(delay - want) == 1 and abs(s_n - h) < 1e-9 * h


@pytest.mark.parametrize(("column", "k", "x"), [("drift_z", 0.5, 5.5), ("drift_residual_m", 4.0, 9.0)])
def test_cusum_drift_detector_resets_after_an_alarm_and_explains(column: str, k: float, x: float) -> None:
    """On either input (sigmas or metres, its own k), +5 per epoch: alarm at the third, restart after reset."""
    cfg = replace(CONFIG, features=replace(CONFIG.features, cusum_input=column))
    det = CusumDriftDetector(cfg)
    det.train(np.zeros((10, len(FEATURE_NAMES))), np.zeros(10), np.zeros(10))
    det.threshold = det._cusum.h = 10.0
    row = np.zeros(len(FEATURE_NAMES))
    row[FEATURE_NAMES.index(column)] = x
    d = [det.decide(row) for _ in range(3)]
    assert [x.flagged for x in d] == [False, False, True] and d[2].score == pytest.approx(15.0)
    why = det.explain(row)
    assert (why.up_m, why.threshold_m, why.allowance_m, why.flagged) == (pytest.approx(15.0), 10.0, k, True)
    assert why.input == column
    det.reset()
    assert not det.decide(row).flagged and det.explain(row).up_m == pytest.approx(5.0)
    with pytest.raises(ValueError, match="cusum_input"):
        CusumDriftDetector(replace(CONFIG, features=replace(CONFIG.features, cusum_input="f2")))


def test_new_methods_run_closed_loop_and_report_thresholds() -> None:
    runner, _ = run_trial(make_trial(5), CONFIG)
    res = runner.finish()
    assert set(res.methods) == set(NEW) and not res.training_errors
    for method in ("anfis_hybrid", "cusum_drift"):
        for leader in ("leader1", "leader2"):
            named = res.thresholds[method][leader]
            assert named["used"] == named["fpr_target"] > 0
        assert np.isfinite(res.open_loop[method]["score"]).all()
    assert "3sigma" in res.thresholds["anfis_hybrid"]["leader1"]
    after = res.epochs["time_s"] > res.training_end_s
    hybrid = after & (res.epochs["method"] == "anfis_hybrid")
    assert res.epochs["flagged"][hybrid].any()
    # the filter-independent features are the same for every method of an epoch
    for name in ("repeat_count", "dr_residual_m", "drift_cusum_m"):
        col = res.epochs[name].reshape(-1, len(NEW))
        assert np.array_equal(col, np.repeat(col[:, :1], len(NEW), axis=1))
