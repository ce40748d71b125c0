"""The stale_aware detector: a repeated range by its error predicted now against T1, fix_aware's tests elsewhere."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.events import EpochResult
from replay.run.config import load_config
from replay.run.evaluate import TrialSpec, evaluate_trial
from replay.stack.config import FeatureConfig, StackConfig
from replay.stack.detectors.fix_aware import FixAwareDetector
from replay.stack.detectors.stale_aware import StaleAwareDetector
from replay.stack.features import EXTRA_FEATURES, FEATURE_NAMES, FeatureTracker, range_to
from replay.stack.methods import METHOD_TABLE, why_line
from samples.scenario import AnomalyEvent, Scenario

F2, USBL, RES, Z, REP, INN = (FEATURE_NAMES.index(n) for n in
                              ("f2", "usbl_residual_m", "drift_residual_m", "drift_z", "repeat_count",
                               "model_innovation_m"))


def _trained(seed: int = 0) -> tuple[StaleAwareDetector, FixAwareDetector]:
    """Both trained on the same rows: normal residuals of 3 m spread and a few beyond T1."""
    rng = np.random.default_rng(seed)
    x = np.full((400, len(FEATURE_NAMES)), np.nan)
    x[:, F2] = rng.chisquare(1, 400)
    x[:, RES] = rng.normal(0, 3, 400)
    x[:, Z] = x[:, RES] / 3
    x[:, REP] = 0.0
    labels = (np.abs(x[:, RES]) > 9).astype(np.int8)
    sa, fa = StaleAwareDetector(StackConfig()), FixAwareDetector(StackConfig())
    sa.train(x, x[:, RES], labels)
    fa.train(x, x[:, RES], labels)
    return sa, fa


row_values = st.tuples(st.floats(0, 400), st.floats(-60, 60), st.one_of(st.just(math.nan), st.floats(-20, 20)),
                       st.one_of(st.just(math.nan), st.floats(-40, 40)), st.integers(0, 5),
                       st.one_of(st.just(math.nan), st.floats(-40, 40)))


@settings(max_examples=200, deadline=None)
@given(st.lists(row_values, min_size=1, max_size=30))
def test_a_stale_range_is_judged_by_its_predicted_error_and_any_other_as_fix_aware(
        values: list[tuple[float, ...]]) -> None:
    sa, fa = _trained()
    x = np.full((len(values), len(FEATURE_NAMES)), np.nan)
    x[:, [F2, RES, Z, USBL, REP, INN]] = np.array(values, dtype=float)
    stale = (x[:, REP] > 0) & np.isfinite(x[:, INN]) & ~np.isfinite(x[:, USBL])
    s = sa.scores(x)
    assert np.array_equal(s[~stale], fa.scores(x[~stale]), equal_nan=True)
    # a stale range's score is above h exactly when its predicted error is beyond T1 (9 m), and grows with it
    assert np.array_equal(s[stale] > sa.threshold, np.abs(x[stale, INN]) > 9.0)
    order = np.argsort(np.abs(x[stale, INN]), kind="stable")
    assert np.all(np.diff(s[stale][order]) >= 0)
    for row, st_ in zip(x, stale):
        d = sa.decide(row)
        if st_:
            assert d.flagged == (abs(row[INN]) > 9.0) == (d.score > d.threshold)
            assert not d.steps_down     # the running threshold's multiplier may rise on it, never fall
        else:
            assert d == fa.decide(row)


def test_calibration_leaves_out_the_stale_and_fixed_rows() -> None:
    rng = np.random.default_rng(3)
    n = 1000
    x = np.full((n, len(FEATURE_NAMES)), np.nan)
    x[:, RES] = rng.normal(0, 30, n)        # beyond T1 mostly: the score is |z|
    x[:, Z] = rng.normal(0, 1, n)
    x[:, REP] = 0.0
    x[:300, REP] = 2.0                      # stale rows with huge z: left out of the quantile
    x[:300, Z] = 50.0
    x[:300, INN] = 1.0
    sa = StaleAwareDetector(StackConfig())
    gate0 = sa.inner.gate
    assert sa.calibrate(x, 0.02)
    plain = np.abs(x[300:, Z])
    assert sa.threshold == pytest.approx(np.quantile(plain, 0.98), rel=0.05)
    assert sa.inner.threshold == sa.threshold == sa.threshold_z
    assert sa.inner.gate == gate0          # no row under a fresh fix: chi-square's gate stays configured


def test_calibration_sets_the_gate_on_every_row_under_a_fresh_fix_repeated_or_not() -> None:
    """The gate decides every row with a fresh fix (repeats too): its quantile is over all of them, as fix_aware's."""
    rng = np.random.default_rng(4)
    n = 1200
    x = np.full((n, len(FEATURE_NAMES)), np.nan)
    x[:, RES] = rng.normal(0, 30, n)
    x[:, Z] = rng.normal(0, 1, n)
    x[:, REP] = 0.0
    x[:, F2] = rng.chisquare(1, n) * 2.0    # twice chi-square's spread: the gate must rise from 6.63
    x[:600, USBL] = 1.0                     # under a fresh fix: the gate decides these
    x[:200, REP] = 3.0                      # ... repeated ones among them too
    x[600:800, REP] = 3.0                   # repeated without a fix: the stale test (T1), left out
    x[600:800, Z] = 50.0
    x[600:800, INN] = 1.0
    sa = StaleAwareDetector(StackConfig())
    assert sa.calibrate(x, 0.02)
    assert sa.inner.gate == pytest.approx(np.quantile(x[:600, F2], 0.98), rel=0.05)
    assert sa.inner.gate > 9.0
    alone = FixAwareDetector(StackConfig())
    assert alone.calibrate(x[800:], 0.02)           # the plain rows: drift_reference's h, as fix_aware's own
    assert sa.threshold == alone.threshold and 1.5 < sa.threshold < 3.5
    assert sa.thresholds["chi_square_gate"] == sa.inner.gate
    assert sa.thresholds["calibration_rows_fresh"] == 600.0
    entry = METHOD_TABLE["stale_aware"]
    assert entry.detects and entry.wide and entry.calibrated and not entry.default


