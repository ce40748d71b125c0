"""The scoreboard shows metrics.json's figures unchanged, ranked; runs are named by what differs."""

from __future__ import annotations

from replay.review.naming import run_labels
from replay.review.scoreboard import format_value, method_kind, scoreboard, verdict, window_text


def _metrics() -> dict:
    return {"window": [600.0, 1700.0], "methods": {
        "ckf": {"error_p50_m": 7.9, "error_p90_m": 69.2, "error_rms_m": 30.0, "tp": None},
        "kmcdf2": {"error_p50_m": 1.9, "error_p90_m": 4.0, "error_rms_m": 2.5},
        "chi_square": {"error_p50_m": 5.4, "error_p90_m": 13.5, "tp": 23, "fp": 17, "fn": 34, "fpr": 0.04,
                       "fnr": 0.6, "auc": 0.88},
        "lms": {"error_p50_m": None, "error_p90_m": None},
    }}


def test_rows_are_ranked_by_p50_in_their_group_with_metrics_figures_unchanged() -> None:
    metrics = _metrics()
    rows = scoreboard(metrics)
    # cooperative estimates and USBL positioning are scored on different epochs: each group ranked on its own
    assert [r.method for r in rows] == ["chi_square", "ckf", "kmcdf2", "lms"]
    assert [r.rank for r in rows] == [1, 2, 1, 2]
    assert [r.group for r in rows] == ["cooperative", "cooperative", "positioning", "positioning"]
    for row in rows:
        for key, value in row.figures.items():
            assert value == metrics["methods"][row.method].get(key)
    assert [r.kind for r in rows] == ["detector", "filter", "positioning", "positioning"]


def test_the_verdict_names_the_best_of_each_group_and_the_best_detector() -> None:
    lines = verdict({**_metrics(), "epochs": 462, "anomalous": 57})
    assert lines == ["Best position estimate: **chi_square**, p50 5.400 m, p90 13.500 m",
                     "Best USBL positioning: **kmcdf2**, p50 1.900 m, p90 4.000 m",
                     "Best detector: **chi_square**, 17 false alarms, 34 misses, AUC 0.880 (462 scored epochs, "
                     "57 anomalous)",
                     "Scored after t_a: 600 s to 1700 s (mission seconds)"]


def test_kinds_window_and_values_read_as_printed() -> None:
    assert method_kind("anfis") == "detector" and method_kind("dead_reckoning") == "filter"
    assert window_text(_metrics()) == "after t_a: 600 s to 1700 s (mission seconds)"
    assert [format_value(v) for v in (None, 0.12345, 1555.0, 7)] == ["-", "0.123", "1555.0", "7"]


def test_runs_are_named_by_what_differs_in_their_configuration() -> None:
    a = {"stack": {"r_m": 3.0, "anfis": {"model": "per_leader", "epochs": 100}}, "engine": {"lag_s": 5.0}}
    b = {"stack": {"r_m": 2.5, "anfis": {"model": "per_leader", "epochs": 100}}, "engine": {"lag_s": 5.0}}
    assert run_labels([a, b]) == ["r_m=3", "r_m=2.5"]
    assert run_labels([a, a]) == ["defaults", "defaults #2"]
    c = {"stack": {"seed": 1}, "engine": {"seed": 2}}
    d = {"stack": {"seed": 3}, "engine": {"seed": 2}}
    assert run_labels([c, d]) == ["stack.seed=1", "stack.seed=3"]
    e = {"stack": {"seed": 1}, "engine": {"seed": 4}}
    assert run_labels([c, e]) == ["engine.seed=2", "engine.seed=4"]
