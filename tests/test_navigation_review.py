"""The one-vehicle navigation review (replay/navigation): the numpy paths against per-sample loops, hand-built
cases with known answers, and the sample trial's follower."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.mcap_reader import ArchiveReader
from recorders.manifest import load_manifest
from recorders.record import record
from replay.errors import UserError
from replay.navigation import NavigationConfig, review_vehicle, scores
from replay.navigation.bottom_lock import bottom_lock
from replay.navigation.columns import BODY_FRD, EARTH_NED, DvlColumns, FixColumns, InsColumns, VehicleColumns
from replay.navigation.dead_reckoning import dead_reckon, heading_at, offset_to_latlon
from replay.navigation.drift import ins_before
from replay.stack.model import horizontal_distance_scalar, metric_scales_scalar
from replay.stack.model import offset_to_latlon as offset_to_latlon_scalar

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
M_PER_DEG = 111_320.0  # metres per degree of latitude, to state tolerances in metres


# -- slow per-sample references -------------------------------------------------------------------------------
def ref_heading(t: float, ht: list[float], hd: list[float], max_gap: float) -> float:
    """Heading (rad) at t between the samples around it, along the shorter arc; NaN where unknown."""
    pairs = [(a, b) for a, b in zip(ht, hd) if math.isfinite(a) and math.isfinite(b)]
    before = [p for p in pairs if p[0] <= t]
    after = [p for p in pairs if p[0] >= t]
    if not before or not after:
        return math.nan
    (t0, h0), (t1, h1) = before[-1], after[0]
    if t1 - t0 > max_gap:
        return math.nan
    if t1 == t0:
        return math.radians(h0) % (2 * math.pi)
    turn = (h1 - h0 + 180.0) % 360.0 - 180.0
    return math.radians(h0 + turn * (t - t0) / (t1 - t0)) % (2 * math.pi)


def ref_dr(t_a: float, t_q: float, dvl: DvlColumns, ins: InsColumns, hold: float,
           max_gap: float) -> tuple[float, float, float, float]:
    """(north, east, path, carried seconds) from t_a to t_q, one DVL interval at a time; NaNs where unknown."""
    nan4 = (math.nan,) * 4
    t = dvl.t_s.tolist()
    usable = dvl.usable.tolist()
    ht, hd = ins.t_s.tolist(), ins.heading_deg.tolist()
    k = max((i for i in range(len(t)) if t[i] <= t_a), default=-1)
    if k < 0 or t_q < t_a:
        return nan4
    north = east = path = held = 0.0
    now = t_a
    while True:
        j = max((i for i in range(k + 1) if usable[i]), default=-1)
        if j < 0:
            return nan4
        end = t[k + 1] if k + 1 < len(t) else math.inf
        seg_end = min(end, t_q)
        if seg_end > t[j] + hold:
            return nan4
        x, y, frame = float(dvl.vx_mps[j]), float(dvl.vy_mps[j]), int(dvl.frame[j])
        if frame == BODY_FRD:
            h = ref_heading(t[k], ht, hd, max_gap)
            vn, ve = x * math.cos(h) - y * math.sin(h), x * math.sin(h) + y * math.cos(h)
        else:
            vn, ve = x, y
        if not (math.isfinite(vn) and math.isfinite(ve)):
            return nan4
        dt = seg_end - now
        north += vn * dt
        east += ve * dt
        path += math.hypot(vn, ve) * dt
        held += dt if j != k else 0.0
        if seg_end == t_q:
            return north, east, path, held
        now, k = end, k + 1


def ref_fix_errors(fixes: FixColumns, dvl: DvlColumns, ins: InsColumns, hold: float,
                   max_gap: float) -> tuple[list[float], list[float], list[float]]:
    """DR error, path and carried seconds at every fix, each fix's DR run from the previous fix."""
    err, path, held = [math.nan], [math.nan], [math.nan]
    for i in range(1, fixes.t_s.size):
        la0, lo0 = math.radians(fixes.lat_deg[i - 1]), math.radians(fixes.lon_deg[i - 1])
        n, e, p, h = ref_dr(float(fixes.t_s[i - 1]), float(fixes.t_s[i]), dvl, ins, hold, max_gap)
        if math.isnan(n):
            err.append(math.nan)
        else:
            la, lo = offset_to_latlon_scalar(n, e, la0, lo0)
            err.append(horizontal_distance_scalar(la, lo, math.radians(fixes.lat_deg[i]),
                                                  math.radians(fixes.lon_deg[i])))
        path.append(p)
        held.append(h)
    return err, path, held


