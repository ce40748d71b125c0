"""The streamed navigation review (replay/navigation/stream.py) against the whole-mission one, to the bit, and the
per-sample references judging it; its memory stays bounded whatever the mission's length."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_navigation_review import dive_trial, ref_fix_errors, ref_ins_error, trials

from formats.mcap_reader import ArchiveReader
from recorders.manifest import load_manifest
from recorders.record import record
from replay.navigation import NavigationConfig, NavigationReview, review_vehicle
from replay.navigation.columns import DvlColumns, InsColumns, SeriesColumns, VehicleColumns, read_columns
from replay.navigation.review import review_metrics
from replay.navigation.stream import NavigationStream, StreamCollector, stream_columns
from replay.run.pipeline import replay_archive

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"


def assert_same_review(a: NavigationReview, b: NavigationReview, series: bool = True) -> None:
    """Every figure of the whole-mission review `a` in the streamed `b`, bit for bit (NaN where NaN);
    `series`: the series and the track are under the stream's cap, so they are whole too."""
    assert review_metrics(a) == review_metrics(b)
    eq = np.testing.assert_array_equal
    for name in ("t_s", "since_prev_s", "dr_error_m", "dr_path_m", "dr_held_s", "ins_error_m", "ins_path_m",
                 "dive_end"):
        eq(getattr(a.fix_errors, name), getattr(b.fix_errors, name), err_msg=name)
    assert b.dead_reckoning.fix_lat_deg.size == 0    # the DR positions at the fixes are not kept
    la, lb = a.bottom_lock, b.bottom_lock
    for name in ("samples", "locked", "sample_share", "time_share", "span_s", "gap_start_s", "gap_end_s",
                 "gap_duration_s", "gap_samples", "bin_start_s", "bin_share"):
        eq(getattr(la, name), getattr(lb, name), err_msg=name)
    for name in ("start_s", "end_s", "dr_error_m", "ins_error_m", "distance_m", "dr_pct", "ins_pct"):
        eq(getattr(a.dives, name), getattr(b.dives, name), err_msg=name)
    assert a.notes == b.notes and a.counts == b.counts
    if not series:
        return
    # the track: the first finite point of each second of the whole one (what the views draw)
    ta = a.dead_reckoning
    ok = np.isfinite(ta.lat_deg) & np.isfinite(ta.lon_deg)
    t = ta.t_s[ok]
    first = np.diff(np.floor(t), prepend=-np.inf) > 0
    eq(t[first], b.dead_reckoning.t_s)
    eq(ta.lat_deg[ok][first], b.dead_reckoning.lat_deg)
    eq(ta.lon_deg[ok][first], b.dead_reckoning.lon_deg)
    for sa, sb in zip(a.series.all(), b.series.all(), strict=True):
        assert (sa.name, sa.unit, sa.source) == (sb.name, sb.unit, sb.source)
        eq(sa.t_s, sb.t_s, err_msg=sa.name)
        eq(sa.values, sb.values, err_msg=sa.name)


@st.composite
def trials_with_more(draw: st.DrawFn) -> tuple[VehicleColumns, NavigationConfig, int]:
    """`trials` with DVL altitudes, rangefinder samples and sometimes a depth sensor; a stretch size."""
    fixes, dvl, ins, hold, max_gap, max_age = draw(trials())
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = dvl.t_s.size
    alt = rng.uniform(1.0, 20.0, n)
    vx, vy = dvl.vx_mps.copy(), dvl.vy_mps.copy()
    ranging = rng.uniform(size=n) < draw(st.floats(0.0, 0.2))
    vx[ranging] = vy[ranging] = np.nan
    dvl = DvlColumns.build(dvl.t_s, vx, vy, dvl.valid, dvl.frame, alt)
    depth = None
    if draw(st.booleans()):
        dt = np.sort(rng.uniform(0.0, dvl.t_s[-1] + 3.0, draw(st.integers(0, 30))))
        depth = SeriesColumns.build(dt, rng.uniform(0.0, 30.0, dt.size))
    cfg = NavigationConfig(dvl_hold_s=hold, heading_max_gap_s=max_gap, ins_max_age_s=max_age, dive_gap_s=8.0,
                           lock_min_gap_s=draw(st.floats(0.5, 5.0)), lock_bin_s=draw(st.floats(1.0, 30.0)))
    return VehicleColumns(fixes=fixes, dvl=dvl, ins=ins, depth=depth), cfg, draw(st.integers(1, 40))


@settings(max_examples=200, deadline=None)
@given(trials_with_more())
def test_streamed_review_is_the_whole_mission_review_to_the_bit(trial: tuple) -> None:
    cols, cfg, block = trial
    streamed = stream_columns(cols, "auv", cfg, block_rows=block)
    assert_same_review(review_vehicle(cols, "auv", cfg), streamed)
    # and the per-sample references judge it as they judge the whole-mission one
    err, path, held = ref_fix_errors(cols.fixes, cols.dvl.velocities(), cols.ins, cfg.dvl_hold_s,
                                     cfg.heading_max_gap_s)
    np.testing.assert_allclose(streamed.fix_errors.dr_error_m, err, rtol=0, atol=1e-6)
    np.testing.assert_allclose(streamed.fix_errors.dr_path_m, path, rtol=0, atol=1e-6)
    np.testing.assert_allclose(streamed.fix_errors.dr_held_s, held, rtol=0, atol=1e-9)
    np.testing.assert_allclose(streamed.fix_errors.ins_error_m, ref_ins_error(cols.fixes, cols.ins,
                                                                             cfg.ins_max_age_s), rtol=0, atol=1e-6)


