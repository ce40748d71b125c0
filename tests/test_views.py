"""The Rerun views: a saved .rrd read back with Rerun's own reader holds every view's entities and values."""

from __future__ import annotations

import argparse
import itertools
import json
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rerun.chunk import RrdReader

from replay.commands import view as view_cmd
from replay.errors import UserError
from replay.review.data import ReviewData
from replay.review.scoreboard import format_value, method_kind, navigation_rows, scoreboard
from replay.stack.detectors.anfis import AnfisModel, predict
from replay.views import recording as views
from replay.views.anfis import SURFACE_GRID, grid_triangles, history_of, surface
from replay.views.cdf import CDF_SNAPSHOTS, PERCENTILES, error_axis, expanding_quantiles
from replay.views.common import groups, make_runs
from replay.views.focus import hidden_methods
from replay.views.lanes import KEY_STATES, detector_order
from replay.views.tracks import decimate
from tests.review_fixtures import FOLLOWER, LEADERS, synthetic_review

N_EPOCHS, ANFIS_EPOCHS = 40, 6


class Rrd:
    """The temporal rows and static cells of every entity of a saved recording, and its blueprint."""

    def __init__(self, path: Path) -> None:
        reader = RrdReader(path)
        self.temporal: dict[str, list] = defaultdict(list)
        self.static: dict[str, list] = defaultdict(list)
        for chunk in reader.stream().to_chunks():
            (self.static if chunk.is_static else self.temporal)[chunk.entity_path].append(chunk.to_record_batch())
        self.view_names: set[str] = set()
        self.view_classes: list[str] = []
        for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks():
            batch = chunk.to_record_batch()
            if "ViewBlueprint:display_name" in batch.schema.names:
                self.view_names.update(v[0] for v in batch.column("ViewBlueprint:display_name").to_pylist() if v)
                self.view_classes += [v[0] for v in batch.column("ViewBlueprint:class_identifier").to_pylist()]
        self.recordings = reader.recordings()

    def cells(self, entity: str, column: str) -> list:
        """Per temporal row, the list of instances of one component, in time order."""
        rows = []
        for batch in self.temporal.get(entity, []):
            if column in batch.schema.names:
                times = batch.column("time").to_pylist() if "time" in batch.schema.names else [None] * batch.num_rows
                rows += list(zip(times, batch.column(column).to_pylist(), strict=True))
        rows.sort(key=lambda r: (r[0] is None, r[0] or 0))
        return [r[1] for r in rows]

    def rows(self, entity: str) -> int:
        """Number of temporal rows of an entity."""
        return sum(b.num_rows for b in self.temporal.get(entity, []))

    def times_ns(self, entity: str) -> np.ndarray:
        """The `time` index of an entity's rows, as int ns, sorted."""
        out = [b.column("time").cast("int64").to_numpy() for b in self.temporal.get(entity, [])
               if "time" in b.schema.names]
        return np.sort(np.concatenate(out)) if out else np.zeros(0, dtype=np.int64)


@pytest.fixture(scope="module")
def review() -> ReviewData:
    return synthetic_review(7, n_epochs=N_EPOCHS, anfis_epochs=ANFIS_EPOCHS)


@pytest.fixture(scope="module")
def rrd(review: ReviewData, tmp_path_factory: pytest.TempPathFactory) -> Rrd:
    path = tmp_path_factory.mktemp("views") / "one.rrd"
    assert views.save_rrd([review], path) == path
    assert not path.with_name(path.name + ".partial").exists()
    return Rrd(path)


def test_recording_id_and_timeline_are_deterministic(rrd: Rrd, review: ReviewData) -> None:
    assert [r.recording_id for r in rrd.recordings] == ["auvreplay:run-a"]
    gps = review.tracks[(review.tracks.vehicle == FOLLOWER) & (review.tracks.source == "gps")]
    expected = review.trial_start_ns + np.round(gps.t_s.to_numpy() * 1e9).astype(np.int64)
    np.testing.assert_array_equal(rrd.times_ns("/run-a/map/follower/gps/position"), np.sort(expected))


def test_map_and_local_plot_hold_every_track(rrd: Rrd, review: ReviewData) -> None:
    for (vehicle, source), rows in review.tracks.groupby(["vehicle", "source"]):
        for view in ("map", "local"):
            assert rrd.rows(f"/run-a/{view}/{vehicle}/{source}/position") == len(rows), (view, vehicle, source)
            assert f"/run-a/{view}/{vehicle}/{source}/track" in rrd.static
    pos = rrd.cells("/run-a/map/leader1/gps/position", "GeoPoints:positions")
    rows = review.tracks[(review.tracks.vehicle == "leader1") & (review.tracks.source == "gps")].sort_values("t_s")
    np.testing.assert_allclose(np.array([p[0] for p in pos]), rows[["lat_deg", "lon_deg"]].to_numpy(), atol=1e-9)
    local = np.array([p[0] for p in rrd.cells("/run-a/local/leader1/gps/position", "Points2D:positions")])
    np.testing.assert_allclose(local[:, 0], rows.east_m, rtol=1e-6)
    np.testing.assert_allclose(local[:, 1], -rows.north_m, rtol=1e-6)       # 2D views draw y down