def ref_ins_error(fixes: FixColumns, ins: InsColumns, max_age: float) -> list[float]:
    """The INS's last solution strictly before each fix, carried by its velocity, against the fix."""
    rows = [(float(t), math.radians(a), math.radians(b), float(vn), float(ve))
            for t, a, b, vn, ve in zip(ins.t_s, ins.lat_deg, ins.lon_deg, ins.vn_mps, ins.ve_mps)
            if math.isfinite(a) and math.isfinite(b)]
    out = []
    for tf, fla, flo in zip(fixes.t_s, fixes.lat_deg, fixes.lon_deg):
        k = max((i for i, r in enumerate(rows) if r[0] < tf), default=-1)
        if k < 0 or tf - rows[k][0] > max_age:
            out.append(math.nan)
            continue
        t, la, lo, vn, ve = rows[k]
        if not (math.isfinite(vn) and math.isfinite(ve)):
            j = max(k - 1, 0)
            span = t - rows[j][0]
            b, a = metric_scales_scalar(0.5 * (la + rows[j][1]), 0.0)
            vn = b * (la - rows[j][1]) / span if span > 0 else math.nan
            ve = a * (lo - rows[j][2]) / span if span > 0 else math.nan
        dt = tf - t
        pla, plo = offset_to_latlon_scalar(vn * dt, ve * dt, la, lo)
        out.append(horizontal_distance_scalar(pla, plo, math.radians(fla), math.radians(flo)))
    return out


# -- random but physically plausible trials -------------------------------------------------------------------
@st.composite
def trials(draw: st.DrawFn) -> tuple[FixColumns, DvlColumns, InsColumns, float, float, float]:
    """A DVL at 0.3-3 s with dropouts and silences, an INS whose heading turns across 0/360, fixes with gaps.

    Hypothesis draws the sizes, rates and settings; the samples come from a generator it seeds (hypothesis
    leans its own floats to the ends of their ranges, which would give a vehicle that never moves).
    """
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(2, 40))
    steps = rng.uniform(0.3, draw(st.floats(0.5, 3.0)), n - 1)
    steps[rng.uniform(size=n - 1) < draw(st.floats(0.0, 0.1))] *= 8.0   # the DVL falls silent now and then
    t = np.concatenate([[0.0], np.cumsum(steps)])
    vx, vy = rng.uniform(-0.5, 2.5, n), rng.uniform(-0.5, 0.5, n)
    vx[rng.uniform(size=n) < 0.03] = np.nan
    valid = rng.uniform(size=n) > draw(st.floats(0.0, 0.4))
    frame = rng.choice([BODY_FRD] * 8 + [EARTH_NED, 3, 0], n)
    dvl = DvlColumns.build(t, vx, vy, valid, frame)

    spacing = draw(st.floats(0.2, 1.5))                                  # heading over the DVL's span, jittered,
    m = int((t[-1] + 4.0) / spacing) + 2                                 # with samples lost now and then
    ht = rng.uniform(-2.0, 0.5) + (np.arange(m) + 0.4 * rng.uniform(size=m)) * spacing
    ht = ht[rng.uniform(size=m) > draw(st.floats(0.0, 0.3))]
    m = ht.size
    turns = rng.uniform(-170.0, 170.0, m) * draw(st.sampled_from([0.05, 0.5, 1.0]))
    hd = np.mod(rng.uniform(0.0, 360.0) + np.cumsum(turns), 360.0)
    lat0, lon0 = draw(st.floats(-70.0, 70.0)), draw(st.floats(-170.0, 170.0))
    walk = np.cumsum(rng.uniform(-3e-5, 3e-5, (2, m)), axis=1)
    vn, ve = rng.uniform(-2.5, 2.5, m), rng.uniform(-2.5, 2.5, m)
    vn[rng.uniform(size=m) < 0.2] = np.nan
    ins = InsColumns.build(ht, lat0 + walk[0], lon0 + walk[1], hd, 5.0, vn, ve)

    k = draw(st.integers(1, 12))
    fix_t = np.unique(np.round(rng.uniform(-2.0, t[-1] + 2.0, k), 1))  # rounded: some fall on DVL times
    fixes = FixColumns.build(fix_t, lat0 + rng.uniform(-5e-4, 5e-4, fix_t.size),
                             lon0 + rng.uniform(-5e-4, 5e-4, fix_t.size))
    return fixes, dvl, ins, draw(st.floats(1.0, 10.0)), draw(st.floats(1.0, 6.0)), draw(st.floats(0.5, 6.0))


