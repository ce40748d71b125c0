"""The focus set: the best of each scoreboard group, chi-square and ANFIS shown at first; the rest hidden."""

from __future__ import annotations

import rerun.blueprint as rrb

from replay.views.common import make_runs
from replay.views.focus import default_focus, focus_note, hidden_methods, hide
from tests.review_fixtures import synthetic_review


def _metrics() -> dict:
    return {"window": [600.0, 1700.0], "methods": {
        "ckf": {"error_p50_m": 7.9, "error_p90_m": 69.2},
        "anfis_hybrid": {"error_p50_m": 4.9, "error_p90_m": 14.8, "fp": 10, "fn": 13},
        "kmcdf2": {"error_p50_m": 1.9, "error_p90_m": 3.3},
        "gar": {"error_p50_m": 2.1, "error_p90_m": 3.9},
        "chi_square": {"error_p50_m": 5.4, "error_p90_m": 13.5, "fp": 9, "fn": 19},
    }}


def test_the_default_focus_is_the_best_of_each_group_and_the_two_references() -> None:
    # anfis_hybrid is the best cooperative estimate and the best detector (10 + 13 wrong against 9 + 19)
    assert default_focus(_metrics()) == ("anfis_hybrid", "kmcdf2", "chi_square", "anfis")
    metrics = _metrics()
    metrics["methods"]["drift_reference"] = {"error_p50_m": 5.2, "error_p90_m": 11.8, "fp": 10, "fn": 8}
    assert default_focus(metrics) == ("anfis_hybrid", "kmcdf2", "drift_reference", "chi_square", "anfis")
    assert default_focus({"methods": {}}) == ("chi_square", "anfis")


def test_out_of_focus_methods_are_hidden_by_visibility_and_all_shows_them() -> None:
    review = synthetic_review(3, n_epochs=30, anfis_epochs=2)
    (run,) = make_runs([review])
    drawn = set(review.tracks["source"].astype(str)) | set(review.errors["method"].astype(str))
    hidden = hidden_methods(run, None)
    shown = set(default_focus(review.metrics))
    assert hidden and not set(hidden) & shown and set(hidden) <= drawn
    assert "gps" not in hidden                               # the truth is always drawn
    overrides = hide([run], None, "map")
    assert overrides and all(isinstance(v, rrb.EntityBehavior) for v in overrides.values())
    assert {str(k).split("/")[-2] for k in overrides} == set(hidden) & set(review.tracks["source"].astype(str))
    assert {str(k).split("/")[-1] for k in overrides} == {"track", "position", "trail"}
    assert hidden_methods(run, ("all",)) == [] and hide([run], ("all",), "error") == {}
    assert focus_note([run], ("all",)) == ""
    assert focus_note([run], None) == f"{len(hidden)} more methods hidden (view --focus all)"
    named = hidden_methods(run, ("ckf",))
    assert "ckf" not in named and "ins" not in named          # a named focus hides only methods, never sources
