"""Chi-square and BP-assisted dual-threshold detectors, labels, and the method mapping."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack import labels
from replay.stack.config import StackConfig
from replay.stack.detectors import dual_threshold
from replay.stack.detectors.chi_square import ChiSquareDetector, chi_square_threshold
from replay.stack.detectors.dual_threshold import DualThresholdDetector, cusum, train_bp
from replay.stack.methods import METHOD_TABLE, detecting_names, filter_kind, runnable_names

CONFIG = StackConfig()


def window_features(seed: int, n: int = 150) -> tuple[np.ndarray, np.ndarray]:
    """Lake-like training features: normal epochs ~3 m, a few 15-40 m anomalies; target |Z - Z_gps|."""
    rng = np.random.default_rng(seed)
    err = np.abs(rng.normal(0.0, 3.0, n))
    bad = rng.random(n) < 0.1
    err[bad] = rng.uniform(15.0, 40.0, bad.sum())
    f1 = np.abs(err + rng.normal(0.0, 1.0, n))
    pzz = 10.0 + rng.random(n)
    f2 = f1 ** 2 / pzz
    f3 = 9.0 * np.maximum(1.0, f1 ** 2 / pzz)
    return np.c_[f1, f2, f3], err


# ---------------------------------------------------------------- labels


def test_range_labels_use_t1_and_unknown() -> None:
    z = np.array([100.0, 100.0, 100.0, 100.0, np.nan])
    truth = np.array([100.0, 109.0, 109.5, np.nan, 100.0])
    np.testing.assert_array_equal(labels.range_labels(z, truth, 9.0), [0, 0, 1, -1, -1])
    assert labels.label_one(100.0, 80.0, 9.0) == 1 and labels.label_one(1.0, math.inf, 9.0) == -1
    np.testing.assert_array_equal(labels.signed_range_error([110.0], [100.0]), [10.0])


def test_interpolate_track_and_truth_ranges() -> None:
    t = np.array([0.0, 1.0, 2.0, 10.0])
    lat = np.array([0.5, 0.5 + 1e-6, 0.5 + 2e-6, 0.5 + 3e-6])
    lon = np.full(4, 2.0)
    qlat, qlon = labels.interpolate_track(np.array([0.5, 1.5, 5.0, -1.0, 11.0]), t, lat, lon)
    np.testing.assert_allclose(qlat[:2], [0.5 + 0.5e-6, 0.5 + 1.5e-6], rtol=1e-15)
    assert np.isnan(qlat[2:]).all() and np.isnan(qlon[2:]).all()     # gap of 8 s, outside
    z = labels.truth_ranges(qlat[:2], qlon[:2], 0.0, 0.5, 2.0, 0.0)
    assert z.shape == (2,) and np.all(z > 0)


# ----------------------------------------------------------- chi-square


def test_chi_square_threshold_and_decisions() -> None:
    assert abs(chi_square_threshold(0.01) - 6.634896601) < 1e-8
    assert abs(chi_square_threshold(0.05) - 3.841458821) < 1e-8
    det = ChiSquareDetector(CONFIG)
    det.train(np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    assert det.decide(np.array([1.0, 6.0, 9.0])).flagged is False
    d = det.decide(np.array([10.0, 7.0, 9.0]))
    assert d.flagged and d.score == 7.0 and d.threshold == det.threshold and d.correction_m == 0.0
    assert det.decide(np.array([np.nan, np.nan, np.nan])).flagged is False
    np.testing.assert_array_equal(det.scores(np.array([[1, 2, 3], [4, 5, 6.0]])), [2.0, 5.0])


# ------------------------------------------------------- dual threshold


def test_bp_network_learns_the_range_error() -> None:
    feats, err = window_features(1)
    net = train_bp(feats, err, hidden=8, seed=0)
    rmse = float(np.sqrt(np.mean((net.predict(feats) - err) ** 2)))
    assert rmse < 0.5 * err.std()
    again = train_bp(feats, err, hidden=8, seed=0)
    np.testing.assert_array_equal(net.w1, again.w1)                      # seeded, deterministic


def _adam_reference(flat: np.ndarray, u: np.ndarray, t: np.ndarray, hidden: int) -> np.ndarray:
    """Adam written as its formulas, one new array per operation: what the buffered `_adam` must equal."""
    m = np.zeros_like(flat)
    v = np.zeros_like(flat)
    for it in range(1, dual_threshold.BP_ITERATIONS + 1):
        g = dual_threshold._gradient(flat, u, t, hidden)
        m = 0.9 * m + 0.1 * g
        v = 0.999 * v + 0.001 * g * g
        flat = flat - (dual_threshold.BP_STEP / (1.0 - 0.9 ** it)) * m / (np.sqrt(v / (1.0 - 0.999 ** it)) + 1e-8)
    return flat


@settings(max_examples=5, deadline=None)
@given(n=st.integers(1, 40), hidden=st.integers(1, 9), seed=st.integers(0, 2**16))
def test_buffered_adam_equals_the_formulas_bit_for_bit(n: int, hidden: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    u, t = rng.normal(size=(n, 3)), rng.normal(size=n)
    flat = rng.normal(size=3 * hidden + 2 * hidden + 1)
    got = dual_threshold._adam(flat.copy(), u, t, hidden)
    want = _adam_reference(flat, u, t, hidden)
    assert got.tobytes() == want.tobytes()


def test_bp_network_with_no_data_predicts_constant() -> None:
    net = train_bp(np.zeros((0, 3)), np.zeros(0), hidden=4, seed=0)
    assert np.all(net.predict(np.ones((3, 3))) == 0.0)
    net = train_bp(np.full((5, 3), np.nan), np.ones(5), hidden=4, seed=0)
    assert np.all(np.isfinite(net.predict(np.ones((2, 3)))))


def test_cusum_restarts() -> None:
    np.testing.assert_array_equal(cusum(np.array([1.0, -3.0, 2.0, np.nan, 2.0])), [1.0, 0.0, 2.0, 2.0, 4.0])
    np.testing.assert_array_equal(cusum(np.array([3.0, 3.0, 3.0, 3.0]), h=5.0), [3.0, 6.0, 3.0, 6.0])
    np.testing.assert_array_equal(cusum(np.ones(3), alarm=np.array([False, True, False])), [1.0, 2.0, 1.0])


def test_dual_threshold_catches_slow_drift_that_chi_square_misses() -> None:
    feats, err = window_features(2)
    dual, chi = DualThresholdDetector(CONFIG), ChiSquareDetector(CONFIG)
    dual.train(feats, err, (err > 9.0).astype(np.int8))
    # a slow drift: the filter follows it, so f2 stays under the chi-square threshold, f1 ~ 6-7 m
    drift = np.array([[6.0 + 0.1 * k, 4.0, 30.0] for k in range(12)])
    dual_flags = [dual.decide(f).flagged for f in drift]
    assert not any(chi.decide(f).flagged for f in drift)
    assert any(dual_flags)
    first = dual_flags.index(True)
    dual.reset()
    assert dual.cusum_state == 0.0
    assert first >= 1                                                    # an accumulation, not one epoch
    # normal epochs do not accumulate
    dual.reset()
    assert not any(dual.decide(np.array([1.5, 0.2, 9.0])).flagged for _ in range(50))


def test_dual_threshold_abrupt_fault_and_scores() -> None:
    feats, err = window_features(3)
    det = DualThresholdDetector(CONFIG)
    det.train(feats, err, (err > 9.0).astype(np.int8))
    d = det.decide(np.array([30.0, 80.0, 700.0]))
    assert d.flagged and d.threshold == 1.0 and d.score >= 80.0 / det.chi2_threshold
    assert det.decide(np.array([np.nan, 1.0, 1.0])).flagged is False
    seq = np.array([[1.5, 0.2, 9.0]] * 5 + [[30.0, 80.0, 700.0]] + [[1.5, 0.2, 9.0]] * 3)
    s = det.scores(seq)
    assert s.shape == (9,) and s[5] > 1.0 and np.all(s[:5] < 1.0) and np.all(s[6:] < 1.0)


def test_untrained_dual_threshold_is_a_chi_square_test() -> None:
    det = DualThresholdDetector(CONFIG)
    assert det.decide(np.array([20.0, 7.0, 9.0])).flagged
    assert not det.decide(np.array([20.0, 6.0, 9.0])).flagged


@settings(deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=3, max_size=3))
def test_detectors_never_raise(values: list[float]) -> None:
    f = np.array(values)
    for det in (ChiSquareDetector(CONFIG), DualThresholdDetector(CONFIG)):
        d = det.decide(f)
        assert isinstance(d.flagged, bool)


# --------------------------------------------------------------- methods


def test_method_mapping_covers_every_method() -> None:
    assert {filter_kind(m) for m in runnable_names()} == {"dr", "ckf", "ackf", "detect"}
    assert {m for m in runnable_names() if filter_kind(m) == "detect"} == set(detecting_names())
    assert [filter_kind(m) for m in ("dead_reckoning", "ckf", "ackf", "anfis")] == ["dr", "ckf", "ackf", "detect"]
    with pytest.raises(ValueError, match="unknown method 'kalman'"):
        filter_kind("kalman")
    assert all(METHOD_TABLE[m].factory is not None for m in detecting_names())
    chi, dual = METHOD_TABLE["chi_square"].factory, METHOD_TABLE["dual_threshold"].factory
    assert chi is not None and isinstance(chi(CONFIG), ChiSquareDetector)
    assert dual is not None and isinstance(dual(CONFIG), DualThresholdDetector)