@settings(max_examples=150, deadline=None)
@given(trials())
def test_dead_reckoning_matches_the_per_sample_loop(trial: tuple) -> None:
    fixes, dvl, ins, hold, max_gap, _ = trial
    dr = dead_reckon(fixes, dvl, ins, hold, max_gap)
    err, path, held = ref_fix_errors(fixes, dvl, ins, hold, max_gap)
    np.testing.assert_allclose(dr.fix_error_m, err, rtol=0, atol=1e-6)
    np.testing.assert_allclose(dr.fix_path_m, path, rtol=0, atol=1e-6)
    np.testing.assert_allclose(dr.fix_held_s, held, rtol=0, atol=1e-9)
    # the track at each DVL time, from the last fix at or before it
    for i, tq in enumerate(dvl.t_s):
        a = int(np.searchsorted(fixes.t_s, tq, side="right")) - 1
        if a < 0:
            assert math.isnan(dr.lat_deg[i])
            continue
        n, e, _, _ = ref_dr(float(fixes.t_s[a]), float(tq), dvl, ins, hold, max_gap)
        if math.isnan(n):
            assert math.isnan(dr.lat_deg[i]) and math.isnan(dr.lon_deg[i])
            continue
        la, lo = offset_to_latlon_scalar(n, e, math.radians(fixes.lat_deg[a]), math.radians(fixes.lon_deg[a]))
        assert horizontal_distance_scalar(la, lo, math.radians(dr.lat_deg[i]), math.radians(dr.lon_deg[i])) < 1e-6


@settings(max_examples=100, deadline=None)
@given(trials())
def test_ins_error_matches_the_per_fix_loop(trial: tuple) -> None:
    fixes, dvl, ins, hold, max_gap, max_age = trial
    cols = VehicleColumns(fixes=fixes, dvl=dvl, ins=ins)
    cfg = NavigationConfig(dvl_hold_s=hold, heading_max_gap_s=max_gap, ins_max_age_s=max_age, dive_gap_s=8.0)
    review = review_vehicle(cols, "auv", cfg)
    np.testing.assert_allclose(review.fix_errors.ins_error_m, ref_ins_error(fixes, ins, max_age), rtol=0,
                               atol=1e-6)
    # the dives are the fixes after a gap longer than the threshold, with their own errors
    gaps = np.diff(fixes.t_s)
    assert len(review.dives) == int((gaps > 8.0).sum())
    np.testing.assert_array_equal(review.dives.dr_error_m, review.fix_errors.dr_error_m[1:][gaps > 8.0])


