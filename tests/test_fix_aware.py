"""The fix_aware detector: chi-square's test with a fresh USBL fix, drift_reference's without, on rows and on a trial."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.run.config import load_config
from replay.run.evaluate import TrialSpec, evaluate_trial, training_set_of
from replay.run.matrix import _config
from replay.stack.config import StackConfig
from replay.stack.detectors.chi_square import chi_square_threshold
from replay.stack.detectors.drift_reference import DriftReferenceDetector
from replay.stack.detectors.fix_aware import FRESH_POWER, FixAwareDetector
from replay.stack.features import FEATURE_NAMES
from replay.stack.methods import METHOD_TABLE, why_line
from replay.stack.running_threshold import RunningThreshold
from replay.stack.scoring import roc_auc, roc_curve
from samples.scenario import AnomalyEvent, Scenario

F2, USBL, RES, Z = (FEATURE_NAMES.index(n) for n in ("f2", "usbl_residual_m", "drift_residual_m", "drift_z"))


def _trained(seed: int = 0) -> tuple[FixAwareDetector, DriftReferenceDetector]:
    """Both detectors trained on the same rows: normal residuals of 3 m spread and a few drifted ones."""
    rng = np.random.default_rng(seed)
    x = np.full((400, len(FEATURE_NAMES)), np.nan)
    x[:, F2] = rng.chisquare(1, 400)
    x[:, RES] = rng.normal(0, 3, 400)
    x[:, Z] = x[:, RES] / 3
    labels = (np.abs(x[:, RES]) > 9).astype(np.int8)
    fa, dr = FixAwareDetector(StackConfig()), DriftReferenceDetector(StackConfig())
    fa.train(x, x[:, RES], labels)
    dr.train(x, x[:, RES], labels)
    return fa, dr


row_values = st.tuples(st.floats(0, 400), st.floats(-60, 60), st.one_of(st.just(math.nan), st.floats(-20, 20)),
                       st.one_of(st.just(math.nan), st.floats(-40, 40)))


@settings(max_examples=200, deadline=None)
@given(st.lists(row_values, min_size=1, max_size=30))
def test_a_fresh_fix_gives_chi_squares_test_and_none_gives_drift_references(values: list[tuple[float, ...]]) -> None:
    fa, dr = _trained()
    x = np.full((len(values), len(FEATURE_NAMES)), np.nan)
    x[:, [F2, RES, Z, USBL]] = np.array(values)
    gate = chi_square_threshold(StackConfig().chi_square_alpha)
    fresh = np.isfinite(x[:, USBL])
    s = fa.scores(x)
    assert np.array_equal(s[~fresh], dr.scores(x[~fresh]), equal_nan=True)
    assert np.allclose(s[fresh], 2.5 * (x[fresh, F2] / gate) ** FRESH_POWER)
    for row, fr in zip(x, fresh):
        d = fa.decide(row)
        if fr:     # flagged exactly where chi-square flags, whatever the drift residual says
            assert d.flagged == (row[F2] > gate) and d.threshold == 2.5
        else:
            assert d == dr.decide(row)


def test_it_trains_drift_references_metres_threshold_and_reports_the_gate() -> None:
    fa, dr = _trained()
    assert fa.threshold_m == dr.threshold_m >= 9.0 and fa.threshold == fa.threshold_z == 2.5
    assert fa.thresholds["chi_square_gate"] == pytest.approx(6.635, abs=1e-3)
    entry = METHOD_TABLE["fix_aware"]
    assert entry.detects and entry.wide and not entry.default and entry.pooled_training


# ---------------------------------------------------------------------------- on a small simulated trial

DRIFT = AnomalyEvent(leader="leader1", kind="drift", start_s=480.0, end_s=550.0, magnitude_m=35.0)
METHODS = ("chi_square", "drift_reference", "fix_aware")


@pytest.fixture(scope="module")
def trials() -> dict[bool, dict[str, dict[str, np.ndarray]]]:
    """Seed 1 (700 s, a 0.5 m/s drift in its scored part) trained on seed 0, without and with USBL fixes."""
    base = replace(Scenario(), anomalies=(DRIFT,))
    cfg = load_config(None, ["training_window_s=400", f"methods={','.join(METHODS)}"])
    out = {}
    for usbl in (False, True):
        c = _config(cfg, usbl)
        given_set = training_set_of(TrialSpec(0, None, 700.0, base), c)
        scores = evaluate_trial(TrialSpec(1, None, 700.0, base), c, given_set)
        out[usbl] = {m: {"label": scores.open_labels[m], "score": scores.open_scores[m]} for m in METHODS}
    return out


def _auc(o: dict[str, np.ndarray]) -> float:
    auc = roc_auc(*roc_curve(o["label"], o["score"])[:2])
    assert auc is not None
    return auc


def test_on_a_trial_it_separates_the_drift_as_the_test_its_fix_age_picks(
        trials: dict[bool, dict[str, dict[str, np.ndarray]]]) -> None:
    no_fix, fixes = trials[False], trials[True]
    for o in (no_fix, fixes):
        assert int(np.sum(o["fix_aware"]["label"] == 1)) >= 5     # the drift's anomalous epochs are scored
    # without fixes it is drift_reference, trained on the other trial
    assert np.array_equal(no_fix["fix_aware"]["score"], no_fix["drift_reference"]["score"], equal_nan=True)
    assert _auc(no_fix["fix_aware"]) > 0.9
    # with fixes every scored epoch has a fresh one: chi-square's ranking, on the h_z scale
    gate = chi_square_threshold(StackConfig().chi_square_alpha)
    assert np.allclose(fixes["fix_aware"]["score"], 2.5 * (fixes["chi_square"]["score"] / gate) ** FRESH_POWER)
    assert _auc(fixes["fix_aware"]) == pytest.approx(_auc(fixes["chi_square"])) and _auc(fixes["fix_aware"]) > 0.9
    # and the drifted epochs score above nearly every normal one in both
    for o in (no_fix["fix_aware"], fixes["fix_aware"]):
        normal, drift = o["score"][o["label"] == 0], o["score"][o["label"] == 1]
        assert np.median(drift) > np.quantile(normal[np.isfinite(normal)], 0.95)


def test_its_why_line_names_the_test_that_decided() -> None:
    from replay.events import EpochResult
    fa, _ = _trained()
    base = EpochResult(900.0, "leader1", "fix_aware", True, 3.1, 2.5, 5.0, 9.8, 9.0, 1, True, False, False,
                       500.0, 495.0, 0.8, 2.2, 1.0, 0.0, 1.0, drift_z=0.4, drift_residual_m=1.2,
                       usbl_residual_m=4.0)
    assert why_line(base, fa).startswith("fresh USBL fix: f2 9.80 > gate 6.63")
    quiet = base._replace(usbl_residual_m=math.nan, flagged=False, score=0.4)
    assert why_line(quiet, fa).startswith("no fresh fix: score 0.40 <= h 2.50 sd")


def test_calibration_sets_each_part_on_its_own_rows() -> None:
    """Without a fresh fix drift_reference's h flags 2 % of those rows; with one the gate flags 2 % of f2."""
    rng = np.random.default_rng(3)
    x = np.full((1000, len(FEATURE_NAMES)), np.nan)
    x[:, F2] = rng.chisquare(1, 1000) * 2.0            # an f2 twice chi-square's: the fixed gate flags ~9 %
    x[:, RES] = rng.normal(0, 6, 1000)
    x[:, Z] = x[:, RES] / 2.0                           # a drift_z wider than its scale says
    x[500:, USBL] = 1.0                                 # half the rows with a fresh fix
    fa, dr = _trained()
    assert METHOD_TABLE["fix_aware"].calibrated
    assert fa.calibrate(x, 0.02)
    assert dr.calibrate(x[:500], 0.02)
    assert fa.threshold == dr.threshold > 2.5 and fa.drift.threshold_z == dr.threshold_z
    s = fa.scores(x)
    assert np.mean(s[:500] > fa.threshold) == pytest.approx(0.02, abs=0.003)
    assert np.mean(s[500:] > fa.threshold) == pytest.approx(0.02, abs=0.003)
    assert fa.gate == fa.thresholds["chi_square_gate"] > chi_square_threshold(0.01)
    assert fa.decide(x[700]).flagged == bool(x[700, F2] > fa.gate)