def test_range_circles_one_per_epoch_around_the_leader(rrd: Rrd, review: ReviewData) -> None:
    for leader in LEADERS:
        rows = review.ranges[review.ranges.leader == leader].sort_values("t_s")
        entity = f"/run-a/local/ranges/{FOLLOWER}/{leader}"
        half = np.array([c[0] for c in rrd.cells(entity, "Ellipses2D:half_sizes")])
        centre = np.array([c[0] for c in rrd.cells(entity, "Ellipses2D:centers")])
        assert len(half) == len(rows)
        np.testing.assert_allclose(half[:, 0], rows.horizontal_m, rtol=1e-6)
        np.testing.assert_allclose(half[:, 1], rows.horizontal_m, rtol=1e-6)
        np.testing.assert_allclose(centre[:, 0], rows.leader_east_m, rtol=1e-6)


def test_time_series_ranges_features_anfis_and_lanes(rrd: Rrd, review: ReviewData) -> None:
    for leader in sorted(LEADERS):
        rows = review.ranges[review.ranges.leader == leader].sort_values("t_s")
        measured = [c[0] for c in rrd.cells(f"/run-a/series/range/{FOLLOWER}/{leader}/measured", "Scalars:scalars")]
        np.testing.assert_allclose(measured, rows.measured_m)
        assert rrd.rows(f"/run-a/series/residual/{FOLLOWER}/{leader}") == len(rows)
        for feature in ("f1_innovation_m", "f2_mahalanobis2", "f3_r_adapted_m2"):
            assert rrd.rows(f"/run-a/series/{feature}/{FOLLOWER}/{leader}") == len(rows)
    assert not any("/series/anfis/" in e and "/chi_square/" in e for e in rrd.temporal)


def _expected_state(t: float, t_a: float, flagged: bool, label: int) -> str:
    """The lane state of one epoch, written out case by case (the reference for the vectorised rule)."""
    if t <= t_a:
        return "training"
    if label < 0:
        return "no label"
    if flagged:
        return "hit" if label == 1 else "false alarm"
    return "miss" if label == 1 else "quiet"


def test_detection_lanes_are_named_and_tell_hits_false_alarms_and_misses_apart(rrd: Rrd, review: ReviewData) -> None:
    """Lanes are state-timeline lanes whose path is their label: /lanes/<leader>/<rank>_<method>, the truth first,
    then the detectors best first (fewest false alarms plus misses, as the verdict)."""
    det, t_a = review.detections, review.metrics["window"][0]
    detectors = [m for m in review.methods if m in set(det.method.unique())]
    assert sorted(detectors) == sorted(["chi_square", "dual_threshold", "anfis", "anfis_aqpso"])
    ranked = detector_order(make_runs([review])[0])       # no figures in this metrics: the run's order
    assert ranked == detectors
    seen: set[str] = set()
    for leader in LEADERS:
        lanes = [e for e in rrd.temporal if e.startswith(f"/lanes/{leader}/")]
        # Rerun sorts lanes naturally, so the rank prefix puts them in the scoreboard's order
        assert sorted(lanes, key=lambda e: int(e.rsplit("/", 1)[1].split("_", 1)[0])) == \
            [f"/lanes/{leader}/0_truth"] + [f"/lanes/{leader}/{i}_{m}" for i, m in enumerate(ranked, start=1)]
        truth_rows = det[(det.leader == leader) & (det.method == detectors[0])].sort_values("t_s")
        truth = [s[0] for s in rrd.cells(f"/lanes/{leader}/0_truth", "StateChange:state")]
        assert truth == ["anomaly" if v == 1 else "normal" if v == 0 else "no label" for v in truth_rows.label]
        for rank, method in enumerate(ranked, start=1):
            rows = det[(det.leader == leader) & (det.method == method)].sort_values("t_s")
            states = [s[0] for s in rrd.cells(f"/lanes/{leader}/{rank}_{method}",
                                              "StateChange:state")]
            assert states == [_expected_state(t, t_a, f, lab) for t, f, lab in zip(rows.t_s, rows.flagged,
                                                                                   rows.label, strict=True)]
            seen |= set(states)
    assert {"hit", "quiet", "training"} <= seen
    window = [s[0] for s in rrd.cells("/lanes/_scoring_window", "StateChange:state")]
    assert window == ["training", "scored", "scored"]
    config = rrd.static[f"/lanes/{leader}/{ranked.index('chi_square') + 1}_chi_square"][0]
    values = config.column("StateConfiguration:values").to_pylist()[0]
    assert {"hit", "false alarm", "miss", "quiet"} <= set(values)
    # no state name in a detector's segments (a one-epoch segment would cut it to "mi"): the key lane names them,
    # each over an equal share of the mission, wide enough for its name
    assert set(config.column("StateConfiguration:labels").to_pylist()[0]) == {" "}
    key = [s[0] for s in rrd.cells("/lanes/_key", "StateChange:state")]
    assert key[:-1] == list(KEY_STATES) and key[-1] == KEY_STATES[-1]
    key_config = rrd.static["/lanes/_key"][0].column("StateConfiguration:labels").to_pylist()[0]
    assert dict(zip(values, key_config, strict=True))["false alarm"] == "false alarm"


