"""Every position source of a trial is a track: MOOS alogs (NAV_*, an INS's INS_NAV, NODE_REPORTs), ArduSub
tlogs (GLOBAL_POSITION_INT, LOCAL_POSITION_NED on its origin) and ROS bags (Odometry on a manifest origin).

Each log is built here, recorded, exported with `auvreplay export --format geojson`, and its tracks compared
with what was written.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.mcap_reader import ArchiveReader
from recorders.alog import convert_alog, moos_yaw_heading
from recorders.base import Ignored, LogContext, Output
from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from tests.trial_shapes import (
    enu_quaternion,
    imu,
    local_reference,
    mavlink,
    odometry,
    ros1_typestore,
    tlog_bytes,
    write_ros1,
)

T0 = 1476237600  # 2016-10-12 02:00:00 UTC, s
R = 6_378_137.0
LAT0, LON0 = 45.7, 126.6
KML = "{http://www.opengis.net/kml/2.2}"


def _trial(tmp: Path, fmt: str, path: str, extra: str = "") -> Path:
    """Record a one-vehicle ("auv") trial of one log; the archive's path."""
    (tmp / "trial.toml").write_text(
        '[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "auv"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "{fmt}"\npath = "{path}"\n{extra}\n')
    out = tmp / "trial.mcap"
    record(load_manifest(tmp / "trial.toml"), out, workers=1)
    return out


def _geojson(archive: Path, tmp: Path, *topics: str) -> dict[str, dict]:
    """`export --format geojson` of the archive: its features by name."""
    out = tmp / "tracks.geojson"
    args = [a for t in topics for a in ("--topic", t)]
    assert main(["export", str(archive), "--format", "geojson", "-o", str(out), "--force", *args]) == 0
    return {f["properties"]["name"]: f for f in json.loads(out.read_text())["features"]}


def _points(feature: dict) -> list[tuple[float, float]]:
    """(lat, lon) of a feature's points."""
    g = feature["geometry"]
    coords = g["coordinates"] if g["type"] == "LineString" else [g["coordinates"]]
    return [(lat, lon) for lon, lat in coords]


def _near(got: list[tuple[float, float]], want: list[tuple[float, float]]) -> bool:
    return len(got) == len(want) and all(abs(a - c) <= 1e-7 and abs(b - d) <= 1e-7
                                         for (a, b), (c, d) in zip(got, want))


def _local(north: float, east: float, lat0: float = LAT0, lon0: float = LON0) -> tuple[float, float]:
    """A local tangent-plane point on its origin, on the earth radii at the origin (as every recorder places one)."""
    return local_reference(north, east, lat0, lon0)


def _topic_raw(archive: Path, topic: str) -> list:
    """Every message of a topic, as the reader hands it (JSON channels included)."""
    with ArchiveReader(archive) as r:
        return list(r.messages([topic]))


def _topic(archive: Path, topic: str) -> list:
    with ArchiveReader(archive) as r:
        return [m.message for m in r.messages([topic])]


def _stats(archive: Path) -> dict:
    with ArchiveReader(archive) as r:
        return r.metadata_json("recording")["files"][0]  # type: ignore[index]


# ---------------------------------------------------------------- MOOS alog

NAV = [(45.7001234, 126.6005678, 30.0), (45.7002345, 126.6006789, 302.5)]     # lat, lon, heading (deg)
SBG = [(45.7003456, 126.6007890), (45.7004567, 126.6008901)]
ALPHA = [(45.7101234, 126.6101234), (45.7102345, 126.6102345)]


