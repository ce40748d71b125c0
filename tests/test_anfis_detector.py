"""ANFIS detector and compensator: thresholds, normalization, decisions, views, per-leader/shared."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from replay.stack.config import AnfisConfig, StackConfig
from replay.stack.detectors import anfis as A
from replay.stack.detectors.anfis_detector import AnfisDetector, detectors_for, threshold_from_rule
from replay.stack.detectors.base import Detector


def lake_like(n: int, seed: int, sign: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features [|r|, r^2/Pzz, R*] and signed range error: ~3 m noise, blocks of 15-50 m errors."""
    rng = np.random.default_rng(seed)
    err = rng.normal(0.0, 3.0, n)
    bad = np.zeros(n, dtype=bool)
    for start in range(7, n - 6, 25):
        bad[start:start + 4] = True
        err[start:start + 4] = sign * rng.uniform(15.0, 50.0)
    r = err + rng.normal(0.0, 1.0, n)
    pzz = 9.0 + rng.uniform(1.0, 4.0, n)
    f2 = r ** 2 / pzz
    return np.column_stack([np.abs(r), f2, 9.0 * np.maximum(1.0, f2)]), err, bad


def config(**anfis: object) -> StackConfig:
    """StackConfig with some AnfisConfig fields replaced."""
    return StackConfig(anfis=dataclasses.replace(AnfisConfig(), **anfis))


@pytest.fixture(scope="module")
def trained() -> AnfisDetector:
    x, err, bad = lake_like(150, 1)
    det = AnfisDetector(StackConfig())
    det.train(x, err, bad.astype(int))
    return det


def test_threshold_rules() -> None:
    assert threshold_from_rule("3sigma", 2.0, 9.0) == 6.0
    assert threshold_from_rule("2.5sigma", 2.0, 9.0) == 5.0
    assert threshold_from_rule(" 4 SIGMA ", 0.5, 9.0) == 2.0
    assert threshold_from_rule("t1", 2.0, 9.0) == 9.0
    for bad in ("sigma3", "3", "", "-1sigma"):
        with pytest.raises(ValueError):
            threshold_from_rule(bad, 1.0, 9.0)
    with pytest.raises(ValueError):
        AnfisDetector(config(threshold_rule="three"))
    with pytest.raises(ValueError):
        AnfisDetector(StackConfig(), trainer="adam")


def test_names() -> None:
    assert AnfisDetector(StackConfig()).name == "anfis"
    assert AnfisDetector(StackConfig(), "aqpso_ga").name == "anfis_aqpso"
    assert AnfisDetector(StackConfig(), "aqpso_ga", compensation=True).name == "anfis_compensation"
    det: Detector = AnfisDetector(StackConfig())        # satisfies the runner's protocol
    assert det.name == "anfis"


def test_training_sets_bounds_sigma_and_t2(trained: AnfisDetector) -> None:
    x, err, _ = lake_like(150, 1)
    np.testing.assert_allclose(trained.input_min, x.min(axis=0))
    np.testing.assert_allclose(trained.input_max, x.max(axis=0))
    assert trained.model is not None and trained.model.n_rules == 8
    recomputed = A.rmse(trained.model, A.normalize(x, trained.input_min, trained.input_max), np.abs(err))
    assert trained.sigma == pytest.approx(recomputed, rel=1e-9)
    assert trained.threshold == pytest.approx(3.0 * trained.sigma)
    assert trained.training_samples == 150 and trained.training_anomalies == 24


def test_detects_the_big_errors_on_new_data(trained: AnfisDetector) -> None:
    x, _, bad = lake_like(300, 2)
    flagged = trained.scores(x) > trained.threshold
    assert flagged[bad].mean() == 1.0                   # every 15-50 m error caught
    t1 = AnfisDetector(config(threshold_rule="t1"))
    x0, e0, b0 = lake_like(150, 1)
    t1.train(x0, e0, b0.astype(int))
    assert t1.threshold == 9.0
    flagged_t1 = t1.scores(x) > 9.0
    assert flagged_t1[bad].mean() == 1.0 and flagged_t1[~bad].mean() < 0.05


def test_decide_agrees_with_scores(trained: AnfisDetector) -> None:
    x, _, _ = lake_like(40, 3)
    scores = trained.scores(x)
    for row, score in zip(x, scores):
        d = trained.decide(row)
        assert d.score == pytest.approx(score, rel=1e-12)
        assert d.flagged == (score > trained.threshold) and d.threshold == trained.threshold
        assert d.correction_m == 0.0


def test_online_inputs_are_clipped_to_the_training_range(trained: AnfisDetector) -> None:
    top = trained.input_max
    far = trained.input_max * 50.0
    below = trained.input_min - 100.0
    s = trained.scores(np.vstack([top, far, trained.input_min, below]))
    assert s[0] == pytest.approx(s[1], rel=1e-12) and s[2] == pytest.approx(s[3], rel=1e-12)


def test_nan_features_and_untrained_never_flag() -> None:
    det = AnfisDetector(StackConfig())
    d = det.decide(np.array([1.0, 2.0, 3.0]))
    assert not d.flagged and np.isnan(d.score)
    x, err, bad = lake_like(60, 4)
    x[5] = np.nan
    err[6] = np.inf
    det.train(x, err, bad.astype(int))
    assert det.training_samples == 58 and det.trained
    d = det.decide(np.array([np.nan, 1.0, 9.0]))
    assert not d.flagged and np.isnan(d.score)
    empty = AnfisDetector(StackConfig())
    empty.train(np.empty((0, 3)), np.empty(0), np.empty(0))
    assert not empty.trained and not empty.decide(np.ones(3)).flagged
    empty.reset()