def test_anfis_output_series(rrd: Rrd) -> None:
    for leader in LEADERS:
        rows = rrd.rows(f"/run-a/series/f1_innovation_m/{FOLLOWER}/{leader}")
        for method in ("anfis", "anfis_aqpso"):
            for series in ("output", "T2"):
                assert rrd.rows(f"/run-a/series/anfis/{FOLLOWER}/{leader}/{method}/{series}") == rows


def test_error_cdf_grows_with_readable_percentiles(rrd: Rrd, review: ReviewData) -> None:
    """The CDF counts the metrics window only (from t_a) and is drawn on a log x axis: the curve read back
    through the axis is the quantile function of the scored errors."""
    t_a = review.metrics["window"][0]
    errors = review.errors[(review.errors.method == "ckf") & (review.errors.t_s >= t_a)].sort_values("t_s")
    axis = error_axis(make_runs([review]))[FOLLOWER]
    n_snap = min(errors.t_s.nunique(), CDF_SNAPSHOTS)
    curves = rrd.cells(f"/run-a/cdf/{FOLLOWER}/ckf/curve", "LineStrips2D:strips")
    assert len(curves) == n_snap and all(len(c) == 1 for c in curves)
    assert rrd.times_ns(f"/run-a/cdf/{FOLLOWER}/ckf/curve")[0] >= review.trial_start_ns + t_a * 1e9 - 1
    last = np.array(curves[-1][0])
    expected = np.clip(np.quantile(errors.error_m, np.linspace(0, 1, last.shape[0])), axis.lo, axis.hi)
    np.testing.assert_allclose(axis.error(last[:, 0]), expected, rtol=1e-4)
    assert np.all(np.diff(last[:, 0]) >= 0) and np.all(np.diff(last[:, 1]) <= 0)
    marks = rrd.cells(f"/run-a/cdf/{FOLLOWER}/ckf/percentiles", "Points2D:positions")
    assert len(marks) == n_snap and all(len(m) == len(PERCENTILES) for m in marks)
    np.testing.assert_allclose(axis.error(np.array([p[0] for p in marks[-1]])),
                               np.clip(np.quantile(errors.error_m, PERCENTILES), axis.lo, axis.hi), rtol=1e-4)
    table = rrd.cells(f"/run-a/cdf/{FOLLOWER}/table", "TextDocument:text")
    assert len(table) == n_snap + 1 and "none is counted before t_a" in table[0][0]       # t = 0 says why
    assert f"| ckf | {np.quantile(errors.error_m, 0.5):.2f} |" in table[-1][0] and f"t_a = {t_a:.0f} s" in table[-1][0]
    ticks = rrd.static[f"/run-a/cdf/{FOLLOWER}/axes/x_ticks"][0].column("Points2D:labels").to_pylist()[0]
    assert all(float(t) == pytest.approx(v) for t, v in zip(ticks, axis.ticks(), strict=True)) and len(ticks) >= 3
    # the legend names the methods in focus (replay.views.focus), best first; the others are hidden; its p50 is
    # the one up to the cursor: "-" at t = 0, then each snapshot's, so at the last the scoreboard's
    legends = rrd.cells(f"/run-a/cdf/{FOLLOWER}/legend/names", "Points2D:labels")
    hidden = set(hidden_methods(make_runs([review])[0], None))
    assert sorted(t.split()[0] for t in legends[-1]) == sorted(set(review.errors.method.unique()) - hidden)
    assert len(legends) == n_snap + 1 and all(t.endswith("p50 - m") for t in legends[0])
    best = legends[-1][0].split()[0]
    mine = review.errors[(review.errors.method == best) & (review.errors.t_s >= t_a)]
    shown = [float(next(t for t in labels if t.startswith(f"{best} ")).split()[2]) for labels in legends[1:]]
    at = np.unique(errors.t_s)[np.unique(np.linspace(0, errors.t_s.nunique() - 1, n_snap).round().astype(int))]
    np.testing.assert_allclose(shown, [np.quantile(mine.error_m[mine.t_s <= t], 0.5) for t in at], atol=0.006)
    assert shown[0] != shown[-1]            # it grows with the curves
    for method in review.errors.method.unique():
        assert rrd.rows(f"/run-a/series/error/{FOLLOWER}/{method}") == (review.errors.method == method).sum()