@settings(max_examples=100, deadline=None)
@given(st.floats(-80.0, 80.0), st.floats(-179.0, 179.0), st.floats(-5e4, 5e4), st.floats(-5e4, 5e4))
def test_vector_offset_to_latlon_is_the_scalar_one(lat: float, lon: float, north: float, east: float) -> None:
    la, lo = offset_to_latlon(np.array([north]), np.array([east]), np.radians([lat]), np.radians([lon]))
    sla, slo = offset_to_latlon_scalar(north, east, math.radians(lat), math.radians(lon))
    assert horizontal_distance_scalar(float(la[0]), float(lo[0]), sla, slo) < 1e-6


# -- hand-built cases -------------------------------------------------------------------------------------------
def test_heading_is_interpolated_across_north() -> None:
    h = heading_at(np.array([1.0, 3.0, 5.0, 20.0]), np.array([0.0, 2.0, 4.0, 6.0, 16.0]),
                   np.array([350.0, 10.0, 350.0, 20.0, 30.0]), max_gap_s=5.0)
    assert math.isclose(math.cos(h[0]), 1.0) and abs(math.sin(h[0])) < 1e-12      # 350 -> 10: through 0, not 180
    assert math.isclose(math.cos(h[1]), 1.0) and abs(math.sin(h[1])) < 1e-12
    assert math.isclose(math.degrees(h[2]), 5.0)                                    # 350 -> 20 at half way
    assert math.isnan(h[3])                                                         # after the last sample


def dive_trial(bias_deg: float, invalid: tuple[float, float] | None = None) -> VehicleColumns:
    """An AUV going east at 2 m/s for a 300 s dive between two exact fixes; its INS 5 m north of the truth."""
    lat0, lon0 = 45.7, 126.6
    t = np.arange(0.0, 301.0, 1.0)
    valid = np.ones(t.size, dtype=bool)
    if invalid is not None:
        valid[(t >= invalid[0]) & (t < invalid[1])] = False
    dvl = DvlColumns.build(t, 2.0, 0.0, valid, BODY_FRD, 8.0)
    north, east = np.full(t.size, 5.0), 2.0 * t
    la, lo = offset_to_latlon(north, east, np.full(t.size, math.radians(lat0)), np.full(t.size, math.radians(lon0)))
    ins = InsColumns.build(t, np.degrees(la), np.degrees(lo), 90.0 + bias_deg, 6.0, 0.0, 2.0)
    fla, flo = offset_to_latlon(np.zeros(2), np.array([0.0, 600.0]), np.full(2, math.radians(lat0)),
                                np.full(2, math.radians(lon0)))
    return VehicleColumns(fixes=FixColumns.build([0.0, 300.0], np.degrees(fla), np.degrees(flo)), dvl=dvl, ins=ins)


def test_a_heading_bias_gives_the_known_drift_at_the_fix() -> None:
    review = review_vehicle(dive_trial(2.0), "auv")
    d = review.dives
    assert len(d) == 1 and d.start_s[0] == 0.0 and d.end_s[0] == 300.0 and d.duration_s[0] == 300.0
    expected = 2.0 * 600.0 * math.sin(math.radians(1.0))      # chord of a 2° turn of a 600 m displacement
    assert abs(d.dr_error_m[0] - expected) < 1e-3
    assert abs(d.distance_m[0] - 600.0) < 1e-9 and bool(d.distance_from_dr[0])
    assert abs(d.dr_pct[0] - 100.0 * expected / 600.0) < 1e-3
    assert abs(d.ins_error_m[0] - 5.0) < 1e-3                   # 5 m north all along, carried 1 s by its velocity
    assert abs(d.ins_pct[0] - 100.0 * 5.0 / 600.0) < 1e-3
    rows = {r.method: r.figures for r in scores(review)}
    assert rows["dead_reckoning (DVL)"]["scored_at"] == "dive ends"
    assert abs(rows["dead_reckoning (DVL)"]["error_max_m"] - expected) < 1e-3
    assert rows["dead_reckoning (DVL)"]["worst_fix_s"] == 300.0 and rows["ins"]["fixes"] == 1


