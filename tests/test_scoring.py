"""Confusion rates (A.36-A.40), ROC / AUC / recall at FPR, horizontal errors, and the result dict."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.geodesy import metric_scales_scalar
from replay.stack import scoring
from replay.stack.runner import RunResults, Track

LAT, LON = 0.8, 2.2
B0, A0 = metric_scales_scalar(LAT, 0.0)


def test_confusion_ignores_unknown_labels() -> None:
    flagged = np.array([1, 1, 0, 0, 1, 0], dtype=bool)
    lab = np.array([1, 0, 1, 0, -1, -1])
    assert scoring.confusion(flagged, lab) == scoring.Confusion(tp=1, tn=1, fp=1, fn=1)


def test_rates_reproduce_paper_a_table() -> None:
    """A's ANFIS row (TP 47, TN 401, FP 4, FN 10) and its chi-square row give the paper's ratios."""
    r = scoring.Confusion(47, 401, 4, 10).rates()
    assert math.isclose(r["accuracy"], 448 / 462) and math.isclose(r["precision"], 47 / 51)
    assert math.isclose(r["recall"], 47 / 57) and math.isclose(r["fpr"], 4 / 405) and math.isclose(r["fnr"], 10 / 57)
    chi = scoring.Confusion(23, 388, 17, 34).rates()
    # A: FPR and FNR reduced by 76.4 % and 70.6 % against the chi-square test
    assert round(100 * (1 - r["fpr"] / chi["fpr"]), 1) == 76.5       # A prints 76.4 (truncated)
    assert round(100 * (1 - r["fnr"] / chi["fnr"]), 1) == 70.6


def test_rates_undefined_are_none() -> None:
    r = scoring.Confusion(0, 5, 0, 0).rates()
    assert r["precision"] is None and r["recall"] is None and r["fnr"] is None
    assert r["accuracy"] == 1.0 and r["fpr"] == 0.0


def test_roc_perfect_reversed_and_tied() -> None:
    lab = np.array([0, 0, 1, 1])
    fpr, tpr, thr = scoring.roc_curve(lab, np.array([0.1, 0.2, 0.8, 0.9]))
    assert scoring.roc_auc(fpr, tpr) == 1.0 and thr[0] == np.inf
    assert scoring.recall_at_fpr(fpr, tpr, 0.0) == 1.0
    fpr, tpr, _ = scoring.roc_curve(lab, np.array([0.9, 0.8, 0.2, 0.1]))
    assert scoring.roc_auc(fpr, tpr) == 0.0
    fpr, tpr, _ = scoring.roc_curve(lab, np.ones(4))
    assert scoring.roc_auc(fpr, tpr) == 0.5
    assert scoring.recall_at_fpr(fpr, tpr, 0.05) == 0.0
    empty = scoring.roc_curve(np.zeros(3), np.ones(3))
    assert empty[0].size == 0 and scoring.roc_auc(*empty[:2]) is None and scoring.recall_at_fpr(*empty[:2], 0.1) is None


def test_roc_unknown_labels_and_nan_scores() -> None:
    fpr, tpr, _ = scoring.roc_curve(np.array([1, 0, -1, 1, 0]), np.array([np.nan, 0.5, 9.0, 2.0, 0.1]))
    # positives: nan (never flags), 2.0; negatives 0.5, 0.1
    np.testing.assert_allclose(fpr, [0, 0, 0.5, 1.0, 1.0])
    np.testing.assert_allclose(tpr, [0, 0.5, 0.5, 0.5, 1.0])


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.integers(0, 5)), min_size=2, max_size=40))
def test_auc_is_the_mann_whitney_probability(pairs: list[tuple[bool, int]]) -> None:
    lab = np.array([int(p) for p, _ in pairs])
    s = np.array([float(v) for _, v in pairs])
    fpr, tpr, _ = scoring.roc_curve(lab, s)
    if lab.min() == lab.max():
        assert fpr.size == 0
        return
    pos, neg = s[lab == 1], s[lab == 0]
    u = (pos[:, None] > neg[None, :]).mean() + 0.5 * (pos[:, None] == neg[None, :]).mean()
    assert abs(scoring.roc_auc(fpr, tpr) - u) < 1e-12
    assert np.all(np.diff(fpr) >= 0) and np.all(np.diff(tpr) >= 0) and fpr[-1] == 1.0 and tpr[-1] == 1.0


def test_recall_at_fpr_picks_best_point_under_target() -> None:
    fpr = np.array([0.0, 0.0, 0.04, 0.06, 0.2, 1.0])
    tpr = np.array([0.0, 0.3, 0.5, 0.8, 0.9, 1.0])
    assert scoring.recall_at_fpr(fpr, tpr, 0.01) == 0.3
    assert scoring.recall_at_fpr(fpr, tpr, 0.05) == 0.5
    assert scoring.recall_at_fpr(fpr, tpr, 0.10) == 0.8


def test_horizontal_errors_interpolate_and_window() -> None:
    t = np.array([0.0, 10.0, 10.0, 20.0])
    lat = LAT + np.array([0.0, 0.0, 10.0, 10.0]) / B0            # a 10 m jump north at t = 10 (the update)
    lon = np.full(4, LON)
    gps_t = np.array([5.0, 10.0, 15.0, 25.0])
    err = scoring.horizontal_errors(t, lat, lon, gps_t, np.full(4, LAT), np.full(4, LON))
    # at t = 10 the last record (after the update) wins, so t = 5 sits half-way; 25 s is outside the track
    np.testing.assert_allclose(err, [5.0, 10.0, 10.0], atol=1e-6)
    err = scoring.horizontal_errors(t, lat, lon, gps_t, np.full(4, LAT), np.full(4, LON), window=(12.0, 30.0))
    np.testing.assert_allclose(err, [10.0], atol=1e-6)


def test_error_stats_and_cdf() -> None:
    e = np.arange(1.0, 11.0)
    st_ = scoring.error_stats(e)
    assert st_["error_p50_m"] == 5.5 and math.isclose(st_["error_p90_m"], 9.1)
    assert math.isclose(st_["error_rms_m"], math.sqrt(np.mean(e ** 2)))
    assert scoring.error_stats(np.empty(0))["error_rms_m"] is None
    x, f = scoring.empirical_cdf(e[::-1])
    np.testing.assert_array_equal(x, e)
    assert f[0] == 0.1 and f[-1] == 1.0


def _results() -> RunResults:
    """A two-method, four-epoch RunResults built by hand."""
    track = Track(np.array([0.0, 100.0]), np.full(2, LAT), np.full(2, LON), np.zeros((2, 2, 2)))
    epochs = {
        "time_s": np.array([5.0, 5.0, 20.0, 20.0, 30.0, 30.0, 40.0, 40.0]),
        "method": np.array(["ckf", "chi_square"] * 4),
        "flagged": np.array([False, True, False, True, False, False, False, True]),
        "label": np.array([1, 1, 1, 1, 0, 0, 0, 0], dtype=np.int8),
    }
    open_loop = {"chi_square": {"time_s": np.array([20.0, 30.0, 40.0]), "leader": np.array(["a"] * 3),
                                "label": np.array([1, 0, 0], dtype=np.int8), "score": np.array([9.0, 1.0, 7.0])}}
    return RunResults(("ckf", "chi_square"), ("a",), 0.0, 10.0, epochs, {"ckf": track, "chi_square": track},
                      open_loop, {}, {"ckf": 0, "chi_square": 2}, 0, True, {})


def test_score_run_has_the_design_keys() -> None:
    out = scoring.score_run(_results(), np.array([15.0, 50.0]), np.full(2, LAT + 3.0 / B0), np.full(2, LON))
    assert set(scoring.RESULT_KEYS) <= set(out["ckf"]) and set(scoring.RESULT_KEYS) <= set(out["chi_square"])
    assert all(out["ckf"][k] is None for k in scoring.RESULT_KEYS[:11])
    chi = out["chi_square"]
    assert (chi["tp"], chi["tn"], chi["fp"], chi["fn"]) == (1, 1, 1, 0)          # the epoch at t = 5 is training
    assert chi["auc"] == 1.0 and chi["recall_at_fpr_5"] == 1.0 and chi["capped"] == 2
    assert math.isclose(chi["error_p50_m"], 3.0, rel_tol=1e-6)