def test_anfis_training_and_explanations(rrd: Rrd, review: ReviewData) -> None:
    for leader in LEADERS:
        base = f"/run-a/anfis/anfis/{leader}"         # one root per model: method, then leader
        for d in (1, 2, 3):
            mf = rrd.cells(f"{base}/training/mf/in{d}", "LineStrips2D:strips")
            assert len(mf) == ANFIS_EPOCHS + 1                    # every epoch, and the kept one on `time`
            assert all(len(strips) == 2 for strips in mf)         # two MFs per input
            assert f"{base}/explain/mf/in{d}/curves" in rrd.static
        surf = rrd.cells(f"{base}/training/surface", "Mesh3D:vertex_positions")
        assert len(surf) == ANFIS_EPOCHS + 1 and all(len(s) == SURFACE_GRID**2 for s in surf)
        assert rrd.rows(f"{base}/training/rmse") == ANFIS_EPOCHS
        ex = review.anfis_explain[review.anfis_explain.model == f"anfis/{leader}"].sort_values("t_s")
        firing = rrd.cells(f"{base}/explain/firing", "LineStrips2D:strips")
        assert len(firing) == len(ex) and all(len(f) == 8 for f in firing)
        heights = np.array([[-bar[1][1] for bar in f] for f in firing])
        np.testing.assert_allclose(heights, np.stack(ex.firing.to_numpy()), rtol=1e-6)
        grades = rrd.cells(f"{base}/explain/mf/in1/grade", "Points2D:positions")
        # the markers first (at the input, y = -grade), then as many grade labels at the top of the plot
        np.testing.assert_allclose([[-p[1] for p in g[: len(g) // 2]] for g in grades], [m[0] for m in ex.memberships],
                                   rtol=1e-6)
        labels = rrd.cells(f"{base}/explain/mf/in1/grade", "Points2D:labels")
        assert [lab[2:] for lab in labels] == [[f"MF{j + 1} {v:.2f}" for j, v in enumerate(m[0])]
                                               for m in ex.memberships]
        verdicts = [t[0] for t in rrd.cells(f"{base}/explain/verdict", "TextDocument:text")]
        assert len(verdicts) == len(ex)
        for text, flagged in zip(verdicts, ex.flagged, strict=True):
            assert ("**flagged**" in text) == bool(flagged) and "Strongest rules: R" in text


def test_kmcdf_epochs_and_events(rrd: Rrd, review: ReviewData) -> None:
    for method in ("kmcdf1", "kmcdf2"):
        rows = review.kmcdf[review.kmcdf.method == method].sort_values("t_s")
        fixes = rrd.cells(f"/run-a/kmcdf/{FOLLOWER}/{method}/fixes", "Points2D:positions")
        assert [len(f) for f in fixes] == [len(v) for v in rows.fixes_east_m]
        colors = rrd.cells(f"/run-a/kmcdf/{FOLLOWER}/{method}/fixes", "Points2D:colors")
        green = (60 << 24) | (200 << 16) | (90 << 8) | 255                  # cluster 1 (C1, kept), RGBA packed
        assert [sum(c == green for c in row) for row in colors] == [sum(k == 1 for k in v) for v in rows.fixes_cluster]
        assert rrd.rows(f"/run-a/kmcdf/{FOLLOWER}/{method}/final") == len(rows)
        assert [len(n) for n in rrd.cells(f"/run-a/kmcdf/{FOLLOWER}/{method}/nodes", "Points2D:positions")] == \
            [4] * len(rows)
    texts = [t[0] for t in rrd.cells("/run-a/events", "TextLog:text")]
    assert sorted(texts) == sorted(review.events.text)


def test_blueprint_saved_with_every_view(rrd: Rrd) -> None:
    names = rrd.view_names
    for expected in ("Local east/north (m), range circles, scale bar", "Events",
                     "leader1: range measured / true (m)", "leader1: ANFIS vs T2 (m)", "Colours",
                     "Rule firing w", "Verdict", "Output surface, f3 at median", "Scoreboard",
                     "Key", "Training RMSE (m) per epoch"):
        assert expected in names
    assert any(n.startswith("Error CDF of follower") for n in names)
    # the default focus: the best of each group, the best detector, chi_square and anfis; the others hidden, and said so
    assert any(n.startswith("Map: GPS truth and the focus tracks; ") and n.endswith("more methods hidden "
                                                                                     "(view --focus all)")
               for n in names)
    assert any(n.startswith("Error vs GPS (m), whole mission") for n in names)
    assert any(n.startswith("Detection lanes") for n in names)
    assert sum(n.startswith("KMCDF follower:") and "prelim. fixes of kmcdf1, kmcdf2" in n for n in names) == 1
    assert {"Map", "2D", "3D", "TimeSeries", "TextLog", "TextDocument", "StateTimeline", "BarChart"} <= set(
        rrd.view_classes)


def test_two_runs_compared_in_one_recording(review: ReviewData, tmp_path: Path) -> None:
    other = synthetic_review(8, n_epochs=20, anfis_epochs=3, run_id="run-a")    # same id: still kept apart
    out = Rrd(views.save_rrd([review, other], tmp_path / "two.rrd"))
    assert out.rows("/run-a/map/follower/ckf/position") == (review.tracks.source == "ckf").sum()
    assert out.rows("/run-a_1/map/follower/ckf/position") == (other.tracks.source == "ckf").sum()
    context = out.static["/run-a_1"][0].column("AnnotationContext:context").to_pylist()[0][0]
    labels = {c["class_description"]["info"]["label"]: c["class_id"] for c in context}
    # the second run is B: its names and lines carry the letter; what it is (here its prefix) is said once
    assert labels["ckf [B]"] == 4 and labels["gps [B]"] == 1
    assert any(n.endswith("[B]") for n in out.view_names)
    assert "Events; A = run-a, B = run-a_1" in out.view_names
    assert all(t.startswith("[B] ") for t in (x[0] for x in out.cells("/run-a_1/events", "TextLog:text")))


def test_kmcdf_rows_without_fixes_keep_the_final_fix(review: ReviewData, tmp_path: Path) -> None:
    km = review.kmcdf.copy()
    one = km.method == "kmcdf1"
    for col in ("fixes_east_m", "fixes_north_m", "fixes_cluster"):
        km[col] = [[] if o else v for o, v in zip(one, km[col], strict=True)]
    out = Rrd(views.save_rrd([ReviewData(**{**review.__dict__, "kmcdf": km})], tmp_path / "k.rrd"))
    assert out.rows(f"/run-a/kmcdf/{FOLLOWER}/kmcdf1/fixes") == 0
    assert out.rows(f"/run-a/kmcdf/{FOLLOWER}/kmcdf1/final") == int(one.sum())
    assert out.rows(f"/run-a/kmcdf/{FOLLOWER}/kmcdf2/fixes") == int((~one).sum())


def test_empty_review_still_makes_a_recording(tmp_path: Path) -> None:
    empty = ReviewData(run_id="nothing", trial="t", trial_start_ns=0, origin_lat_deg=0.0, origin_lon_deg=0.0)
    out = Rrd(views.save_rrd([empty], tmp_path / "empty.rrd"))
    assert "/nothing" in out.static and not out.temporal
    with pytest.raises(ValueError):
        views.build_recording([])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0, 100, allow_nan=False), min_size=1, max_size=30), st.integers(1, 6))