def _alog() -> str:
    lines = [f"%% LOGSTART {T0}", f"0.000 GPS_LAT iGPS {LAT0}", f"0.000 GPS_LONG iGPS {LON0}"]
    for k, (lat, lon, heading) in enumerate(NAV):
        t = 1.0 + k
        yaw = -math.radians(heading)  # MOOS: yaw = -heading, radians
        lines += [f"{t:.3f} NAV_LAT pNav {lat}", f"{t:.3f} NAV_LONG pNav {lon}", f"{t:.3f} NAV_YAW pNav {yaw!r}",
                  f"{t:.3f} NAV_SPEED pNav 2.0",
                  f"{t:.3f} INS_NAV iInsSBG TIME={T0 + t:.3f},LAT={SBG[k][0]},LON={SBG[k][1]},ALT=1.5",
                  f"{t:.3f} INS_EULER iInsSBG TIME={T0 + t:.3f},ROLL=0.01,PITCH=-0.02,YAW={math.radians(heading)!r}"]
    for k, (lat, lon) in enumerate(ALPHA):
        lines.append(f"{3.0 + k:.3f} NODE_REPORT pShare NAME=alpha,X=10,Y=20,LAT={lat},LON={lon},SPD=1.5,HDG=45,"
                     f"DEP=3.5,TIME={T0 + 2.5 + k:.2f}")
    lines += [f"5.000 NODE_REPORT_LOCAL pNodeReporter NAME=auv_moos,X=30,Y=-40,SPD=2,HDG=90,TIME={T0 + 5}",
              "5.000 NODE_REPORT pShare NAME=bad/name,X=1,Y=2",
              "5.000 NODE_REPORT pShare NAME=bravo,SPD=1",
              "5.000 NODE_REPORT pShare NAME=replay,LAT=45.7,LON=126.6",
              "5.500 INS_NAV iInsSBG no key value here"]
    return "\n".join(lines) + "\n"


def test_alog_nav_ins_and_node_reports_are_tracks(tmp_path):
    (tmp_path / "auv.alog").write_text(_alog())
    archive = _trial(tmp_path, "alog", "auv.alog", f"origin = [{LAT0}, {LON0}]")
    nav = _topic(archive, "/auv/ins")
    assert [round(s.heading_deg, 9) for s in nav] == [30.0, 302.5]  # from NAV_YAW alone
    assert nav[0].velocity_north_mps == pytest.approx(2 * math.cos(math.radians(30)))
    sbg = _topic(archive, "/auv/ins/sbg")
    assert [s.heading_deg for s in sbg] == pytest.approx([30.0, 302.5]) and sbg[0].altitude_m == 1.5
    assert sbg[0].roll_deg == pytest.approx(math.degrees(0.01)) and sbg[0].pitch_deg == pytest.approx(-1.1459156)
    alpha = _topic(archive, "/alpha/node_report")
    assert [(s.frame_id, s.depth_m, s.heading_deg) for s in alpha] == [("alpha", 3.5, 45.0)] * 2
    assert [s.timestamp.ToNanoseconds() for s in alpha] == [(T0 + 2.5) * 10**9, (T0 + 3.5) * 10**9]

    tracks = _geojson(archive, tmp_path)
    assert set(tracks) == {"auv gps", "auv ins", "auv ins/sbg", "alpha node_report", "auv node_report"}
    assert _near(_points(tracks["auv ins"]), [(lat, lon) for lat, lon, _ in NAV])
    assert _near(_points(tracks["auv ins/sbg"]), SBG)
    assert _near(_points(tracks["alpha node_report"]), ALPHA)
    # the log's own report, named by the manifest not by its MOOS community; X/Y on the origin
    assert _near(_points(tracks["auv node_report"]), [_local(-40, 30)])
    assert _near(_points(tracks["auv gps"]), [(LAT0, LON0)])
    props = tracks["auv ins/sbg"]["properties"]
    assert (props["vehicle"], props["source"], props["topic"]) == ("auv", "ins/sbg", "/auv/ins/sbg")

    kml = tmp_path / "tracks.kml"
    assert main(["export", str(archive), "--format", "kml", "-o", str(kml)]) == 0
    names = [p.findtext(f"{KML}name") for p in ET.parse(kml).getroot().iter(f"{KML}Placemark")]
    assert sorted(names) == sorted(tracks)

    one = _geojson(archive, tmp_path, "/auv/ins")
    assert list(one) == ["auv ins"] and len(_points(one["auv ins"])) == 2

    stats = _stats(archive)
    lines = _alog().count("\n") - 1
    # every posting archived as a message of its own (/auv/moos/<VARIABLE>); those that give none of our
    # messages besides are said in the ignored reasons
    assert stats["parsed"] == lines and stats["skipped"] == 0
    # bad/name, replay (a namespace of the archive), bravo without a position, INS_NAV that is no key=value:
    # archived as postings, and said
    assert sorted(k.split(":")[0] for k in stats["ignored_reasons"]) == ["INS_NAV"] + ["NODE_REPORT"] * 3


