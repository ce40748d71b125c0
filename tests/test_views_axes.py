"""One time base on every axis, the metre scale bar, the why panel's true error, the report's time labels."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest
from hypothesis import given
from hypothesis import strategies as st
from matplotlib.backends.backend_agg import FigureCanvasAgg
from rerun.chunk import RrdReader

from replay.review.report_plots import series_figure
from replay.views import recording as views
from replay.views.common import MISSION, mission_column, mission_seconds
from replay.views.features import range_error_at
from replay.views.scale import label, nice_length, scale_bar
from replay.views.series import SPAN
from replay.views.tracks import CIRCLE_SHARE, local_frame, track_bounds
from tests.review_fixtures import synthetic_review
from tests.test_views import Rrd


def test_mission_seconds_are_a_sequence_of_whole_seconds() -> None:
    """A sequence timeline (Rerun writes "#620" on an axis), never a duration ("+10m")."""
    col = mission_column(np.array([0.0, 0.4, 0.6, 619.5, 1699.9]))
    batch = col.as_arrow_array()
    assert col.timeline_name() == MISSION and batch.type == pa.int64()
    assert batch.to_pylist() == [0, 0, 1, 620, 1700]
    np.testing.assert_array_equal(mission_seconds(pd.Series([2.2, 5.5])), [2, 6])


def test_every_time_series_of_a_recording_is_on_mission_seconds(tmp_path: Path) -> None:
    """Read back from the .rrd: every temporal row of every view carries `mission_s` as int64 whole seconds
    beside UTC `time`, and they agree to within half a second."""
    review = synthetic_review(3, n_epochs=30, anfis_epochs=3)
    rrd = Rrd(views.save_rrd([review], tmp_path / "t.rrd"))
    checked = 0
    for entity, batches in rrd.temporal.items():
        for b in batches:
            if "time" not in b.schema.names:       # ANFIS training epochs: their own sequence
                assert "anfis_epoch" in b.schema.names, entity
                continue
            assert b.schema.field(MISSION).type == pa.int64(), entity
            utc = b.column("time").cast("int64").to_numpy()
            mission = b.column(MISSION).to_numpy()
            assert np.abs(utc - review.trial_start_ns - mission * 1_000_000_000).max() <= 500_000_000, entity
            checked += b.num_rows
    assert checked > 1000
    for prefix in ("/run-a/series/error/", "/run-a/scores/", "/run-a/features/", "/lanes/"):
        assert any(e.startswith(prefix) for e in rrd.temporal) or prefix == "/run-a/features/", prefix


@given(st.floats(min_value=1e-3, max_value=1e7, allow_nan=False))
def test_the_scale_bar_is_a_round_length_about_a_fifth_of_the_view(span: float) -> None:
    length = nice_length(span)
    mantissa = length / 10.0 ** math.floor(math.log10(length) + 1e-12)
    assert min(abs(mantissa - m) for m in (1.0, 2.0, 5.0)) < 1e-6
    assert 0.2 * span / 2.5 * (1 - 1e-9) <= length <= 0.2 * span * (1 + 1e-9)


def test_the_scale_bar_sits_inside_its_view_and_says_its_length() -> None:
    strips, at, length = scale_bar((-300.0, 700.0), (-400.0, 200.0))
    assert length == 200.0 and label(length) == "200 m" and label(2000.0) == "2 km" and label(0.5) == "0.5 m"
    pts = np.concatenate([*strips, at])
    assert (pts[:, 0] > -300).all() and (pts[:, 0] < 700).all() and (pts[:, 1] > -400).all() and (pts[:, 1] < 200).all()
    bar = strips[0]
    assert bar[1, 0] - bar[0, 0] == pytest.approx(200.0) and bar[0, 1] == bar[1, 1]
    assert bar[0, 1] > 100.0          # the lower part of the view (y down)


def test_the_scale_bar_is_in_the_local_and_kmcdf_views(tmp_path: Path) -> None:
    review = synthetic_review(4, n_epochs=30, anfis_epochs=3)
    rrd = Rrd(views.save_rrd([review], tmp_path / "s.rrd"))
    frame = local_frame([review])
    assert frame is not None
    text = rrd.static["/run-a/local/scale/length"][0].column("Points2D:labels").to_pylist()[0]
    assert text == [label(nice_length(frame[0][1] - frame[0][0]))]
    for target in review.kmcdf.target.unique():
        assert f"/run-a/kmcdf/{target}/truth/scale/bar" in rrd.static


def test_local_bounds_hold_the_range_circles() -> None:
    """A range circle around a leader reaches beyond every vehicle: the default bounds hold it (no clipping)."""
    review = synthetic_review(4, n_epochs=30, anfis_epochs=3)
    lo, hi = track_bounds([review])
    r = review.ranges
    east, radius = r.leader_east_m.to_numpy(), r.horizontal_m.to_numpy()
    # all but the 1 % most extreme on each side (outliers of hundreds of metres would shrink the tracks)
    allowed = max(1, math.ceil((1 - CIRCLE_SHARE) / 2 * len(r)))
    assert (east - radius < lo[0] - 1e-6).sum() <= allowed and (east + radius > hi[0] + 1e-6).sum() <= allowed
    gps = review.tracks[review.tracks.source == "gps"]
    assert (east + radius).max() > gps.east_m.max() and hi[0] > gps.east_m.max()     # wider than the vehicles


def test_range_error_at_matches_the_epoch_or_says_nan() -> None:
    ranges = pd.DataFrame({"t_s": [10.0, 15.0, 20.0], "residual_m": [1.5, -3.25, np.nan]})
    np.testing.assert_array_equal(range_error_at(ranges, np.array([15.0, 10.0, 12.0, 20.0, 99.0])),
                                  [-3.25, 1.5, np.nan, np.nan, np.nan])
    assert np.isnan(range_error_at(None, np.array([1.0]))).all()


def test_report_error_panels_label_time_on_every_row() -> None:
    t = np.linspace(0.0, 1700.0, 200)
    series = {m: (t, 1.0 + np.abs(np.sin(t / (50 + 10 * i)))) for i, m in enumerate(["ckf", "ackf", "anfis", "lms",
                                                                                     "kmcdf2"])}
    fig = series_figure(series, {m: m for m in series}, 600.0, 1700.0)
    FigureCanvasAgg(fig).draw()
    shown = [ax for ax in fig.axes if ax.get_visible()]
    assert len(shown) == 5
    for ax in shown:
        labels = [tl for tl in ax.get_xticklabels() if tl.get_visible() and tl.get_text()]
        assert labels and "1000" in {tl.get_text() for tl in labels}
        assert ax.get_xlabel() == "mission time (s)"


def test_every_time_series_view_spans_the_mission_from_zero(tmp_path: Path) -> None:
    """A hidden series at 0 s and at the end, in every time series view: each x axis starts at 0 (round ticks,
    plots aligned) whatever its first sample."""
    review = synthetic_review(6, n_epochs=30, anfis_epochs=3)
    path = views.save_rrd([review], tmp_path / "span.rrd")
    rrd = Rrd(path)
    mission = np.concatenate([b.column(MISSION).to_numpy() for b in rrd.temporal[SPAN]])
    end = max(review.tracks.t_s.max(), review.errors.t_s.max(), review.ranges.t_s.max())
    np.testing.assert_array_equal(np.sort(mission), [0, round(end)])
    assert np.isnan([c[0] for c in rrd.cells(SPAN, "Scalars:scalars")]).all()
    reader = RrdReader(path)
    contents: list[list[str]] = []
    for chunk in reader.stream(store=reader.blueprints()[0]).to_chunks():
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith("ViewContents:query"):
                contents += [c for c in batch.column(name).to_pylist() if c]
    series_views = [c for c in contents if any("/series/" in q or "/scores/" in q for q in c)
                    and not any(q.endswith("/scores/key") for q in c)]        # the key is a text document
    assert series_views and [c for c in series_views if f"+ {SPAN}" not in c] == []