def test_a_short_dropout_is_carried_and_a_long_one_leaves_the_dr_unknown() -> None:
    short = review_vehicle(dive_trial(0.0, invalid=(100.0, 104.0)), "auv")
    assert short.fix_errors.dr_held_s[1] == 4.0                  # 4 samples carried, the velocity unchanged
    assert short.dives.dr_error_m[0] < 1e-3
    long = review_vehicle(dive_trial(0.0, invalid=(100.0, 110.0)), "auv")
    assert math.isnan(long.dives.dr_error_m[0])
    assert math.isfinite(long.dives.ins_error_m[0]) and abs(long.dives.distance_m[0] - 600.0) < 0.1  # INS path
    assert not long.dives.distance_from_dr[0]
    assert any("DR unknown at 1 of 1 fixes" in n for n in long.notes)
    # the track is unknown from hold_s after the last locked sample (99 s) to the next restart (the fix at 300 s)
    tr = long.dead_reckoning
    assert np.isfinite(tr.lat_deg[tr.t_s <= 104.0]).all()
    assert np.isnan(tr.lat_deg[(tr.t_s > 104.0) & (tr.t_s < 300.0)]).all() and np.isfinite(tr.lat_deg[-1])


def test_bottom_lock_gaps_on_a_hand_built_sequence() -> None:
    t = np.arange(0.0, 21.0)
    valid = np.ones(21, dtype=bool)
    valid[[0, 1]] = False          # no lock at the start: a gap from the first sample to t = 2
    valid[5:12] = False            # locked at 4 and 12: an 8 s gap holding 7 samples
    valid[18:] = False             # lost at the end: 17 -> 20
    dvl = DvlColumns.build(t, 1.0, 0.0, valid)
    lock = bottom_lock(dvl, min_gap_s=1.5, bin_s=10.0)
    assert (lock.samples, lock.locked) == (21, 9) and lock.sample_share == 9 / 21
    np.testing.assert_array_equal(lock.gap_start_s, [0.0, 4.0, 17.0])
    np.testing.assert_array_equal(lock.gap_end_s, [2.0, 12.0, 20.0])
    np.testing.assert_array_equal(lock.gap_duration_s, [2.0, 8.0, 3.0])
    np.testing.assert_array_equal(lock.gap_samples, [2, 7, 3])
    assert lock.time_share == pytest.approx(1.0 - 13.0 / 20.0)
    np.testing.assert_array_equal(lock.bin_start_s, [0.0, 10.0])
    np.testing.assert_allclose(lock.bin_share, [3 / 10, 6 / 11])  # t = 20 falls in the last bin
    wide = bottom_lock(dvl, min_gap_s=5.0)
    np.testing.assert_array_equal(wide.gap_start_s, [4.0])
    assert wide.time_share == pytest.approx(0.6)
    none = bottom_lock(DvlColumns.build(t, 1.0, 0.0, np.zeros(21, dtype=bool)))
    assert none.sample_share == 0.0 and none.time_share == 0.0 and none.gap_duration_s.tolist() == [20.0]


def test_ins_before_never_takes_a_solution_at_the_fix_time() -> None:
    ins = InsColumns.build([0.0, 1.0, 2.0], [10.0, 10.001, 10.5], [20.0, 20.0, 20.0], vn_mps=np.nan, ve_mps=np.nan)
    lat, lon = ins_before(ins, np.array([2.0, 9.0, -1.0]), max_age_s=5.0)
    # at t = 2 the solution of t = 1 carried 1 s by the velocity between t = 0 and t = 1, not the jump to 10.5
    assert abs(lat[0] - 10.002) * M_PER_DEG < 1e-3 and lon[0] == pytest.approx(20.0)
    assert math.isnan(lat[1]) and math.isnan(lat[2])             # too old; before any solution