def test_compensation_predicts_the_signed_error_and_corrects() -> None:
    x, err, bad = lake_like(150, 5, sign=-1.0)
    det = AnfisDetector(StackConfig(), compensation=True)
    det.train(x, err, bad.astype(int))
    assert det.threshold == 9.0
    xt, et, bt = lake_like(200, 6, sign=-1.0)
    decisions = [det.decide(row) for row in xt]
    flagged = np.array([d.flagged for d in decisions])
    corr = np.array([d.correction_m for d in decisions])
    assert flagged[bt].mean() == 1.0 and flagged[~bt].mean() < 0.05
    assert np.all(corr[flagged] < -9.0)                 # the learned error is negative
    assert np.all(corr[~flagged] == 0.0)
    # the corrected range is far closer to the truth than the raw one on anomalous epochs
    assert np.sqrt(np.mean((et[bt] - corr[bt]) ** 2)) < 0.25 * np.sqrt(np.mean(et[bt] ** 2))
    np.testing.assert_allclose(det.scores(xt), np.abs(det.predict(xt)))


def test_aqpso_trainer_uses_config_and_is_reproducible() -> None:
    x, err, bad = lake_like(120, 7)
    cfg = config(particles=10, iterations=12, seed=3)
    d1, d2 = AnfisDetector(cfg, "aqpso_ga"), AnfisDetector(cfg, "aqpso_ga")
    d1.train(x, err, bad.astype(int))
    d2.train(x, err, bad.astype(int))
    assert d1.history is not None and d1.history.epochs == 13
    assert d1.sigma == d2.sigma and d1.threshold == pytest.approx(3.0 * d1.sigma)


def test_explain(trained: AnfisDetector) -> None:
    x, _, _ = lake_like(10, 8)
    one = trained.explain(x[0])
    assert one.memberships.shape == (3, 2) and one.firing.shape == (8,)
    assert one.normalized_firing.sum() == pytest.approx(1.0)
    assert float(one.output) == pytest.approx(trained.scores(x[:1])[0])
    many = trained.explain(x)
    assert many.normalized_inputs.shape == (10, 3) and many.rule_outputs.shape == (10, 8)
    np.testing.assert_allclose(many.output, trained.scores(x))
    assert np.all((many.normalized_inputs >= 0.0) & (many.normalized_inputs <= 1.0))


@pytest.mark.parametrize("structure", ["grid", "diagonal"])
def test_explain_rows_is_explain_one_row_at_a_time_bit_for_bit(structure: str) -> None:
    """The review's stacked explanations equal, element for element and bit for bit, one `explain` per row: lake-like
    rows, rows outside the training range (clipped), a NaN feature and huge values, for both rule structures."""
    x, err, bad = lake_like(150, 3)
    det = AnfisDetector(config(rule_structure=structure, epochs=30))
    det.train(x, err, bad.astype(int))
    rows, _, _ = lake_like(60, 9)
    rows = np.vstack([rows, [[1e9, 1e12, 1e9], [0.0, 0.0, 0.0], [np.nan, 1.0, 9.0], [-5.0, 3.0, 9.0]]])
    many = det.explain_rows(rows)
    for k, row in enumerate(rows):
        one = det.explain(row)
        for field in ("normalized_inputs", "memberships", "firing", "normalized_firing", "rule_outputs", "output"):
            np.testing.assert_array_equal(getattr(many, field)[k], getattr(one, field), err_msg=f"{field} row {k}")
    with pytest.raises(RuntimeError):
        AnfisDetector(StackConfig()).explain_rows(rows)


def test_snapshots(trained: AnfisDetector) -> None:
    snaps = trained.snapshots()
    assert len(snaps) == 100 and [s.epoch for s in snaps[:3]] == [0, 1, 2]
    assert all(np.isnan(s.threshold) for s in snaps)
    assert snaps[0].consequents.shape == (8, 4) and snaps[0].inputs == 3
    final = trained.snapshot()
    assert final.threshold == trained.threshold and final.training_rmse == trained.sigma
    assert final.epoch == trained.result.best_epoch and final.trainer == "hybrid"
    np.testing.assert_array_equal(final.a, snaps[final.epoch].a)
    assert final.rule_structure == "grid" and final.mfs_per_input == 2
    # epoch 0 is the genfis1 start over the normalized range
    np.testing.assert_allclose(snaps[0].c, [[0.0, 1.0]] * 3)
    np.testing.assert_allclose(snaps[0].a, 0.5)


def test_detectors_for_per_leader_and_shared() -> None:
    per = detectors_for(StackConfig(), ["leader1", "leader2"])
    assert per["leader1"] is not per["leader2"]
    shared = detectors_for(config(model="shared"), ["leader1", "leader2"], "aqpso_ga")
    assert shared["leader1"] is shared["leader2"] and shared["leader1"].name == "anfis_aqpso"
    with pytest.raises(ValueError):
        detectors_for(config(model="pooled"), ["leader1"])


def test_diagonal_structure_from_config() -> None:
    x, err, bad = lake_like(100, 9)
    det = AnfisDetector(config(rule_structure="diagonal", mfs_per_input=3, epochs=20))
    det.train(x, err, bad.astype(int))
    assert det.model is not None and det.model.n_rules == 3
    assert det.snapshot().rule_structure == "diagonal"


def test_surface(trained: AnfisDetector) -> None:
    u, v, z = trained.surface((0, 1), fixed=0.0, resolution=5)
    assert z.shape == (5, 5) and u[0] == 0.0 and v[-1] == 1.0
    corner = trained.input_min + (trained.input_max - trained.input_min) * np.array([1.0, 0.0, 0.0])
    assert z[-1, 0] == pytest.approx(trained.scores(corner[None])[0], rel=1e-9)