def test_the_model_innovation_of_a_repeated_range_is_the_stale_value_against_the_moved_geometry() -> None:
    """The model never takes a repeated range: a stale run's innovation is its error from where the leader is now."""
    cfg = FeatureConfig()
    lat0, lon0, depth = math.radians(43.0), math.radians(5.0), 10.0
    tracker = FeatureTracker(cfg, ("leader1",), (lat0, lon0), range_sigma_m=3.0)
    geo = (lat0 + 0.005, lon0, 5.0)               # a fixed leader ~556 m north
    col = EXTRA_FEATURES.index("model_innovation_m")
    t, stale_z = 0.0, None
    innovations = []
    for k in range(60):
        tracker.propagate(5.0, 1.0, 0.0, 0.0, depth)          # 5 m north per step, towards the leader
        t += 5.0
        z = range_to(tracker.dr[0], tracker.dr[1], depth, *geo)
        if k >= 50:                                            # the modem repeats its value of step 49
            z = stale_z
        else:
            stale_z = z
        innovations.append(tracker.epoch(t, "leader1", z, z, depth, geo)[col])
    assert all(abs(v) < 1e-6 for v in innovations[:50])     # DR is the truth here: no innovation
    # each repeated step the leader is 5 m closer than the stale value says
    assert innovations[50:] == pytest.approx([5.0 * (k + 1) for k in range(10)], abs=1e-3)


def test_without_the_model_there_is_no_innovation() -> None:
    tracker = FeatureTracker(replace(FeatureConfig(), drift_source="stiff"), ("leader1",),
                             (math.radians(43.0), math.radians(5.0)))
    geo = (math.radians(43.005), math.radians(5.0), 5.0)
    out = tracker.epoch(10.0, "leader1", 500.0, 500.0, 10.0, geo)
    assert math.isnan(out[EXTRA_FEATURES.index("model_innovation_m")])


STALE = AnomalyEvent(leader="leader1", kind="stale", start_s=480.0, end_s=560.0, magnitude_m=0.0)


def test_on_a_trial_stale_ranges_are_caught_by_their_predicted_error() -> None:
    """Seed 1 (700 s) with an 80 s stale run in its scored part: stale_aware flags its epochs beyond T1."""
    base = replace(Scenario(), anomalies=(STALE,))
    cfg = load_config(None, ["training_window_s=400", "methods=chi_square,fix_aware,stale_aware"])
    scores = evaluate_trial(TrialSpec(1, None, 700.0, base), cfg)
    labels, stale, fixaw = scores.open_labels["stale_aware"], scores.open_scores["stale_aware"], \
        scores.open_scores["fix_aware"]
    normal = np.isfinite(stale) & (labels == 0)
    anomalous = labels == 1
    assert int(anomalous.sum()) >= 5
    h = np.quantile(stale[normal], 0.98)
    assert np.mean(stale[anomalous] > h) >= np.mean(fixaw[anomalous] > np.quantile(fixaw[normal], 0.98))
    assert np.mean(stale[anomalous] > h) > 0.8


def test_its_why_line_names_the_stale_test() -> None:
    sa, _ = _trained()
    base = EpochResult(900.0, "leader1", "stale_aware", True, 30.0, 2.5, 5.0, 9.8, 9.0, 1, True, False, False,
                       500.0, 495.0, 0.8, 2.2, 1.0, 0.0, 1.0, repeat_count=3.0, model_innovation_m=-12.0,
                       drift_z=0.4, drift_residual_m=1.2)
    assert why_line(base, sa).startswith("repeated range: its error predicted now -12.0 m > T1 9.00 m")
    fresh = base._replace(repeat_count=0.0, flagged=False, score=0.4)
    assert why_line(fresh, sa).startswith("no fresh fix: score 0.40 <= h 2.50 sd")