def test_expanding_quantiles_match_numpy(values: list[float], n_at: int) -> None:
    v = np.array(values)
    t = np.arange(v.size, dtype=float)
    at = np.linspace(-1, v.size, n_at)
    probs = np.array([0.0, 0.1, 0.5, 0.9, 0.95, 1.0])
    got = expanding_quantiles(t, v, at, probs)
    for i, a in enumerate(at):
        seen = v[t <= a]
        if seen.size == 0:
            assert np.isnan(got[i]).all()
        else:
            np.testing.assert_allclose(got[i], np.quantile(seen, probs), rtol=1e-12, atol=1e-12)


@given(st.integers(1, 20_000), st.integers(2, 500))
def test_decimate_keeps_ends_and_limit(n: int, limit: int) -> None:
    idx = decimate(n, limit)
    assert idx[0] == 0 and idx[-1] == n - 1 and idx.size <= max(limit, 1) and np.all(np.diff(idx) > 0)


def test_surface_is_the_stacks_anfis_output(review: ReviewData) -> None:
    rows = review.anfis_epochs[review.anfis_epochs.model == "anfis/leader1"]
    h = history_of(rows)
    assert h is not None and h.a.shape == (ANFIS_EPOCHS, 3, 2) and h.rules.shape == (8, 3)
    x, out = surface(h, 0.3)
    for e in (0, ANFIS_EPOCHS - 1):
        model = AnfisModel(h.a[e], h.b[e], h.c[e], h.consequents[e], h.rules, "grid")
        np.testing.assert_allclose(out[e], predict(model, x), rtol=1e-12)
    alt = rows.assign(params=[{"a": np.asarray(p["membership"])[..., 0], "b": np.asarray(p["membership"])[..., 1],
                               "c": np.asarray(p["membership"])[..., 2], "consequents": p["consequents"],
                               "rule_structure": "grid"}
                              for p in rows.params])
    np.testing.assert_allclose(history_of(alt).c, h.c)
    assert history_of(rows.assign(params=[{"nonsense": 1}] * len(rows))) is None


