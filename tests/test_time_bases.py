"""Logs whose clocks are not UTC (docs/time-bases.md): a ROS 1 bag in simulated time, a dataflash `.BIN`
without GPS, and clock offsets of any size that put the log in 1980-2100. Logs are built here."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from recorders.clock import NS, parse_utc
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record
from replay.cli import main
from replay.run.mission_time import mission_seconds, trial_start_ns
from tests.test_ecosystem_inputs import T0, write_dataflash
from tests.trial_shapes import (
    enu_quaternion,
    imu,
    local_reference,
    navsatfix,
    ros1_typestore,
    write_nogps_bin,
    write_ros1,
)

START = "2024-05-01T10:00:00Z"
START_NS = 1_714_557_600 * NS  # 2024-05-01 10:00:00 UTC


def trial(tmp: Path, entry: str) -> Path:
    """A one-vehicle manifest (vehicle "auv", no trial date) with one log entry."""
    (tmp / "trial.toml").write_text('[trial]\nname = "t"\n[[vehicles]]\nname = "auv"\nrole = "follower"\n'
                                    "[[vehicles.logs]]\n" + entry + "\n")
    return tmp / "trial.toml"


def recorded(tmp: Path, manifest: Path) -> tuple[dict[str, list[tuple[int, bytes]]], dict, int]:
    """Record through the API: messages by topic, the recording's statistics, and the archive's trial start."""
    out = tmp / "a.mcap"
    record(load_manifest(manifest), out, workers=1)
    by: dict[str, list[tuple[int, bytes]]] = {}
    with ArchiveReader(out) as r:
        for m in r.messages():
            by.setdefault(m.topic, []).append((m.log_time_ns, m.message.SerializeToString()))
        stats = r.metadata_json("recording")["files"][0]
        start = trial_start_ns(r)
    return by, stats, start


def cli_error(capsys, manifest: Path) -> str:
    """`auvreplay record` of a manifest that must fail: its one error line."""
    rc = main(["record", str(manifest), "-o", str(manifest.parent / "o.mcap"), "--quiet"])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 1 and "Traceback" not in err and len(lines) == 1, err
    assert not (manifest.parent / "o.mcap").exists()
    return lines[0]


# ---------------------------------------------------------------- a ROS 1 bag in simulated time

def write_sim_bag(path: Path, t0_ns: int = 100 * NS) -> None:
    """A ROS 1 bag from a simulator: three NavSatFix at t0, t0 + 1 s, t0 + 5 s of its clock (header stamp and
    bag time alike, as `rosbag record` with use_sim_time writes them) and an Imu at t0 + 2 s, heading north."""
    ts = ros1_typestore()
    items = [navsatfix(ts, t0_ns + dt * NS, 47.0 + i * 1e-4, 8.5, 400.0) for i, dt in enumerate((0, 1, 5))]
    items.append(imu(ts, t0_ns + 2 * NS, enu_quaternion(ts, 0.0)))
    write_ros1(path, ts, items)


def test_sim_time_bag_with_its_start_gives_utc_and_mission_seconds(tmp_path):
    write_sim_bag(tmp_path / "sim.bag")
    by, stats, start = recorded(tmp_path, trial(tmp_path, f'format = "rosbag"\npath = "sim.bag"\n'
                                                          f'time_base = "sim"\nstart = "{START}"'))
    fixes = by["/auv/gps"]
    assert [t for t, _ in fixes] == [START_NS + 100 * NS, START_NS + 101 * NS, START_NS + 105 * NS]
    assert S.LocationFix.FromString(fixes[2][1]).latitude == pytest.approx(47.0002)
    (ins_t, ins), = by["/auv/ins"]
    assert ins_t == START_NS + 102 * NS and S.InsState.FromString(ins).heading_deg == pytest.approx(0.0, abs=1e-9)
    assert start == START_NS + 100 * NS and stats["start"] == "2024-05-01T10:01:40Z"
    assert list(mission_seconds([t for t, _ in fixes] + [ins_t], start)) == [0.0, 1.0, 5.0, 2.0]
    assert stats["skipped"] == 0


def test_a_toml_datetime_start_is_the_same_instant(tmp_path):
    write_sim_bag(tmp_path / "sim.bag")
    by, _, _ = recorded(tmp_path, trial(tmp_path, 'format = "rosbag"\npath = "sim.bag"\ntime_base = "sim"\n'
                                                  "start = 2024-05-01T12:00:00+02:00"))
    assert by["/auv/gps"][0][0] == START_NS + 100 * NS


def test_an_offset_of_1_6e9_is_accepted(tmp_path):
    write_sim_bag(tmp_path / "sim.bag")
    by, _, _ = recorded(tmp_path, trial(tmp_path, 'format = "rosbag"\npath = "sim.bag"\nclock_offset_s = 1.6e9'))
    assert [t for t, _ in by["/auv/gps"]] == [(1_600_000_000 + s) * NS for s in (100, 101, 105)]


def test_an_offset_giving_2150_is_one_line_naming_the_date(tmp_path, capsys):
    write_sim_bag(tmp_path / "sim.bag")
    offset = 5_680_281_600 - 100  # 2150-01-01 00:00:00 UTC at the bag's first time
    line = cli_error(capsys, trial(tmp_path, f'format = "rosbag"\npath = "sim.bag"\nclock_offset_s = {offset}'))
    assert f"clock_offset_s = {offset}" in line and "out of range" in line and "2149-12-31T23:58:20Z" in line
    # within the static bound, the log's own first time decides: a bag in 2016 moved 4.1e9 s lands in 2146
    write_sim_bag(tmp_path / "utc.bag", T0)
    line = cli_error(capsys, trial(tmp_path, 'format = "rosbag"\npath = "utc.bag"\nclock_offset_s = 4.1e9'))
    assert "utc.bag: clock_offset_s = 4.1e+09 puts the log's first time at 2146-" in line
    assert "outside 1980-01-01 .. 2100-01-01 UTC" in line


def test_a_utc_bag_given_a_sim_start_is_refused_with_its_date(tmp_path, capsys):
    write_sim_bag(tmp_path / "real.bag", T0)  # stamped in 2016 UTC, not from 0
    line = cli_error(capsys, trial(tmp_path, 'format = "rosbag"\npath = "real.bag"\ntime_base = "sim"\n'
                                             'start = "2060-01-01T00:00:00Z"'))
    assert "time_base = 'sim' with start = 2060-01-01T00:00:00Z puts the log's first time at 2106-" in line


def test_an_offset_on_a_vendor_log_is_checked_at_its_first_time(tmp_path, capsys):
    line = "$GPGGA,020000.00,4542.135726,N,12635.845169,E,1,08,0.9,117.87,M,-8.00,M,,*75\n"
    (tmp_path / "gps.log").write_text(line)
    entry = 'sensor = "gps"\nformat = "nmea"\npath = "gps.log"\n'
    text = trial(tmp_path, entry).read_text().replace('name = "t"', 'name = "t"\ndate = "2016-10-12"')
    (tmp_path / "trial.toml").write_text(text + "clock_offset_s = 4.1e9\n")
    assert "gps.log: clock_offset_s = 4.1e+09 puts the log's first time at 2146-" in \
        cli_error(capsys, tmp_path / "trial.toml")
    (tmp_path / "trial.toml").write_text(text + "clock_offset_s = -1.5e9\n")  # 2016-10-12 02:00 - 1.5e9 s
    assert "puts the log's first time at 1969-03-31T23:20:00Z" in cli_error(capsys, tmp_path / "trial.toml")


@pytest.mark.parametrize("keys, words", [
    ('time_base = "sim"', 'time_base = \'sim\' needs start = "YYYY-MM-DDTHH:MM:SSZ"'),
    ('time_base = "gps"', "time_base = 'gps'; use one of utc, sim, boot"),
    (f'start = "{START}"', 'give it with time_base = "sim"'),
    ('time_base = "sim"\nstart = "2024-05-01T10:00:00"', "is not an ISO 8601 UTC instant"),
    ('time_base = "sim"\nstart = 2024-05-01T10:00:00', "is not an ISO 8601 UTC instant"),
    ('time_base = "sim"\nstart = "yesterday"', "start = 'yesterday' is not an ISO 8601 UTC instant"),
    ('time_base = "sim"\nstart = 5', "start = 5 is not an ISO 8601 UTC instant"),
    ('time_base = "sim"\nstart = "2150-01-01T00:00:00Z"', "outside 1980-01-01 .. 2100-01-01 UTC"),
    (f'time_base = "sim"\nstart = "{START}"\nclock_offset_s = 2.0', "give start or clock_offset_s, not both"),
])
def test_time_base_keys_are_checked_with_one_line(tmp_path, keys, words):
    write_sim_bag(tmp_path / "sim.bag")
    with pytest.raises(ManifestError, match="vehicle 'auv', log 1 \\(sim.bag\\)") as err:
        load_manifest(trial(tmp_path, f'format = "rosbag"\npath = "sim.bag"\n{keys}'))
    assert words in str(err.value) and "\n" not in str(err.value)


def test_parse_utc_reads_zones_and_refuses_naive_times():
    assert parse_utc("2024-05-01T10:00:00Z") == START_NS
    assert parse_utc("2024-05-01T06:00:00.5-04:00") == START_NS + NS // 2
    assert parse_utc("2024-05-01T10:00:00") is None and parse_utc("garbage") is None and parse_utc(3) is None


# ---------------------------------------------------------------- a dataflash .BIN without GPS

BOOT = f'format = "mavlink"\npath = "dive.BIN"\ntime_base = "boot"\nstart = "{START}"'


def test_bin_without_gps_is_timed_by_its_start(tmp_path):
    write_nogps_bin(tmp_path / "dive.BIN")
    by, stats, start = recorded(tmp_path, trial(tmp_path, BOOT))
    states = [(t, S.InsState.FromString(b)) for t, b in by["/auv/ins"]]
    assert [t for t, _ in states] == [START_NS + (k + 1) * NS + 1_000_000 for k in range(3)]
    last = states[2][1]
    assert (last.roll_deg, last.pitch_deg, last.heading_deg) == \
        (pytest.approx(1.5), pytest.approx(-2.5), pytest.approx(30.0))
    assert (last.velocity_north_mps, last.velocity_east_mps, last.velocity_down_mps) == \
        (pytest.approx(0.5), pytest.approx(0.25), pytest.approx(0.1))
    assert last.depth_m == pytest.approx(4.0) and last.source_format == "mavlink:XKF1"
    # PN/PE 200 m north, 100 m east of the ORGN origin (45.7, 126.6)
    lat, lon = local_reference(200.0, 100.0, 45.7, 126.6)
    assert last.latitude == pytest.approx(lat, abs=1e-9) and last.longitude == pytest.approx(lon, abs=1e-9)
    (dvl_t, dvl), = by["/auv/dvl"]
    assert dvl_t == START_NS + 3_500_000_000 and S.DvlVelocity.FromString(dvl).altitude_m == 8.5
    assert start == START_NS + 1_001_000_000  # the first INS state (ATT is merged, ORGN unmapped)
    reasons = stats["ignored_reasons"]
    assert reasons["XKF1 of EKF core 1 (core 0's is archived)"] == 3
    assert reasons["ATT: the XKF1 INS state carries the attitude"] == 3
    assert reasons["BARO: the EKF's depth is archived"] == 6
    assert stats["skipped"] == 0


def test_bin_without_ekf_gives_attitude_with_the_depth_sensors_depth(tmp_path):
    write_nogps_bin(tmp_path / "dive.BIN", ekf=False, origin=False)
    by, stats, _ = recorded(tmp_path, trial(tmp_path, BOOT))
    states = [(t, S.InsState.FromString(b)) for t, b in by["/auv/ins"]]
    assert [t for t, _ in states] == [START_NS + (k + 1) * NS for k in range(3)]
    assert math.isnan(states[0][1].depth_m)  # no BARO yet
    assert [s.depth_m for _, s in states[1:]] == [pytest.approx(2.1), pytest.approx(3.1)]  # instance 1, -Alt
    assert all(math.isnan(s.latitude) and s.heading_deg == pytest.approx(30.0) for _, s in states)
    assert stats["ignored_reasons"]["BARO instance 0 (instance 1 measures depth)"] == 3


def test_bin_without_origin_has_ekf_states_without_position_unless_the_manifest_gives_one(tmp_path):
    write_nogps_bin(tmp_path / "dive.BIN", origin=False)
    by, _, _ = recorded(tmp_path, trial(tmp_path, BOOT))
    state = S.InsState.FromString(by["/auv/ins"][0][1])
    assert math.isnan(state.latitude) and state.depth_m == pytest.approx(2.0)
    by, _, _ = recorded(tmp_path, trial(tmp_path, BOOT + "\norigin = [10.0, 20.0]"))
    state = S.InsState.FromString(by["/auv/ins"][0][1])
    assert (state.latitude, state.longitude) == (10.0, 20.0)


def test_bin_without_gps_or_start_names_the_keys(tmp_path, capsys):
    write_nogps_bin(tmp_path / "dive.BIN")
    line = cli_error(capsys, trial(tmp_path, 'format = "mavlink"\npath = "dive.BIN"'))
    assert "dive.BIN: no UTC time: the dataflash log has no GPS week and time" in line
    assert 'time_base = "boot" and start = "YYYY-MM-DDTHH:MM:SSZ"' in line


def test_bin_with_gps_time_is_not_overridden_by_a_start(tmp_path, capsys):
    write_dataflash(tmp_path / "dive.BIN")  # GPS week 1918: booted at T0 - 1 s
    line = cli_error(capsys, trial(tmp_path, BOOT))
    assert "its own GPS time (boot at 2016-10-12T01:59:59Z)" in line and "give it no time_base or start" in line
    by, _, _ = recorded(tmp_path, trial(tmp_path, 'format = "mavlink"\npath = "dive.BIN"\nclock_offset_s = 2.5'))
    assert by["/auv/gps"][0][0] == T0 + 2_500_000_000
