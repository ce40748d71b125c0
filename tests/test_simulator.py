"""The lake-trial simulator: determinism, statistics, noise models, anomalies, logs and the command."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.geodesy import LocalFrame, earth_radii
from samples import anomalies as an
from samples.scenario import (
    AnomalyEvent,
    Scenario,
    ScenarioError,
    TrialConfig,
    load_scenario,
    scenario_from_dict,
    scenario_to_toml,
)
from samples.simulator import simulate_trial
from samples.trajectories import gauss_markov, stream
from samples.writer import render


@pytest.fixture(scope="module")
def trial():
    """The default trial (the sample), simulated once."""
    return simulate_trial(Scenario(), 0)


@pytest.fixture(scope="module")
def short():
    """A 5-minute trial with two followers, for the log tests."""
    return simulate_trial(Scenario().with_options(300.0, 2), 3)


# ---- scenario

def test_scenario_toml_round_trip(tmp_path):
    sc = Scenario().with_options(900.0, 2)
    path = tmp_path / "s.toml"
    path.write_text(scenario_to_toml(sc))
    assert load_scenario(path) == sc


def test_scenario_rejects_unknown_keys_and_bad_events():
    with pytest.raises(ScenarioError, match="unknown key"):
        scenario_from_dict({"trial": {"duraton_s": 10}})
    with pytest.raises(ScenarioError, match="bad event"):
        scenario_from_dict({"anomalies": [{"leader": "leader1", "kind": "melt", "start_s": 1, "end_s": 2}]})
    with pytest.raises(ScenarioError, match="unknown table"):
        scenario_from_dict({"gsp": {}})


def test_integer_values_are_read_as_floats():
    sc = scenario_from_dict({"trial": {"duration_s": 120}, "anomalies": [
        {"leader": "leader1", "kind": "drift", "start_s": 10, "end_s": 20, "magnitude_m": 5}]})
    assert sc.trial.duration_s == 120.0 and isinstance(sc.trial.duration_s, float)
    assert sc.anomalies == (AnomalyEvent("leader1", "drift", 10.0, 20.0, 5.0),)


# ---- geometry and noise primitives

@settings(max_examples=50, deadline=None)
@given(st.floats(-3000, 3000), st.floats(-3000, 3000), st.floats(-60, 60), st.floats(-179, 179))
def test_local_frame_round_trip(east, north, lat0, lon0):
    frame = LocalFrame(lat0, lon0)
    lat, lon = frame.to_geodetic(np.array([east]), np.array([north]))
    e, n = frame.to_local(lat, lon)
    assert e[0] == pytest.approx(east, abs=1e-6) and n[0] == pytest.approx(north, abs=1e-6)


def test_local_frame_agrees_with_stack_range_formula():
    frame = LocalFrame(45.7, 126.6)
    lat, lon = frame.to_geodetic(np.array([-400.0, 500.0]), np.array([-100.0, 300.0]))
    z = an.gps_range(lat[:1], lon[:1], lat[1:], lon[1:], np.zeros(1), np.zeros(1))
    assert z[0] == pytest.approx(math.hypot(900.0, 400.0), rel=3e-5)  # ~1 cm per km
    rm, rn = earth_radii(math.radians(45.7))
    assert 6.36e6 < rm < rn < 6.40e6


def test_gauss_markov_is_stationary_with_the_given_sigma():
    x = gauss_markov(np.random.default_rng(1), 200_000, 1.0, 2.0, 5.0)
    assert x.std() == pytest.approx(2.0, rel=0.03)
    lag1 = np.corrcoef(x[:-1], x[1:])[0, 1]
    assert lag1 == pytest.approx(math.exp(-1 / 5.0), abs=0.01)


def test_streams_are_independent_per_name():
    a = stream(0, "gps", "leader1").random(3)
    assert np.array_equal(a, stream(0, "gps", "leader1").random(3))
    assert not np.array_equal(a, stream(0, "gps", "leader2").random(3))


# ---- anomaly application

@settings(max_examples=60, deadline=None)
@given(st.floats(0, 80), st.floats(1, 60), st.integers(0, 2**32 - 1))
def test_stale_holds_the_last_reply_and_drift_ramps(start, length, seed):
    t = np.arange(0.0, 200.0, 4.8)
    noisy = 500.0 + np.random.default_rng(seed).normal(0, 3, len(t))
    events = [AnomalyEvent("leader1", "stale", start, start + length),
              AnomalyEvent("leader1", "drift", 120.0, 180.0, 30.0)]
    measured, replied, kinds = an.apply_events(t, noisy, events)
    inside = (t >= start - 1e-9) & (t <= start + length + 1e-9)
    assert replied.all()
    if inside.any():
        before = np.flatnonzero(t < start - 1e-9)
        held = measured[before[-1]] if len(before) else noisy[np.flatnonzero(inside)[0]]
        assert np.all(measured[inside] == held) and np.all(kinds[inside] == 1)
    drift = (t >= 120.0) & (t <= 180.0) & ~inside
    np.testing.assert_allclose(measured[drift] - noisy[drift], 30.0 * (t[drift] - 120.0) / 60.0)
    clean = ~inside & ~((t >= 120.0) & (t <= 180.0))
    assert np.array_equal(measured[clean], noisy[clean]) and np.all(kinds[clean] == 0)


def test_dropouts_remove_epochs_and_stale_skips_them():
    t = np.arange(0.0, 50.0, 5.0)
    noisy = np.arange(len(t), dtype=float) + 100.0
    events = [AnomalyEvent("l", "dropout", 10.0, 15.0), AnomalyEvent("l", "stale", 20.0, 30.0),
              AnomalyEvent("l", "outlier", 40.0, 40.0, -20.0)]
    measured, replied, kinds = an.apply_events(t, noisy, events)
    assert replied.tolist() == [True, True, False, False] + [True] * 6
    assert measured[4:7].tolist() == [101.0, 101.0, 101.0]  # the reply before the dropouts
    assert measured[8] == 88.0 and kinds[8] == 3


def test_labels_follow_the_9_m_rule():
    z_gps = np.array([100.0, 100.0, 100.0])
    assert an.label(z_gps, np.array([109.0, 109.01, 91.0])).tolist() == [0, 1, 0]


# ---- the default trial: the source statistics (docs/design.md section 15)

def test_range_statistics_match_the_source_within_5_percent(trial):
    r = trial.ranges
    for leader in ("leader1", "leader2"):
        assert abs((r.leader == leader).sum() - 340) <= 0.05 * 340
    test = r.t_s > 600.0
    assert abs(test.sum() - 462) <= 0.05 * 462
    assert abs(int(r.label[test].sum()) - 57) <= 0.05 * 57
    assert np.all(np.diff(r.t_s) > 0)
    # leaders alternate: consecutive epochs of one follower change leader unless a ping dropped
    assert np.mean(r.leader[1:] != r.leader[:-1]) > 0.95


def test_every_leader_has_a_labelled_anomaly_in_the_training_window(trial):
    r = trial.ranges
    for leader in ("leader1", "leader2"):
        assert r.label[(r.leader == leader) & (r.t_s <= 600.0)].sum() >= 3


def test_measured_minus_true_is_the_configured_noise_outside_anomalies(trial):
    r = trial.ranges
    clean = r.injected == 0
    err = r.range_m[clean] - r.range_true_m[clean]
    sigma = trial.scenario.ranging.range_sigma_m
    assert np.abs(err).max() < 5 * sigma
    assert err.std() == pytest.approx(sigma, rel=0.1)
    assert abs(err.mean()) < 0.5


def test_source_anomalies_are_where_the_source_puts_them(trial):
    r = trial.ranges
    l1 = r.leader == "leader1"
    stale = l1 & (r.t_s >= 100.0) & (r.t_s <= 150.0)
    assert np.all(r.injected[stale] == 1) and len(np.unique(r.range_m[stale])) == 1
    drift = l1 & (r.t_s >= 1100.0) & (r.t_s <= 1170.0)
    excess = r.range_m[drift] - r.range_true_m[drift]
    assert np.all(r.injected[drift] == 2) and excess[-1] > 15.0 and excess[0] < 10.0
    assert r.label[drift].sum() >= 5


def test_gps_fixes_are_within_5_sigma_of_truth(trial):
    for v in trial.vehicles:
        g = v.gps
        e = g.east_m - np.interp(g.t_s, v.track.t_s, v.track.east_m)
        n = g.north_m - np.interp(g.t_s, v.track.t_s, v.track.north_m)
        assert np.abs(e).max() < 5 * g.sigma_m and np.abs(n).max() < 5 * g.sigma_m
        assert math.sqrt(np.mean(e**2 + n**2)) == pytest.approx(1.8, rel=0.25)


def test_follower_ins_heading_has_bias_and_walk_and_dvl_its_accuracy(trial):
    f = trial.vehicle("follower")
    true = np.interp(f.ins.t_s, f.track.t_s, np.degrees(np.unwrap(np.radians(f.track.heading_deg))))
    err = (f.ins.heading_deg - true + 180.0) % 360.0 - 180.0
    assert err[0] == pytest.approx(trial.scenario.ins.follower_heading_bias_deg, abs=0.01)
    assert err.std() > 0.1
    d = f.dvl
    surge = np.interp(d.t_s, f.track.t_s, f.track.surge_mps)
    assert (d.forward_mps - surge).std() == pytest.approx(trial.scenario.dvl.sigma_mps, rel=0.1)


def test_tracks_cover_about_a_kilometre_at_boat_speeds(trial):
    for v in trial.vehicles:
        span = max(np.ptp(v.track.east_m), np.ptp(v.track.north_m))
        speed = np.hypot(v.track.vel_north_mps, v.track.vel_east_mps)
        assert 100.0 < span < 1500.0 and 1.0 < speed.mean() < 3.0


def test_usbl_delays_and_phases_follow_seed_k_outside_faults(trial):
    u = trial.usbl
    ok_d, ok_p = ~u.abnormal_delay, ~u.abnormal_phase
    assert np.abs(u.delay_s - u.delay_true_s)[ok_d].max() < 5 * trial.scenario.usbl.delay_sigma_s
    assert np.abs(u.phase_x_rad - u.phase_x_true_rad)[ok_p].max() < 5 * trial.scenario.usbl.phase_sigma_rad
    assert u.kappa_d0_rad == pytest.approx(2 * math.pi * 75e3 / 1450.0 * 0.18)
    # buoy2's scripted delay fault covers 400-700 s
    rows = (u.t_s >= 400.0) & (u.t_s <= 700.0)
    assert u.abnormal_delay[rows, 1].all() and not u.abnormal_phase[rows, 1].any()
    assert np.all(u.delay_s[u.abnormal_delay] < 2830.0 / 1450.0)


def test_deterministic_per_seed_and_different_across_seeds(trial):
    again = simulate_trial(Scenario(), 0)
    assert np.array_equal(again.ranges.range_m, trial.ranges.range_m)
    assert np.array_equal(again.usbl.phase_y_rad, trial.usbl.phase_y_rad)
    other = simulate_trial(Scenario(), 1)
    assert not np.array_equal(other.vehicle("follower").gps.lat_deg, trial.vehicle("follower").gps.lat_deg)


def test_extra_followers_leave_the_leaders_untouched(trial, short):
    assert [v.name for v in short.vehicles] == ["leader1", "leader2", "follower", "follower2"]
    assert set(np.unique(short.ranges.follower)) == {"follower", "follower2"}
    base = simulate_trial(Scenario().with_options(300.0, 1), 3)
    assert np.array_equal(base.vehicle("leader1").gps.lat_deg, short.vehicle("leader1").gps.lat_deg)


# ---- logs on disk

def test_logs_decode_without_a_single_reject(short):
    from formats import phins
    from formats.evologics import notifications as evologics
    from formats.micromodem import sentences as micromodem
    from formats.nmea import sentences as nmea
    from formats.novatel import logs as novatel
    from formats.pd0 import ensembles as pd0
    from formats.records import Reject

    by_name = {"gps.log": nmea.decode, "ins.log": phins.decode, "dvl.pd0": pd0.decode,
               "modem.log": micromodem.decode, "usbl.log": evologics.decode}
    checked = 0
    for rel, data in render(short).items():
        name = rel.split("/")[-1]
        if name not in by_name:
            continue
        decode = novatel.decode if data.startswith(b"#") else by_name[name]
        records = list(decode(data))
        assert records and not any(isinstance(r, Reject) for r in records), rel
        checked += 1
    assert checked == 4 * 4 + 4 * 2


def test_manifest_lists_every_log_and_parses(short, tmp_path):
    from recorders.manifest import parse_manifest

    files = render(short)
    m = parse_manifest(files["trial.toml"].decode(), tmp_path / "trial.toml")
    assert {log.path for log in m.logs()} == {k for k in files if "/" in k}
    assert m.address_book()[3] == "follower" and m.address_book()[11] == "buoy1"
    roles = {v.name: v.role for v in m.vehicles}
    assert roles["follower2"] == "follower" and roles["buoy4"] == "buoy"
    assert m.sound_speed_mps == 1450.0


def test_render_is_byte_identical_and_csvs_agree_with_arrays(short):
    a, b = render(short), render(simulate_trial(replace(Scenario().with_options(300.0, 2)), 3))
    assert a == b
    rows = a["ranges.csv"].decode().splitlines()
    assert len(rows) == len(short.ranges.t_s) + 1
    anomalies = a["anomalies.csv"].decode().splitlines()
    assert anomalies[0].startswith("vehicle,leader,kind,start_s,end_s")
    assert len(anomalies) == len(short.intervals) + 1


def test_modem_log_holds_one_reply_per_range_and_commands_for_dropouts(short):
    data = render(short)["follower/modem.log"].decode()
    pings = short.pings
    mine = pings.follower == "follower"
    assert data.count("$CCMPC") == mine.sum()
    assert data.count("$CAMPR") == (mine & pings.replied).sum()
    assert data.count("$CAMPR") == (short.ranges.follower == "follower").sum()


def test_simulate_command(tmp_path, capsys):
    from replay.cli import main

    out = tmp_path / "trial"
    assert main(["simulate", "-o", str(out), "--duration", "120", "--followers", "2", "--seed", "5"]) == 0
    assert (out / "trial.toml").is_file() and (out / "follower2" / "dvl.pd0").is_file()
    assert "ranges" in capsys.readouterr().out
    assert main(["simulate", "-o", str(out), "--duration", "120"]) == 1
    assert "not empty" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[trial]\nduration_s = -5\n")
    assert main(["simulate", "-o", str(tmp_path / "x"), "--scenario", str(bad)]) == 1
    assert "scenario" in capsys.readouterr().err
    assert main(["simulate", "-o", str(tmp_path / "y"), "--seed", "-1"]) == 1
    assert "--seed must be >= 0" in capsys.readouterr().err and not (tmp_path / "y").exists()


def test_trial_config_defaults_are_the_source_trial():
    t = TrialConfig()
    assert (t.date, t.duration_s, t.training_window_s, t.followers) == ("2016-10-12", 1700.0, 600.0, 1)
