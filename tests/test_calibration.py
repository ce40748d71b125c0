"""Thresholds calibrated on the training trial (replay.stack.calibration): the rows, the quantile, a real trial."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from replay.run.config import load_config
from replay.run.evaluate import TrialSpec, closed_loop_fpr, evaluate_trial, training_set_of
from replay.stack.calibration import MIN_ROWS, calibrate
from replay.stack.config import StackConfig
from replay.stack.detectors.drift_reference import Z_FLOOR, DriftReferenceDetector
from replay.stack.features import FEATURE_NAMES
from replay.stack.methods import METHOD_TABLE
from replay.stack.training import TrainingSet

Z, X = FEATURE_NAMES.index("drift_z"), FEATURE_NAMES.index("drift_residual_m")
F = len(FEATURE_NAMES)


def _rows(n: int, seed: int, dof: float = 3.0) -> np.ndarray:
    """Normal epochs whose drift_z has Student-t tails (heavier than 2.5 sigma's 1.2 %) and a residual of 4 m·z."""
    rng = np.random.default_rng(seed)
    rows = np.full((n, F), np.nan)
    rows[:, Z] = rng.standard_t(dof, n)
    rows[:, X] = 4.0 * rows[:, Z] + rng.normal(0.0, 1.0, n)
    return rows


def _set(n: int, calibration: np.ndarray | None = None) -> TrainingSet:
    ts = TrainingSet(np.zeros((n, F)), np.zeros(n), np.zeros(n, np.int8), np.array(["l1"] * n, dtype=object),
                     FEATURE_NAMES)
    return ts if calibration is None else ts.with_calibration(calibration)


def test_calibration_rows_go_with_the_set() -> None:
    """concat, select, for_leader and with_features keep them; the digest changes only when there are some."""
    cal = _rows(5, 0)
    a, b = _set(3, cal), _set(2, cal[:2])
    both = a.concat(b)
    assert both.calibration.shape == (7, F)
    np.testing.assert_array_equal(both.calibration[:5], cal)
    assert both.select(np.array([True, False, True, False, False])).calibration.shape == (7, F)
    assert both.for_leader("l1").calibration.shape == (7, F)
    narrow = both.with_features(("drift_z", "f2"))
    np.testing.assert_array_equal(narrow.calibration[:, 0], both.calibration[:, Z])
    assert _set(3).digest() == _set(3, np.empty((0, F))).digest()
    assert _set(3, cal).digest() != _set(3).digest()


def test_drift_reference_calibrated_holds_its_rate_where_the_configured_multiple_does_not() -> None:
    """Student-t (3 dof) scores: 2.5 flags ~2.8 % of them; the 2 % quantile of one sample flags 2 % of another."""
    det = DriftReferenceDetector(StackConfig())
    other = _rows(20000, 2)
    configured = float(np.mean(det.scores(other) > det.threshold))
    assert configured > 0.025
    assert calibrate(det, _rows(4000, 1), 0.02)
    assert det.threshold == det.threshold_z > 2.5 and det.thresholds["calibrated_z"] == det.threshold
    fpr = float(np.mean(det.scores(other) > det.threshold))
    assert 0.015 < fpr < 0.025
    # decide flags exactly where scores beat the threshold: |z| > h and |x| > t1_m·h/2.5
    flags = np.array([det.decide(r).flagged for r in other[:3000]])
    np.testing.assert_array_equal(flags, det.scores(other[:3000]) > det.threshold)
    h = det.threshold
    expect = (np.abs(other[:3000, Z]) > h) & (np.abs(other[:3000, X]) > 9.0 * h / 2.5)
    np.testing.assert_array_equal(flags, expect)


def test_too_few_rows_keep_the_trained_threshold_and_the_floor_holds() -> None:
    det = DriftReferenceDetector(StackConfig())
    assert not calibrate(det, _rows(MIN_ROWS - 1, 3), 0.02)
    assert det.threshold == 2.5
    tight = _rows(1000, 4)
    tight[:, X] = 0.1                                   # no residual beyond any metres floor: a quantile of 0
    assert calibrate(det, tight, 0.02) and det.threshold == Z_FLOOR


class _Plain:
    """A detector whose score is its first column, flagged above ``threshold``."""

    name = "plain"
    threshold = 10.0

    def scores(self, features: np.ndarray) -> np.ndarray:
        return np.asarray(features, float)[:, 0]


def test_any_detector_with_a_threshold_gets_the_quantile_of_its_scores() -> None:
    det = _Plain()
    rows = np.arange(1000, dtype=float).reshape(-1, 1)
    assert calibrate(det, rows, 0.02)      # type: ignore[arg-type]
    assert det.threshold == 979.0          # 20 of the 1000 scores above it


def test_the_method_table_marks_drift_reference_calibrated() -> None:
    assert METHOD_TABLE["drift_reference"].calibrated
    assert not METHOD_TABLE["chi_square"].calibrated


def test_a_threshold_calibrated_on_one_simulated_trial_holds_on_another() -> None:
    """Seed 41's normal epochs after t_a set h; seed 42's closed-loop false-alarm rate lands within 0.5-4 %.

    1000 s trials with a 400 s window: about 230 normal epochs on each side, so the band is wide.
    """
    cfg = load_config(None, ["methods=chi_square,drift_reference"])          # calibrated: the default
    cfg = replace(cfg, stack=replace(cfg.stack, training_window_s=400.0, training_source="given"))
    ts = training_set_of(TrialSpec(41, None, 1000.0), cfg)
    assert ts.calibration.shape[0] >= MIN_ROWS
    scores = evaluate_trial(TrialSpec(42, None, 1000.0), cfg, ts)
    fpr = closed_loop_fpr([scores], "drift_reference")
    assert fpr is not None and 0.005 <= fpr <= 0.04, fpr


if __name__ == "__main__":
    pytest.main([__file__])
