"""`simulate --tracks`: the acoustics and DR sensors simulated along a recorded trial's GPS tracks.

Two archives are built here: the sample trial recorded (three vehicles with GPS, four buoys), and a ROS 1 bag of
one boat (NavSatFix only, a 200 s dive without fixes and a 10 s dropout) recorded as a one-vehicle trial. Each is
simulated on with `simulate --tracks`, the result recorded and replayed. The source fixes are read back with the
mcap library's own reader, not ours.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from formats.geodesy import LocalFrame
from formats.units import NS
from replay.cli import main
from samples.recorded import covered, intersect
from samples.scenario import load_scenario, scenario_to_toml
from samples.trajectories import FOLLOWER_DEPTH_M, LEADER_DEPTH_M, track_from_fixes
from tests.trial_shapes import enu_quaternion, imu, navsatfix, ros1_typestore, write_ros1

ROOT = Path(__file__).resolve().parent.parent
T0 = 1476237600  # 2016-10-12 02:00:00 UTC, s
LAT0, LON0 = 45.7, 126.6
BOAT_S = 2400                  # the boat's log: fixes each second, none in the dive nor the dropout
DIVE = (300, 500)              # 200 s without GPS: over the 30 s limit, the trial is cut after it
DROPOUT = (1500, 1510)         # 10 s without GPS: bridged


def fixes(archive: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Vehicle -> (UTC ns, lat, lon) of its /<v>/gps LocationFix messages, read with the mcap library."""
    out: dict[str, list[tuple[int, float, float]]] = defaultdict(list)
    with open(archive, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            parts = channel.topic.strip("/").split("/")
            if parts[1:] == ["gps"]:
                fix = LocationFix.FromString(message.data)
                out[parts[0]].append((message.log_time, fix.latitude, fix.longitude))
    return {v: tuple(np.array(c) for c in zip(*rows)) for v, rows in out.items()}  # type: ignore[misc]


def table(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def truth(trial: Path) -> dict[str, dict[str, np.ndarray]]:
    """Vehicle -> truth.csv columns (t_s, lat, lon) as arrays."""
    rows: dict[str, list[tuple[float, float, float]]] = defaultdict(list)
    for r in table(trial / "truth.csv"):
        rows[r["vehicle"]].append((float(r["t_s"]), float(r["latitude_deg"]), float(r["longitude_deg"])))
    return {v: dict(zip(("t", "lat", "lon"), (np.array(c) for c in zip(*x)))) for v, x in rows.items()}


def start_ns(trial: Path) -> int:
    s = load_scenario(trial / "scenario.toml").trial
    hh, mm, ss = (int(x) for x in s.start_time_utc.split(":"))
    return int(np.datetime64(s.date, "s").astype(np.int64) + hh * 3600 + mm * 60 + ss) * NS


def simulate(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, str]:
    code = main(["simulate", *args])
    out = capsys.readouterr()
    return code, out.out + out.err


def replay_json(trial: Path, tmp: Path, capsys: pytest.CaptureFixture) -> dict:
    archive = tmp / f"{trial.name}.mcap"
    assert main(["record", str(trial / "trial.toml"), "-o", str(archive), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["replay", str(archive), "--json", "-o", str(tmp / f"{trial.name}-results.mcap")]) == 0
    return json.loads(capsys.readouterr().out)


def finite_metrics(metrics: dict) -> None:
    """Every method that ran has finite errors; the detectors a finite AUC."""
    assert metrics["epochs"] > 100
    for name, m in metrics["methods"].items():
        assert math.isfinite(m["error_p50_m"]) and math.isfinite(m["error_p90_m"]), name
    assert math.isfinite(metrics["methods"]["chi_square"]["auc"])


# ---------------------------------------------------------------- the sample trial's three tracks

@pytest.fixture(scope="module")
def sample(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str]:
    """(the sample trial's archive, the trial simulated on its tracks, what simulate printed)."""
    tmp = tmp_path_factory.mktemp("sample")
    archive = tmp / "sample.mcap"
    assert main(["record", str(ROOT / "samples/lake_trial/trial.toml"), "-o", str(archive), "--quiet"]) == 0
    out = tmp / "on-tracks"
    assert main(["simulate", "--tracks", str(archive), "-o", str(out), "--seed", "3"]) == 0
    return archive, out, (out / "README.md").read_text()


def test_truth_is_the_source_gps_track(sample):
    archive, trial, readme = sample
    src = fixes(archive)
    sim = truth(trial)
    assert set(sim) == {"leader1", "leader2", "follower"}         # the buoys' fixes are not tracks
    assert "tracks: leader1 = leader1, leader2 = leader2, follower = follower" in readme
    t0 = start_ns(trial)
    assert t0 == min(int(t[0]) for t, _, _ in src.values())       # dated where the archive is
    s = load_scenario(trial / "scenario.toml")
    assert s.trial.duration_s == 1700.0 and s.tracks.archive == str(archive.resolve())
    frame = LocalFrame(s.trial.origin_lat_deg, s.trial.origin_lon_deg)
    for v, (t_ns, lat, lon) in src.items():
        if v not in sim:
            continue
        t_s = (t_ns - t0) / NS
        e, n = frame.to_local(lat, lon)
        te, tn = frame.to_local(sim[v]["lat"], sim[v]["lon"])
        # truth.csv at 1 Hz, 7 decimals (1.1 cm); between its rows, linear like the track itself
        de = np.interp(t_s, sim[v]["t"], te) - e
        dn = np.interp(t_s, sim[v]["t"], tn) - n
        assert len(t_s) == 1701 and np.max(np.hypot(de, dn)) < 0.02, v


def test_ranges_are_the_tracks_distances_plus_the_configured_noise(sample):
    archive, trial, _ = sample
    src = fixes(archive)
    t0 = start_ns(trial)
    s = load_scenario(trial / "scenario.toml")
    frame = LocalFrame(s.trial.origin_lat_deg, s.trial.origin_lon_deg)

    def at(v: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t_ns, lat, lon = src[v]
        e, n = frame.to_local(lat, lon)
        return np.interp(t, (t_ns - t0) / NS, e), np.interp(t, (t_ns - t0) / NS, n)

    rows = table(trial / "ranges.csv")
    assert {r["leader"] for r in rows} == {"leader1", "leader2"}
    noise = []
    for leader in ("leader1", "leader2"):
        mine = [r for r in rows if r["leader"] == leader]
        t = np.array([float(r["t_s"]) for r in mine])
        fe, fn = at("follower", t)
        le, ln = at(leader, t)
        dist = np.sqrt((fe - le) ** 2 + (fn - ln) ** 2 + (FOLLOWER_DEPTH_M - LEADER_DEPTH_M) ** 2)
        true = np.array([float(r["range_true_m"]) for r in mine])
        assert np.max(np.abs(true - dist)) < 2e-3        # ranges.csv's millimetres
        clean = np.array([r["injected"] == "" for r in mine])        # nothing injected
        noise.append((np.array([float(r["range_m"]) for r in mine]) - true)[clean])
    e = np.concatenate(noise)
    sigma = s.ranging.range_sigma_m
    assert len(e) > 500
    assert abs(e.mean()) < 4 * sigma / math.sqrt(len(e))
    assert e.std() == pytest.approx(sigma, rel=0.1)


def test_its_scenario_reproduces_it_and_its_replay_has_finite_metrics(sample, tmp_path, capsys):
    _, trial, _ = sample
    again = tmp_path / "again"
    code, _ = simulate(capsys, "--scenario", str(trial / "scenario.toml"), "-o", str(again), "--seed", "3")
    assert code == 0
    for name in ("ranges.csv", "truth.csv", "scenario.toml", "follower/dvl.pd0", "follower/ins.log"):
        assert (again / name).read_bytes() == (trial / name).read_bytes(), name
    assert scenario_to_toml(load_scenario(trial / "scenario.toml")) == (trial / "scenario.toml").read_text()
    finite_metrics(replay_json(trial, tmp_path, capsys))


def test_dr_sensors_follow_the_tracks_motion(sample):
    """The simulated follower's DVL speed and INS heading agree with the motion of its recorded fixes."""
    from samples.simulator import simulate_trial

    _, trial, _ = sample
    sim = simulate_trial(load_scenario(trial / "scenario.toml"), 3)
    k = sim.vehicle("follower").track
    h = np.radians(k.heading_deg)
    dt = float(k.t_s[1] - k.t_s[0])
    # the track's own DR (heading, surge, sway) stays within the fixes' noise (1.8 m RMS) of the track
    ve, vn = k.surge_mps * np.sin(h) + k.sway_mps * np.cos(h), k.surge_mps * np.cos(h) - k.sway_mps * np.sin(h)
    e = k.east_m[0] + np.concatenate(([0.0], np.cumsum(ve[:-1]) * dt))
    n = k.north_m[0] + np.concatenate(([0.0], np.cumsum(vn[:-1]) * dt))
    assert np.max(np.hypot(e - k.east_m, n - k.north_m)) < 4.0
    # course over 10 s of the truth against the heading at mid-interval
    c = np.degrees(np.arctan2(k.east_m[100:] - k.east_m[:-100], k.north_m[100:] - k.north_m[:-100]))
    d = (c - k.heading_deg[50:-50] + 180) % 360 - 180
    assert np.median(np.abs(d)) < 2.0
    dvl = sim.vehicle("follower").dvl
    speed = np.hypot(np.diff(k.east_m[::10]), np.diff(k.north_m[::10]))      # 1 s differences
    assert np.median(dvl.forward_mps) == pytest.approx(np.median(speed), abs=0.05)


def test_the_conditions_table_still_applies(sample):
    """A sound-speed bias of 1 % scales every range along the recorded tracks; USBL epochs are simulated too."""
    from dataclasses import replace

    from samples.simulator import simulate_trial

    _, trial, _ = sample
    base = load_scenario(trial / "scenario.toml")
    biased = replace(base, conditions=replace(base.conditions, sound_speed_bias=0.01))
    sim = simulate_trial(biased, 3)
    r = sim.ranges
    clean = r.injected == 0
    ratio = (r.range_m[clean] - r.range_true_m[clean]) / r.range_true_m[clean]
    assert np.median(ratio) == pytest.approx(0.01, abs=0.002)
    assert len(sim.usbl.t_s) == 340 and sim.notes == ("tracks: leader1 = leader1, leader2 = leader2, "
                                                       "follower = follower",)


# ---------------------------------------------------------------- one boat's track

def write_boat_bag(path: Path) -> None:
    """A boat's NavSatFix each second on a Lissajous path (up to ~2 m/s) with 0.5 m noise, none in the dive or
    the dropout, and an Imu at 1 Hz (no position)."""
    ts = ros1_typestore()
    rng = np.random.default_rng(5)
    items = []
    for k in range(BOAT_S + 1):
        if DIVE[0] < k < DIVE[1] or DROPOUT[0] < k < DROPOUT[1]:
            continue
        e = 400 * math.sin(2 * math.pi * k / 1200) + rng.normal(0, 0.5)
        n = 250 * math.sin(2 * math.pi * k / 800) + rng.normal(0, 0.5)
        lat, lon = LocalFrame(LAT0, LON0).to_geodetic(e, n)
        items += [navsatfix(ts, (T0 + k) * NS, lat, lon, 120.0), imu(ts, (T0 + k) * NS + 1, enu_quaternion(ts, 0.0))]
    write_ros1(path, ts, items)


def one_vehicle_archive(tmp: Path, name: str, write) -> Path:
    write(tmp / f"{name}.bag")
    (tmp / f"{name}.toml").write_text(
        f'[trial]\nname = "{name}"\ndate = "2016-10-12"\n[[vehicles]]\nname = "boat"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "rosbag"\npath = "{name}.bag"\n')
    archive = tmp / f"{name}.mcap"
    assert main(["record", str(tmp / f"{name}.toml"), "-o", str(archive), "--quiet"]) == 0
    return archive


def test_one_vehicle_gives_leaders_offset_in_time_and_replays(tmp_path, capsys):
    archive = one_vehicle_archive(tmp_path, "boat", write_boat_bag)
    capsys.readouterr()
    out = tmp_path / "boat-trial"
    code, printed = simulate(capsys, "--tracks", str(archive), "-o", str(out))
    assert code == 0
    lines = printed.splitlines()
    assert lines[1] == ("one vehicle with a GPS track (boat): it is the follower, and each leader is its own track "
                        "ahead in time (leader1 +300 s, leader2 +600 s)")
    assert lines[2] == ("GPS gaps over 30 s: the trial is cut to the longest span every track covers, 1300 s from "
                        "2016-10-12T02:08:20+00:00")
    s = load_scenario(out / "scenario.toml")
    # after the dive (500 s) to the end (2400 s) less the second leader's 600 s ahead; the dropout bridged
    assert (s.trial.start_time_utc, s.trial.duration_s) == ("02:08:20", 1300.0)
    sim = truth(out)
    for k, leader in ((1, "leader1"), (2, "leader2")):
        lag = int(300 * k)
        f, ld = sim["follower"], sim[leader]
        assert np.array_equal(ld["lat"][:-lag], f["lat"][lag:]) and np.array_equal(ld["lon"][:-lag], f["lon"][lag:])
    # the follower's truth is the boat's fixes, the dropout's seconds interpolated between them
    src_t, src_lat, _ = fixes(archive)["boat"]
    t_s = (src_t - start_ns(out)) / NS
    inside = (t_s >= 0) & (t_s <= 1300)
    assert np.max(np.abs(np.interp(t_s[inside], sim["follower"]["t"], sim["follower"]["lat"])
                         - src_lat[inside])) < 2e-7
    finite_metrics(replay_json(out, tmp_path, capsys))


# ---------------------------------------------------------------- bad input

def write_one_fix_bag(path: Path) -> None:
    ts = ros1_typestore()
    write_ros1(path, ts, [navsatfix(ts, T0 * NS, LAT0, LON0), imu(ts, T0 * NS + 5 * NS, enu_quaternion(ts, 0.0))])


def write_imu_bag(path: Path) -> None:
    ts = ros1_typestore()
    write_ros1(path, ts, [imu(ts, (T0 + k) * NS, enu_quaternion(ts, 0.0)) for k in range(5)])


def test_bad_input_is_one_line_and_exit_1(tmp_path, capsys, sample):
    text = tmp_path / "notes.mcap"
    text.write_text("not an archive\n")
    one = one_vehicle_archive(tmp_path, "one", write_one_fix_bag)
    imu_only = one_vehicle_archive(tmp_path, "imu", write_imu_bag)
    capsys.readouterr()
    cases = {
        str(text): "not an MCAP file",
        str(tmp_path / "missing.mcap"): "cannot read",
        str(imu_only): "no GPS track",
        str(one): "every GPS track has one point (boat)",
    }
    for path, says in cases.items():
        code, printed = simulate(capsys, "--tracks", path, "-o", str(tmp_path / "out"))
        assert code == 1 and len(printed.strip().splitlines()) == 1 and says in printed, printed
    code, printed = simulate(capsys, "--tracks", str(sample[0]), "--follower", "nobody", "-o", str(tmp_path / "out"))
    assert code == 1 and "no GPS track of vehicle 'nobody' to follow; tracks: leader1, leader2, follower" in printed
    code, printed = simulate(capsys, "--tracks", str(sample[0]), "--leaders", "0", "-o", str(tmp_path / "out"))
    assert code == 1 and "[tracks]: leaders >= 1" in printed
    code, printed = simulate(capsys, "--follower", "x", "-o", str(tmp_path / "out"))
    assert code == 1 and "go with --tracks" in printed
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- the numerics, against slow references

@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.1, 60.0), min_size=0, max_size=40), st.floats(0.0, 40.0))
def test_covered_spans_split_at_gaps_over_the_limit(steps, max_gap):
    t = np.cumsum([0.0, *steps])
    want, first = [], 0
    for i in range(1, len(t) + 1):
        if i == len(t) or t[i] - t[i - 1] > max_gap:
            if t[i - 1] > t[first]:
                want.append((t[first], t[i - 1]))
            first = i
    assert covered(t, max_gap) == want


spans = st.lists(st.floats(0.0, 100.0), max_size=12).map(
    lambda xs: [(a, b) for a, b in zip(sorted(xs)[::2], sorted(xs)[1::2]) if b > a])


@settings(max_examples=100, deadline=None)
@given(spans, spans)
def test_intersect_is_every_pairwise_overlap(a, b):
    a = [s for i, s in enumerate(a) if i == 0 or s[0] > a[i - 1][1]]      # disjoint, as covered() gives
    b = [s for i, s in enumerate(b) if i == 0 or s[0] > b[i - 1][1]]
    want = sorted((max(p[0], q[0]), min(p[1], q[1])) for p in a for q in b if min(p[1], q[1]) > max(p[0], q[0]))
    assert intersect(a, b) == want


@settings(max_examples=40, deadline=None)
@given(st.floats(0.3, 4.0), st.floats(0.0, 359.0), st.floats(0.0, 10.0))
def test_a_straight_track_passes_through_its_fixes_with_its_course_and_speed(speed, course, smoothing):
    """Fixes of a vehicle on a straight line at constant speed: the track is the line, its heading the course and
    its surge the speed everywhere, ends included."""
    fix_t = np.arange(0.0, 121.0)
    h = math.radians(course)
    e, n = 10 + speed * np.sin(h) * fix_t, -5 + speed * np.cos(h) * fix_t
    t = np.arange(1201) * 0.1
    k = track_from_fixes("boat", fix_t, e, n, t, LocalFrame(LAT0, LON0), 2.5, 0, smoothing)
    np.testing.assert_allclose(k.east_m[::10], e, atol=1e-9)
    np.testing.assert_allclose(k.north_m[::10], n, atol=1e-9)
    assert np.max(np.abs((k.heading_deg - course + 180) % 360 - 180)) < 1e-6
    np.testing.assert_allclose(k.surge_mps, speed, atol=1e-6)
    np.testing.assert_allclose(k.sway_mps, 0.0, atol=1e-6)