def test_config_refuses_negative_or_non_finite_settings() -> None:
    with pytest.raises(UserError, match="dvl_hold_s"):
        NavigationConfig(dvl_hold_s=-1.0)
    with pytest.raises(UserError, match="dive_gap_s"):
        NavigationConfig(dive_gap_s=math.nan)


# -- the sample trial's follower ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def lake_archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("lake") / "trial.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), out)
    return out


def test_sample_follower_review(lake_archive: Path) -> None:
    with ArchiveReader(lake_archive) as reader:
        review = review_vehicle(reader, "follower")
        with pytest.raises(UserError, match="no /nobody/gps"):
            review_vehicle(reader, "nobody")
    cols = review.columns
    assert cols.fixes.t_s.size == 1701 and cols.dvl.t_s.size == 1701 and cols.ins.t_s.size == 1701
    assert cols.fixes.t_s[0] == 0.0 and cols.fixes.t_s[-1] == 1700.0
    lock = review.bottom_lock
    assert 0.0 <= lock.sample_share <= 1.0 and 0.0 <= lock.time_share <= 1.0
    fe = review.fix_errors
    # fixes every second: the DR runs 1 s (~2 m) between them, so its error is the GPS noise of two fixes
    # (1.8 m rms horizontal, 3 sigma each: under 11 m) plus a second of DVL noise (0.1 m/s)
    assert np.isfinite(fe.dr_error_m[1:]).all() and np.nanmax(fe.dr_error_m) < 11.0
    # the follower's INS is unaided, its position std growing to 26 m: within 3 sigma plus the GPS noise
    assert np.isfinite(fe.ins_error_m[1:]).all() and np.nanmax(fe.ins_error_m) < 3 * 26.0 + 6.0
    assert len(review.dives) == 0
    for s in review.series.all():
        assert len(s) == 1701 and np.isfinite(s.values).all(), s.name
    assert 1.0 < np.median(review.series.speed_dvl.values) < 3.0
    assert 0.0 <= review.series.heading.values.min() and review.series.heading.values.max() < 360.0
    rows = {r.method: r.figures for r in scores(review)}
    assert set(rows) == {"dead_reckoning (DVL)", "ins"}
    assert rows["dead_reckoning (DVL)"]["scored_at"] == "every fix" and rows["ins"]["fixes"] == 1700
    assert 0.0 <= rows["dead_reckoning (DVL)"]["worst_fix_s"] <= 1700.0

    # a 300 s dive made by removing the fixes between 700 s and 1000 s
    f = cols.fixes
    keep = (f.t_s <= 700.0) | (f.t_s >= 1000.0)
    dived = review_vehicle(replace(cols, fixes=FixColumns(f.t_s[keep], f.lat_deg[keep], f.lon_deg[keep])),
                           "follower")
    d = dived.dives
    assert len(d) == 1 and d.duration_s[0] == 300.0 and bool(d.distance_from_dr[0])
    assert 300.0 < d.distance_m[0] < 900.0                       # 1-3 m/s for 300 s
    # heading bias 1.5° plus a walk of 0.03°/sqrt(s) and 0.05 m/s of correlated velocity error on ~2 m/s:
    # well under 10 % of the distance, plus the noise of two GPS fixes
    assert d.dr_error_m[0] < 0.10 * d.distance_m[0] + 11.0
    assert 0.0 < d.dr_pct[0] < 10.0 + 1100.0 / d.distance_m[0]
    assert np.isfinite(d.ins_error_m[0])
    rows = {r.method: r.figures for r in scores(dived)}
    assert rows["dead_reckoning (DVL)"]["scored_at"] == "dive ends"
    assert rows["dead_reckoning (DVL)"]["final_drift_pct"] == d.dr_pct[0]
    assert rows["dead_reckoning (DVL)"]["worst_fix_s"] == 1000.0