def test_a_part_with_too_few_rows_keeps_its_threshold() -> None:
    """All rows without a fix (a trial without USBL): the gate stays chi-square's; none with: h stays 2.5."""
    rng = np.random.default_rng(4)
    x = np.full((400, len(FEATURE_NAMES)), np.nan)
    x[:, F2] = rng.chisquare(1, 400) * 2.0
    x[:, RES] = rng.normal(0, 6, 400)
    x[:, Z] = x[:, RES] / 2.0
    fa, _ = _trained()
    assert fa.calibrate(x, 0.02) and fa.gate == chi_square_threshold(0.01) and fa.threshold > 2.5
    x[:, USBL] = 0.5
    fa, _ = _trained()
    assert fa.calibrate(x, 0.02) and fa.threshold == 2.5 and fa.gate > chi_square_threshold(0.01)
    assert not fa.calibrate(x[:100], 0.02)


def test_under_a_fresh_fix_the_running_thresholds_band_and_step_on_f2_are_set_by_the_power() -> None:
    """The cut on f2 is gate·g^(1/p), a marginal exceedance is f2 within 1.3^(1/p) of it, and a step moves it by gain/p."""
    config = StackConfig()
    fa, _ = _trained()
    row = np.full(len(FEATURE_NAMES), np.nan)
    row[USBL] = 1.0
    band_f2 = config.running_threshold_band ** (1.0 / FRESH_POWER)
    cases = (((1.0 + band_f2) / 2, True), (band_f2 * 1.05, False), (0.9, False))   # f2 / gate -> marginal?
    for ratio, marginal in cases:
        rt = RunningThreshold(config, 1.0)
        row[F2] = ratio * fa.gate
        d = rt.decide(fa.decide(row))
        assert d.flagged == (ratio > 1.0)
        step = config.running_threshold_gain * (float(marginal) - config.running_threshold_share)
        assert rt.g == pytest.approx(math.exp(step))
        # the next cut on f2: gate * g^(1/p), moved by gain/p in log
        assert fa.gate * rt.g ** (1.0 / FRESH_POWER) == pytest.approx(fa.gate * math.exp(step / FRESH_POWER))
        row[F2] = fa.gate * rt.g ** (1.0 / FRESH_POWER) * 1.001
        assert rt.decide(fa.decide(row)).flagged
        row[F2] = fa.gate * rt.g ** (1.0 / FRESH_POWER) * 0.999
        assert not rt.decide(fa.decide(row)).flagged
