"""Detection views: why each detector did (not) flag, the new features by unit, scores against thresholds, lanes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from rerun.chunk import RrdReader

from replay.events import EpochResult
from replay.review.data import ReviewData
from replay.stack.config import StackConfig
from replay.stack.detectors.chi_square import ChiSquareDetector
from replay.stack.detectors.cusum import CusumDriftDetector
from replay.stack.detectors.drift_reference import DriftReferenceDetector
from replay.stack.detectors.dual_threshold import DualThresholdDetector
from replay.stack.detectors.why_text import epoch_features
from replay.stack.features import EXTRA_FEATURES, FEATURE_NAMES
from replay.stack.methods import why_line
from replay.views import recording as views
from replay.views.common import make_runs
from replay.views.features import FEATURE_GROUPS
from replay.views.lanes import detector_order, epoch_states
from tests.review_fixtures import FOLLOWER, LEADERS, synthetic_review
from tests.test_views import Rrd


def _result(method: str, flagged: bool, score: float, threshold: float, f2: float = 1.0, label: int = 0,
            **extra: float) -> EpochResult:
    return EpochResult(100.0, "leader1", method, flagged, score, threshold, 2.0, f2, 9.0, label, flagged, False,
                       False, 500.0, 498.0, 0.1, 0.2, 1.0, 0.0, 1.0, 498.5, **extra)


def test_why_lines_name_each_detectors_statistic_and_threshold() -> None:
    cfg = StackConfig()
    chi = ChiSquareDetector(cfg)
    d = chi.decide(np.array([2.0, 31.0, 9.0]))
    assert why_line(_result("chi_square", d.flagged, d.score, d.threshold, f2=31.0), chi) == "f2 31.00 > gate 6.63"
    assert why_line(_result("chi_square", False, 0.5, 6.63, f2=0.5)) == "f2 0.50 <= gate 6.63"

    dual = DualThresholdDetector(cfg)                # untrained: a zero predicted error, so S stays 0
    d = dual.decide(np.array([2.0, 20.0, 9.0]))
    line = why_line(_result("dual_threshold", d.flagged, d.score, d.threshold, f2=20.0), dual)
    assert line.startswith(f"f2/gate {20.0 / dual.chi2_threshold:.2f}, drift S/h <= ") and line.endswith("> 1 (abrupt)")
    d = dual.decide(np.array([2.0, 1.0, 9.0]))
    line = why_line(_result("dual_threshold", d.flagged, d.score, d.threshold, f2=1.0), dual)
    assert line == f"f2/gate {1.0 / dual.chi2_threshold:.2f}, drift S/h 0.00; max <= 1"

    assert why_line(_result("anfis", True, 6.21, 3.75)) == "output 6.21 m > T2 3.75 m, isolated"
    assert why_line(_result("anfis_compensation", False, 1.0, 9.0)) == "output 1.00 m <= T2 9.00 m"

    cusum = CusumDriftDetector(cfg)
    r = _result("cusum_drift", False, 0.0, cusum.threshold, drift_z=1.7, drift_residual_m=4.0)
    d = cusum.decide(epoch_features(r))
    r = r._replace(flagged=d.flagged, score=d.score)
    expected_s = max(1.7 - cusum.k, 0.0) if cusum.input == "drift_z" else max(4.0 - cusum.k, 0.0)
    line = why_line(r, cusum)
    assert line.startswith(f"S {expected_s:.2f} <= h {cusum.threshold:.2f}")
    assert f"({cusum.input} +{1.7 if cusum.input == 'drift_z' else 4.0:.2f}, k {cusum.k:.2f})" in line

    assert why_line(_result("anfis_hybrid", True, 12.0, 10.4)) == "output 12.00 m > thr 10.40 m"

    dref = DriftReferenceDetector(cfg)
    r = _result("drift_reference", False, 0.0, 0.0, drift_residual_m=-14.5)      # no drift_z yet: metres
    d = dref.decide(epoch_features(r))
    assert why_line(r._replace(flagged=d.flagged, score=d.score, threshold=d.threshold), dref) == \
        f"|drift residual| 14.50 m > h {dref.threshold_m:.2f} m"
    r = _result("drift_reference", False, 0.0, 0.0, drift_residual_m=-14.5, drift_z=-4.2)
    d = dref.decide(epoch_features(r))
    assert d.flagged and d.threshold == dref.threshold_z
    assert why_line(r._replace(flagged=d.flagged, score=d.score, threshold=d.threshold), dref) == \
        f"score {d.score:.2f} > h {dref.threshold_z:.2f} sd (drift_z -4.20, residual -14.5 m, needs > T1 too)"
    assert why_line(_result("dual_threshold", False, math.nan, 1.0)) == "not judged (a feature is missing at this epoch)"


def test_wide_features_follow_feature_names() -> None:
    values = {n: float(i) for i, n in enumerate(EXTRA_FEATURES, start=10)}
    v = epoch_features(_result("cusum_drift", False, 0.0, 1.0, f2=5.0, **values))
    assert v.tolist() == [2.0, 5.0, 9.0, *values.values()] and len(v) == len(FEATURE_NAMES)


def _with_features(review: ReviewData) -> ReviewData:
    """The synthetic review with new features as a run that computes them: drift_z missing before 30 s, no USBL."""
    det = review.detections.copy()
    t = det["t_s"].to_numpy()
    rng = np.random.default_rng(3)
    for f in EXTRA_FEATURES:
        det[f] = rng.normal(0, 5, len(det))
    det["repeat_count"] = (t // 20) % 3
    det["drift_z"] = np.where(t < 30.0, np.nan, det["drift_z"])
    det["usbl_residual_m"] = np.nan
    det["why"] = np.where(t > review.metrics["window"][0], "score " + det["score"].round(2).astype(str), "")
    return ReviewData(**{**review.__dict__, "detections": det})


@pytest.fixture(scope="module")
def featured(tmp_path_factory: pytest.TempPathFactory) -> tuple[ReviewData, Rrd, Path]:
    review = _with_features(synthetic_review(7, n_epochs=40, anfis_epochs=4))
    path = views.save_rrd([review], tmp_path_factory.mktemp("det") / "f.rrd")
    return review, Rrd(path), path


def test_features_drawn_where_finite_in_groups_by_unit(featured: tuple[ReviewData, Rrd, Path]) -> None:
    review, rrd, _ = featured
    det = review.detections
    group_of = {f: key for key, _, names in FEATURE_GROUPS for f in names}
    for leader in LEADERS:
        epochs = det[(det.leader == leader)].drop_duplicates("t_s").sort_values("t_s")
        for f in EXTRA_FEATURES:
            path = f"/run-a/features/{FOLLOWER}/{leader}/{group_of[f]}/{f}"
            finite = epochs[f].dropna()
            assert rrd.rows(path) == len(finite), f
            if len(finite):
                np.testing.assert_allclose([c[0] for c in rrd.cells(path, "Scalars:scalars")], finite)
    note = rrd.static["/run-a/features/note"][0].column("TextDocument:text").to_pylist()[0][0]
    assert "usbl_residual_m" in note and "drift_z" not in note
    for leader in LEADERS:
        assert f"{leader}: standardized (sd)" in rrd.view_names
        assert f"{leader}: vs lagged / others (m)" in rrd.view_names      # no USBL fix: not named


def test_a_run_without_the_new_features_says_so(tmp_path: Path) -> None:
    review = synthetic_review(5, n_epochs=20, anfis_epochs=3)
    rrd = Rrd(views.save_rrd([review], tmp_path / "plain.rrd"))
    note = rrd.static["/run-a/features/note"][0].column("TextDocument:text").to_pylist()[0][0]
    assert note.startswith("The filter-independent features") and "not computed" in note
    assert not [e for e in rrd.temporal if e.startswith("/run-a/features/")]
    assert "Features this run did not compute" in rrd.view_names
    assert not any(n.endswith("standardized (sd)") for n in rrd.view_names)


def test_why_document_per_epoch_after_t_a_one_line_per_detector(featured: tuple[ReviewData, Rrd, Path]) -> None:
    review, rrd, _ = featured
    det, t_a = review.detections, review.metrics["window"][0]
    for leader in LEADERS:
        rows = det[(det.leader == leader) & (det.t_s > t_a)].sort_values(["t_s"], kind="stable")
        docs = rrd.cells(f"/run-a/why/{FOLLOWER}/{leader}", "TextDocument:text")
        epochs = sorted(rows.t_s.unique())
        assert len(docs) == len(epochs) + 1
        assert docs[0][0].startswith(f"**{leader}**: the detectors train until t_a = {t_a:.0f} s")
        for doc, t in zip(docs[1:], epochs, strict=True):
            at = rows[rows.t_s == t]
            label = int(at.label.iloc[0])
            truth = "anomaly" if label == 1 else "normal" if label == 0 else "no label"
            # the epoch's true range error (measured - GPS-true range), as the event log gives it
            rng = review.ranges[(review.ranges.leader == leader) & (review.ranges.t_s == t)]
            err = float(rng.measured_m.iloc[0] - rng.true_m.iloc[0])
            assert doc[0].startswith(f"**{leader} at {t:.1f} s: truth {truth}; true range error {err:+.1f} m**")
            lines = [ln for ln in doc[0].splitlines() if ln.startswith("- ")]
            states = epoch_states(at.flagged.to_numpy(), at.label.to_numpy(), np.ones(len(at), dtype=bool))
            assert lines == [f"- **{s}** {m}: {w}" for s, m, w in zip(states, at.method, at.why, strict=True)]


def test_detector_scores_against_thresholds_and_colour_key(featured: tuple[ReviewData, Rrd, Path]) -> None:
    review, rrd, _ = featured
    det = review.detections
    for leader in LEADERS:
        rows = det[(det.leader == leader) & (det.method == "chi_square")].sort_values("t_s")
        base = f"/run-a/scores/chi_square/{FOLLOWER}/{leader}"
        np.testing.assert_allclose([c[0] for c in rrd.cells(f"{base}/score", "Scalars:scalars")], rows.score)
        np.testing.assert_allclose([c[0] for c in rrd.cells(f"{base}/threshold", "Scalars:scalars")], rows.threshold)
        assert not [e for e in rrd.temporal if e.startswith("/run-a/scores/anfis")]   # the ANFIS plot has those
    key = rrd.static["/run-a/scores/key"][0].column("TextDocument:text").to_pylist()[0][0]
    assert "orange leader1, blue leader2" in key and "Triangles below 0" in key
    # the key is short (it fits its grid cell with all eight detectors), and the truth marks sit under each plot
    assert len(key) < 400
    rows_y = []
    for leader in LEADERS:
        base = f"/run-a/scores/chi_square/{FOLLOWER}/{leader}"
        rows = det[(det.leader == leader) & (det.method == "chi_square")].sort_values("t_s")
        marks = [c[0] for c in rrd.cells(f"{base}/truth", "Scalars:scalars")]
        assert len(marks) == (rows.label == 1).sum() > 0 and len(set(marks)) == 1 and marks[0] < 0
        assert rrd.rows(f"/run-a/series/anfis/{FOLLOWER}/{leader}/truth") == len(marks)
        rows_y.append(marks[0])
    assert rows_y[0] > rows_y[1]        # one row per leader, the first nearest zero
    assert {"chi_square: f2 vs gate", "dual_threshold vs 1", "Colours"} <= rrd.view_names


def test_blueprint_opens_paused_on_mission_seconds(featured: tuple[ReviewData, Rrd, Path]) -> None:
    """The cursor cannot be placed by a 0.41 blueprint: paused, a loaded file opens at its start (not its end)."""
    *_, path = featured
    reader = RrdReader(path)
    panel = {}
    for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks():
        batch = chunk.to_record_batch()
        for name in ("TimePanelBlueprint:play_state", "TimePanelBlueprint:timeline"):
            if name in batch.schema.names:
                panel[name] = batch.column(name).to_pylist()[0][0]
    assert panel["TimePanelBlueprint:timeline"] == "mission_s"
    assert panel["TimePanelBlueprint:play_state"] in ("Paused", 1, "paused")


def test_lane_names_read_leader_and_method(featured: tuple[ReviewData, Rrd, Path]) -> None:
    review, rrd, _ = featured
    lanes = sorted(e for e in rrd.temporal if e.startswith("/lanes/"))
    detectors = detector_order(make_runs([review])[0])
    assert sorted(detectors) == sorted(review.detections.method.unique())
    assert lanes == sorted(["/lanes/_key", "/lanes/_scoring_window"]
                           + [f"/lanes/{ld}/{m}" for ld in LEADERS
                              for m in ["0_truth", *(f"{i}_{d}" for i, d in enumerate(detectors, start=1))]])
    assert pd.Series(lanes).str.len().max() < 40