def test_a_topic_that_is_no_position_says_so(tmp_path, capsys):
    (tmp_path / "auv.alog").write_text(_alog())
    archive = _trial(tmp_path, "alog", "auv.alog", f"origin = [{LAT0}, {LON0}]")
    out = str(tmp_path / "x.geojson")
    assert main(["export", str(archive), "--format", "geojson", "-o", out, "--topic", "/auv/gps/status"]) == 1
    err = capsys.readouterr().err
    assert "/auv/gps/status is not a position track" in err and "/alpha/node_report" in err


@settings(max_examples=60, deadline=None)
@given(st.floats(0, 360, exclude_max=True))
def test_moos_yaw_back_to_heading(heading):
    got = moos_yaw_heading(-math.radians(heading))  # what pNav / uSimMarine post for this heading
    assert 0 <= got < 360 and min(abs(got - heading), 360 - abs(got - heading)) < 1e-9


KEYS = st.sampled_from(["NAME", "LAT", "LON", "X", "Y", "HDG", "SPD", "DEP", "TIME", "ROLL", "YAW", "ALT", "", "="])
VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.text(max_size=8))


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["INS_NAV", "INS_EULER", "INS_EEULER", "NODE_REPORT",
                                           "NODE_REPORT_LOCAL"]),
                          st.lists(st.tuples(KEYS, VALUES), max_size=6)), min_size=1, max_size=6))
def test_any_key_value_posting_is_counted_once(postings):
    lines = [f"%% LOGSTART {T0}"]
    for k, (var, pairs) in enumerate(postings):
        text = ",".join(f"{key}={value}" for key, value in pairs).replace("\n", " ").replace("\r", " ") or "x"
        lines.append(f"{k * 0.5:.3f} {var} proc {text}")
    ctx = LogContext("auv", options={"origin": [LAT0, LON0]})
    items = list(convert_alog(("\n".join(lines) + "\n").encode(), ctx))
    # each posting line is archived as itself, and gives its mapped Output or an Ignored reason
    assert len({item.where.offset for item in items if item.where is not None}) == len(postings)
    assert [item.topic for item in items if isinstance(item, Output) and "/moos/" in item.topic] == \
        [f"/auv/moos/{var}" for var, _ in postings]
    for item in items:
        if isinstance(item, Output) and "/moos/" not in item.topic:  # out-of-range values: the recorder's checks
            assert item.topic in ("/auv/ins/sbg", f"/{item.message.frame_id}/node_report")
        elif not isinstance(item, Output):
            assert isinstance(item, Ignored) and item.reason


# ---------------------------------------------------------------- MAVLink tlog

GPI = [(457022621, 1265974195), (457023732, 1265975306)]  # GLOBAL_POSITION_INT lat, lon (1e-7 deg)
ORIGIN = (457000000, 1266000000)
LOCAL = [(12.5, -7.25, 3.0), (15.0, -9.5, 4.25)]  # LOCAL_POSITION_NED x north, y east, z down


def _tlog(path: Path, origin: bool = True) -> None:
    m = mavlink()
    us = T0 * 10**6
    packets = [(0, m.gps_raw_int_encode(us, 3, 457022000, 1265974000, 109870, 90, 200, 462, 9041, 8)),
               (1, m.attitude_encode(1000, 0.0, 0.0, math.radians(45.0), 0, 0, 0))]
    if origin:
        packets.append((1, m.gps_global_origin_encode(*ORIGIN, 0)))
    for k, (lat, lon) in enumerate(GPI):
        packets.append((2 + k, m.global_position_int_encode(2000 + k, lat, lon, 100000, -5500, 100, -50, 10, 4500)))
    for k, (x, y, z) in enumerate(LOCAL):
        packets.append((2 + k, m.local_position_ned_encode(2000 + k, x, y, z, 1.0, -0.5, 0.1)))
    path.write_bytes(tlog_bytes(m, [(us + s * 1_000_000, p) for s, p in packets]))