def test_grid_triangles_cover_the_grid() -> None:
    tri = grid_triangles(4)
    assert tri.shape == (18, 3) and tri.max() == 15 and tri.min() == 0
    assert len({tuple(sorted(t)) for t in tri}) == 18
    assert set(itertools.chain.from_iterable(tri.tolist())) == set(range(16))


def test_view_command_without_display_prints_the_command(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "x.rrd"
    path.write_bytes(b"")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    parser = argparse.ArgumentParser()
    view_cmd.add_arguments(parser)
    assert view_cmd.run(parser.parse_args([str(path)])) == 0
    out = capsys.readouterr().out
    assert "no display" in out and str(path) in out and "--web" in out


def test_view_command_rejects_bad_files(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no such file"):
        view_cmd.check_file(str(tmp_path / "missing.rrd"))
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(UserError, match="expected an .rrd"):
        view_cmd.check_file(str(tmp_path / "notes.txt"))
    assert view_cmd.has_display({"WAYLAND_DISPLAY": "wayland-0"}) and not view_cmd.has_display({"DISPLAY": ""})


def test_web_viewer_binds_loopback_only(tmp_path: Path) -> None:
    cmd = views.viewer_command(tmp_path / "a.mcap", web=True)
    assert Path(cmd[0]).name == "rerun" and cmd[1].endswith("a.mcap")
    assert cmd[cmd.index("--bind") + 1] == "127.0.0.1" and "--web-viewer" in cmd
    assert "--bind" not in views.viewer_command(tmp_path / "a.rrd")


def test_comparison_names_runs_by_what_differs_and_says_what_changed(review: ReviewData, tmp_path: Path) -> None:
    a = ReviewData(**{**review.__dict__, "parameters": {"stack": {"r_m": 2.0, "q": 1}}})
    b = ReviewData(**{**synthetic_review(8, n_epochs=20, anfis_epochs=3, run_id="run-b").__dict__,
                      "parameters": {"stack": {"r_m": 2.5, "q": 1}}})
    out = Rrd(views.save_rrd([a, b], tmp_path / "cmp.rrd"))
    context = out.static["/run-b"][0].column("AnnotationContext:context").to_pylist()[0][0]
    info = {c["class_description"]["info"]["label"]: c["class_description"]["info"]["color"] for c in context}
    first = out.static["/run-a"][0].column("AnnotationContext:context").to_pylist()[0][0]
    info_a = {c["class_description"]["info"]["label"]: c["class_description"]["info"]["color"] for c in first}
    assert "ckf [B]" in info and "ckf [A]" in info_a and info["ckf [B]"] != info_a["ckf [A]"]
    assert not any("] " in n and n.count("[") > 1 for n in out.view_names)          # no doubled tags
    changes = out.static["/run-b/changes"][0].column("TextDocument:text").to_pylist()[0][0]
    assert "**A = r_m=2** (run run-a) against **B = r_m=2.5** (run run-b)" in changes
    # the setting that differs is said once, in the event log's title; each line carries only the letter
    assert "Events; r_m: A 2, B 2.5" in out.view_names
    lines = [x[0] for run in ("run-a", "run-b") for x in out.cells(f"/{run}/events", "TextLog:text")]
    assert lines and all(t[:4] in ("[A] ", "[B] ") and "r_m=" not in t for t in lines)
    assert {n for n in out.view_names if n.startswith("Scoreboard")} == {"Scoreboard of A", "Scoreboard of B"}
    assert "Epochs that differ" in out.view_names and "What changed: A vs B" in out.view_names
    assert sum(n.startswith("Detection lanes") for n in out.view_names) == 1     # both runs in one view
    # a detector's lanes of both runs are neighbours: one root, the run last
    rank = detector_order(make_runs([a])[0]).index("chi_square") + 1
    assert out.rows(f"/lanes/leader1/{rank}_chi_square/A") == (
        (a.detections.leader == "leader1") & (a.detections.method == "chi_square")).sum()
    assert out.rows(f"/lanes/leader1/{rank}_chi_square/B") == (
        (b.detections.leader == "leader1") & (b.detections.method == "chi_square")).sum()


def _view_args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    view_cmd.add_arguments(parser)
    return parser.parse_args(list(argv))


def test_view_never_replaces_a_recording_it_did_not_make(tmp_path: Path) -> None:
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    assert view_cmd.recording_path([a], None, False) == tmp_path / "a.rrd"
    assert view_cmd.recording_path([a, b], None, False) == tmp_path / "a-vs-b.rrd"
    (tmp_path / "a.rrd").write_bytes(b"earlier")
    (tmp_path / "a-vs-b.rrd").write_bytes(b"earlier")
    (tmp_path / "a-vs-b-2.rrd").write_bytes(b"earlier")
    assert view_cmd.recording_path([a], None, False) == tmp_path / "a-2.rrd"
    assert view_cmd.recording_path([a, b], None, False) == tmp_path / "a-vs-b-3.rrd"
    assert view_cmd.recording_path([a], None, True) == tmp_path / "a.rrd"
    with pytest.raises(UserError, match="exists"):
        view_cmd.recording_path([a], str(tmp_path / "a.rrd"), False)
    assert view_cmd.recording_path([a], str(tmp_path / "a.rrd"), True) == tmp_path / "a.rrd"
    assert _view_args(str(a), "--force").force and not _view_args(str(a)).force
    assert (tmp_path / "a.rrd").read_bytes() == b"earlier"


@pytest.fixture(scope="module")
def sample(tmp_path_factory: pytest.TempPathFactory) -> tuple[ReviewData, dict, Rrd]:
    """The bundled sample trial recorded, replayed with every method (metrics.json written) and drawn."""
    from recorders.manifest import load_manifest
    from recorders.record import record
    from replay.reproduce.anfis import sample_trial_dir
    from replay.run.pipeline import replay_archive

    d = tmp_path_factory.mktemp("sample")
    record(load_manifest(sample_trial_dir() / "trial.toml"), d / "lake.mcap")
    outcome = replay_archive(d / "lake.mcap", output=d / "results.mcap", review=True)
    metrics = json.loads((d / "results.metrics.json").read_text())
    return outcome.review, metrics, Rrd(views.save_rrd([outcome.review], d / "lake.rrd"))


def test_sample_scoreboard_shows_metrics_json_exactly(sample: tuple[ReviewData, dict, Rrd]) -> None:
    review, metrics, rrd = sample
    doc = rrd.static[f"/{review.run_id}/scoreboard"][0].column("TextDocument:text").to_pylist()[0][0]
    assert "after t_a: 600 s to 1700 s (mission seconds)" in doc
    methods_part, _, navigation_part = doc.partition("**Own navigation against GPS at the fixes**")

    def table(text: str) -> list[list[str]]:
        return [[c.strip() for c in line.strip("|").split("|")] for line in text.splitlines()
                if line.startswith("| ") and line[2].isdigit()]
    rows = table(methods_part)
    assert [r[1] for r in rows] == [r.method for r in scoreboard(metrics)]
    # each vehicle's own navigation (DR restarted at the fixes, INS) ranked beneath, figures as metrics.json
    nav = navigation_rows(metrics)
    assert {r.vehicle for r in nav} == {"follower", "leader1", "leader2"}
    assert [(r[1], r[2]) for r in table(navigation_part)] == [(r.vehicle, r.method) for r in nav]
    for row, r in zip(table(navigation_part), nav, strict=True):
        assert row[3] == format_value(metrics["navigation"][r.vehicle]["methods"][r.method]["error_p50_m"])
    assert {r[1] for r in rows} == set(metrics["methods"])
    columns = ("error_p50_m", "error_p90_m", "error_rms_m", "tp", "fp", "fn", "fpr", "fnr", "auc")
    for row in rows:
        assert row[3:] == [format_value(metrics["methods"][row[1]][c]) for c in columns], row[1]
    # the verdict first: the best of each group by p50, in words, before any table
    verdict_part = methods_part.split("| #")[0]
    for group, words in (("cooperative", "Best position estimate"), ("positioning", "Best USBL positioning")):
        best = min((m for m in metrics["methods"] if (method_kind(m) == "positioning") == (group == "positioning")),
                   key=lambda m: metrics["methods"][m]["error_p50_m"])
        assert f"{words}: **{best}**, p50 {format_value(metrics['methods'][best]['error_p50_m'])} m" in verdict_part


def test_sample_every_method_has_a_track_an_error_series_and_a_cdf(sample: tuple[ReviewData, dict, Rrd]) -> None:
    review, metrics, rrd = sample
    p = f"/{review.run_id}"
    followers = [v for v, role in review.vehicles.items() if role == "follower"]
    assert followers == ["follower"]
    for method in metrics["methods"]:
        assert rrd.rows(f"{p}/map/follower/{method}/position") > 100, method
        assert rrd.rows(f"{p}/local/follower/{method}/trail") > 100, method
        assert rrd.rows(f"{p}/series/error/follower/{method}") > 100, method
        marks = rrd.cells(f"{p}/cdf/follower/{method}/percentiles", "Points2D:positions")
        axis = error_axis(make_runs([review]))["follower"]
        # the last snapshot of the CDF is the scoreboard's: p50 and p90 of the metrics window
        np.testing.assert_allclose(axis.error(np.array([marks[-1][0][0], marks[-1][1][0]])),
                                   [metrics["methods"][method]["error_p50_m"],
                                    min(metrics["methods"][method]["error_p90_m"], axis.hi)], rtol=1e-4)
    # the lanes of each leader: the truth, then the detectors best first (fewest false alarms plus misses)
    merit = {m: metrics["methods"][m]["fp"] + metrics["methods"][m]["fn"] for m in metrics["methods"]
             if method_kind(m) == "detector"}
    ranked = sorted(merit, key=lambda m: merit[m])
    assert merit[ranked[0]] < merit[ranked[-1]]
    for leader in ("leader1", "leader2"):
        lanes = sorted((e for e in rrd.temporal if e.startswith(f"/lanes/{leader}/")),
                       key=lambda e: int(e.rsplit("/", 1)[1].split("_", 1)[0]))
        assert len(lanes) == 1 + sum(r.kind == "detector" for r in scoreboard(metrics))
        assert lanes[0] == f"/lanes/{leader}/0_truth"
        assert [merit[e.rsplit("/", 1)[1].split("_", 1)[1]] for e in lanes[1:]] == sorted(merit.values())


def test_sample_mission_seconds_beside_utc_and_events_use_them(sample: tuple[ReviewData, dict, Rrd]) -> None:
    review, _, rrd = sample
    batches = rrd.temporal[f"/{review.run_id}/events"]
    # mission_s is a sequence of whole seconds (Rerun writes it "#620" on every axis, a duration "+10m")
    assert all(b.schema.field("mission_s").type == pa.int64() for b in batches)
    mission = np.concatenate([b.column("mission_s").to_numpy() for b in batches])
    utc = np.concatenate([b.column("time").cast("int64").to_numpy() for b in batches])
    assert np.abs(utc - review.trial_start_ns - mission * 1_000_000_000).max() <= 500_000_000
    np.testing.assert_array_equal(np.sort(mission), np.sort(np.round(review.events.t_s.to_numpy())))
    for entity in (f"/{review.run_id}/series/error/follower/kmcdf2", f"/{review.run_id}/local/follower/gps/position",
                   f"/{review.run_id}/cdf/follower/legend/names", "/lanes/leader1/0_truth"):
        assert all(b.schema.field("mission_s").type == pa.int64() for b in rrd.temporal[entity]), entity
    ev = review.events
    warn = ev[ev.level == "WARN"].text
    assert warn.str.startswith("FALSE ALARM").any() and warn.str.startswith("MISS").any()
    starts, ends = ev.text.str.startswith("ANOMALY STARTS").sum(), ev.text.str.startswith("ANOMALY ENDS").sum()
    assert 0 <= starts - ends <= 2                 # at most one interval per leader still open at the end
    assert (ev.text.str.startswith("ANOMALY STARTS").sum() > 10
            and ev[ev.level == "INFO"].text.str.contains("trained at t_a").any())
    assert not ev[ev.level == "INFO"].text.str.startswith(("FALSE ALARM", "MISS")).any()


def test_a_run_groups_each_table_once_and_gives_what_groups_gives() -> None:
    review = synthetic_review(0, n_epochs=N_EPOCHS, anfis_epochs=ANFIS_EPOCHS)
    run = make_runs([review])[0]
    det = review.detections
    pairs = run.groups(det, ["follower", "leader"])
    assert run.groups(det, ["follower", "leader"]) is pairs  # asked again: the same list, not grouped again
    direct = groups(det, ["follower", "leader"])
    assert [k for k, _ in pairs] == [k for k, _ in direct] and len(pairs) == len(LEADERS)
    for (_, rows), (_, expected) in zip(pairs, direct, strict=True):
        assert rows.equals(expected) and list(rows.index) == list(expected.index)
    # a group's rows grouped again are cached by that group; another table (or keys) is grouped anew
    assert run.groups(pairs[0][1], ["method"]) is run.groups(pairs[0][1], ["method"])
    copy = det.copy()
    assert run.groups(copy, ["follower", "leader"]) is not pairs
    assert run.groups(det, ["follower"]) is not pairs and len(run.groups(det, ["follower"])) == 1
    assert replace(run).groups(det, ["follower", "leader"]) is not pairs  # a new Run starts with no cache