@pytest.mark.parametrize("case", [dict(bias=2.0), dict(bias=0.0, invalid=(100.0, 104.0)),
                                  dict(bias=0.0, invalid=(100.0, 110.0))])
@pytest.mark.parametrize("block", [1, 5, 4096])
def test_hand_built_dives_streamed(case: dict, block: int) -> None:
    cols = dive_trial(case["bias"], case.get("invalid"))
    assert_same_review(review_vehicle(cols, "auv"), stream_columns(cols, "auv", block_rows=block))


def test_no_dvl_no_ins_and_a_lone_fix_streamed() -> None:
    only_fixes = VehicleColumns(fixes=dive_trial(0.0).fixes)
    assert_same_review(review_vehicle(only_fixes, "auv"), stream_columns(only_fixes, "auv", block_rows=1))
    cols = dive_trial(1.0)
    one = VehicleColumns(fixes=type(cols.fixes)(cols.fixes.t_s[:1], cols.fixes.lat_deg[:1],
                                                cols.fixes.lon_deg[:1]), dvl=cols.dvl, ins=cols.ins)
    assert_same_review(review_vehicle(one, "auv"), stream_columns(one, "auv", block_rows=3))


def long_mission(hours: float) -> VehicleColumns:
    """A DVL at 5 Hz and an INS at 1 Hz going round a 1 km circle, a 60 s dive every 10 minutes."""
    t = np.arange(0.0, hours * 3600.0, 0.2)
    ti = np.arange(0.0, hours * 3600.0, 1.0)
    heading = np.mod(np.degrees(ti * 2.0 / 500.0), 360.0)
    lat = 45.0 + 0.004 * np.sin(ti * 2.0 / 500.0)
    lon = 126.0 + 0.006 * (1.0 - np.cos(ti * 2.0 / 500.0))
    dvl = DvlColumns.build(t, 2.0, 0.0, (t % 97.0) > 3.0, 1, 10.0)
    ins = InsColumns.build(ti, lat, lon, heading, 5.0, 2.0 * np.cos(np.radians(heading)),
                           2.0 * np.sin(np.radians(heading)))
    fix = (ti % 600.0) < 540.0
    return VehicleColumns(fixes=type(dive_trial(0.0).fixes).build(ti[fix], lat[fix], lon[fix]), dvl=dvl, ins=ins)


def test_the_stream_holds_a_bounded_state_and_bounded_series() -> None:
    cols = long_mission(3.0)
    s = NavigationStream("auv", 0, series_cap=500, block_rows=512)
    d, i, f = cols.dvl, cols.ins, cols.fixes
    rows = sorted([(float(r[0]), "dvl", tuple(r)) for r in np.column_stack(
        [d.t_s, d.vx_mps, d.vy_mps, d.altitude_m, d.valid, d.frame]).tolist()]
        + [(r[0], "ins", tuple(r)) for r in np.column_stack(
            [i.t_s, i.lat_deg, i.lon_deg, i.heading_deg, i.depth_m, i.vn_mps, i.ve_mps]).tolist()]
        + [(r[0], "gps", tuple(r)) for r in np.column_stack([f.t_s, f.lat_deg, f.lon_deg]).tolist()],
        key=lambda r: r[0])
    most = 0
    for t, kind, row in rows:
        s.add(kind, row)
        if s.pending >= s.block_rows:
            s.settle(t)
            most = max(most, s._ins.shape[0], s.pending)
    assert most < 600       # the rows of a stretch and the INS seconds behind it, not hours of samples
    review = s.finish()
    whole = review_vehicle(cols, "auv")
    assert_same_review(whole, review, series=False)
    assert 250 <= review.dead_reckoning.t_s.size <= 500       # a track of 10,800 seconds, every 32nd kept
    for sw, ss in zip(whole.series.all(), review.series.all(), strict=True):
        assert 250 <= len(ss) <= 500 and len(sw) > 10_000, sw.name
        stride = len(sw) // len(ss) if len(sw) % len(ss) == 0 else (len(sw) + len(ss) - 1) // len(ss)
        # every stride-th sample of the whole series, the stride a power of two
        assert stride & (stride - 1) == 0
        np.testing.assert_array_equal(ss.t_s, sw.t_s[::stride][: len(ss)])
        np.testing.assert_array_equal(ss.values, sw.values[::stride][: len(ss)])


# -- the sample trial, through the replay ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def lake_archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("lake") / "trial.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), out)
    return out


def test_sample_trial_replay_navigation_is_the_whole_mission_review(lake_archive: Path) -> None:
    outcome = replay_archive(lake_archive, write_output=False, review=True)
    with ArchiveReader(lake_archive) as reader:
        start = reader.summary().start_ns
        for vehicle, figures in outcome.metrics["navigation"].items():
            cols = read_columns(reader, vehicle, start)
            whole = review_vehicle(cols, vehicle)
            assert figures == review_metrics(whole), vehicle
            assert_same_review(whole, outcome.review.navigation[vehicle])
            # small stretches through the collector itself: the same
            collector = StreamCollector([vehicle], start, block_rows=7)
            topics = [t for t in collector.topics if t in reader.summary().topics]
            for m in reader.messages(topics):
                collector.add(m.topic, m.log_time_ns, m.message)
            assert_same_review(whole, collector.review(vehicle))
    assert math.isfinite(outcome.metrics["navigation"]["follower"]["methods"]["ins"]["error_p50_m"])