def test_tlog_autopilot_and_local_positions_are_tracks(tmp_path):
    _tlog(tmp_path / "sub.tlog")
    archive = _trial(tmp_path, "mavlink", "sub.tlog")
    tracks = _geojson(archive, tmp_path)
    assert set(tracks) == {"auv gps", "auv ins", "auv ins/local"}
    assert _near(_points(tracks["auv ins"]), [(lat * 1e-7, lon * 1e-7) for lat, lon in GPI])
    assert _near(_points(tracks["auv ins/local"]),
                 [_local(x, y, ORIGIN[0] * 1e-7, ORIGIN[1] * 1e-7) for x, y, _ in LOCAL])
    local = _topic(archive, "/auv/ins/local")
    assert [s.depth_m for s in local] == [3.0, 4.25] and local[0].velocity_east_mps == -0.5
    assert len(_topic_raw(archive, "/auv/mavlink/GPS_GLOBAL_ORIGIN")) == 1     # kept as a message of its own


def test_tlog_local_positions_take_the_manifest_origin_else_are_ignored(tmp_path):
    _tlog(tmp_path / "sub.tlog", origin=False)
    archive = _trial(tmp_path, "mavlink", "sub.tlog", f"origin = [{LAT0}, {LON0}]")
    assert _near(_points(_geojson(archive, tmp_path)["auv ins/local"]), [_local(x, y) for x, y, _ in LOCAL])
    bare = tmp_path / "bare"
    bare.mkdir()
    _tlog(bare / "sub.tlog", origin=False)
    archive = _trial(bare, "mavlink", "sub.tlog")
    assert set(_geojson(archive, bare)) == {"auv gps", "auv ins"}
    reasons = _stats(archive)["ignored_reasons"]
    assert reasons["LOCAL_POSITION_NED without an origin (no GPS_GLOBAL_ORIGIN in the log, no manifest origin)"] == 2


# ---------------------------------------------------------------- ROS bag

ODOM = [(100.0, 200.0, -5.0), (110.5, 190.25, -6.0), (121.0, 180.5, -7.0)]  # ENU x east, y north, z up


def _bag(path: Path) -> None:
    """Odometry heading north at 1 m/s forward on ODOM's points, one a second, each with an IMU half a second on
    (attitude only, no point of the track)."""
    ts = ros1_typestore()
    north = enu_quaternion(ts, 0.0)
    items = []
    for k, (x, y, z) in enumerate(ODOM):
        t = (T0 + k) * 10**9
        items += [odometry(ts, t, x, y, z, north, 1.0), imu(ts, t + 500_000_000, north)]
    write_ros1(path, ts, items)


def test_bag_odometry_on_an_origin_is_a_track(tmp_path, capsys):
    _bag(tmp_path / "ugv.bag")
    archive = _trial(tmp_path, "rosbag", "ugv.bag", f"origin = [{LAT0}, {LON0}]")
    # the Imu is a source of its own below the Odometry's /auv/ins (attitude only: no track)
    assert len(_topic(archive, "/auv/ins")) == len(_topic(archive, "/auv/ins/imu")) == 3
    tracks = _geojson(archive, tmp_path)
    assert list(tracks) == ["auv ins"]
    assert _near(_points(tracks["auv ins"]), [_local(y, x) for x, y, _ in ODOM])
    assert tracks["auv ins"]["properties"]["mission_s"] == [0.0, 1.0, 2.0]
    # without an origin the same bag has no position: no track, and asking for one says why
    bare = tmp_path / "bare"
    bare.mkdir()
    _bag(bare / "ugv.bag")
    archive = _trial(bare, "rosbag", "ugv.bag")
    assert _geojson(archive, bare) == {}
    capsys.readouterr()
    out = str(bare / "x.geojson")
    assert main(["export", str(archive), "--format", "geojson", "-o", out, "--topic", "/auv/ins"]) == 1
    assert "/auv/ins holds no position (none of its 3 messages" in capsys.readouterr().err
