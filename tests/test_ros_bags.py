"""ROS bags as users bring them: a ROS 2 bag folder, custom types with their .msg/.idl files, Imu rates, several
topics of one kind, Water Linked JSON in a string topic, and a ROS 2 MCAP bag with a chunk bomb.

Every bag is written here with rosbags' own writers (a Humble-era database without its definitions is one with
the definitions table emptied); the MCAP bomb is written record by record from the MCAP spec.
"""

from __future__ import annotations

import json
import math
import sqlite3
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.rosbag import read_bag
from recorders.attachments import unpack
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record
from tests.hostile import GIB, run_child, zstd_bomb
from tests.test_any_trial import geodetic, review, track_vertices, tracks
from tests.trial_shapes import enu_quaternion, navsatfix, odometry, ros1_typestore, ros_header, write_ros1

NS = 10**9
T0 = 1476237600 * NS  # 2016-10-12 02:00:00 UTC
LAT0, LON0 = 45.7, 126.6
DVL_PING = "std_msgs/Header header\ngeometry_msgs/Vector3 velocity\nfloat64 altitude\nbool valid\n"
DVL_PING_IDL = """module my_auv_msgs {
  module msg {
    struct DvlPing {
      std_msgs::msg::Header header;
      geometry_msgs::msg::Vector3 velocity;
      double altitude;
      boolean valid;
    };
  };
};
"""


def manifest(folder: Path, path: str, extra: str = "", vehicle: str = "auv") -> Path:
    (folder / "trial.toml").write_text(
        f'[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "{vehicle}"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "rosbag"\npath = {json.dumps(path)}\n{extra}\n')
    return folder / "trial.toml"


def recorded(folder: Path, toml: Path, name: str = "a.mcap", **kw: Any) -> tuple[dict[str, list], dict, list[str]]:
    """topic -> [(log time, message bytes)], the log's statistics and the attachment names of a recording."""
    out = folder / name
    record(load_manifest(toml, **kw), out, workers=1)
    by: dict[str, list] = {}
    with ArchiveReader(out) as r:
        for m in r.messages():
            by.setdefault(m.topic, []).append((m.log_time_ns, m.message.SerializeToString()))
        stats = r.metadata_json("recording")["files"][0]
        names = [a.name for a in r.attachments()]
    return by, stats, names


def humble_store() -> Any:
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_HUMBLE)


def navsat(store: Any, t_ns: int, lat: float, lon: float, topic: str = "/gps/fix") -> tuple:
    T = store.types
    return (topic, "sensor_msgs/msg/NavSatFix", t_ns, T["sensor_msgs/msg/NavSatFix"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=t_ns // NS, nanosec=t_ns % NS),
                                        frame_id="gps"),
        status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1), latitude=lat, longitude=lon, altitude=10.0,
        position_covariance=np.eye(3).flatten(), position_covariance_type=2))


def write_ros2(folder: Path, store: Any, items: list[tuple], storage: str = "sqlite3") -> Path:
    """A ROS 2 bag folder of (topic, type, bag time, message) items."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(folder, version=8, storage_plugin=plugin) as w:
        conns: dict[str, Any] = {}
        for topic, msgtype, t, msg in sorted(items, key=lambda x: x[2]):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=store)
            w.write(conns[topic], t, store.serialize_cdr(msg, msgtype))
    return folder


# ---------------------------------------------------------------- 1. a ROS 2 bag folder is the bag

@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_ros2_bag_folder_is_the_bag_and_unpacks_to_a_bag_rosbags_reopens(tmp_path, storage):
    from rosbags.rosbag2 import Reader
    store = humble_store()
    fixes = [navsat(store, T0 + k * NS, LAT0 + k * 1e-5, LON0) for k in range(5)]
    write_ros2(tmp_path / "dive3", store, fixes, storage)
    suffix = ".mcap" if storage == "mcap" else ".db3"
    files = sorted(p.name for p in (tmp_path / "dive3").iterdir())
    assert files == sorted(["metadata.yaml", "dive3" + suffix])
    # the folder (with or without its slash), its metadata.yaml or its storage file: the same whole bag
    results = [recorded(tmp_path, manifest(tmp_path, path), f"{i}.mcap")
               for i, path in enumerate(["dive3/", "dive3", "dive3/metadata.yaml", "dive3/dive3" + suffix])]
    for by, stats, names in results:
        assert names == [f"dive3/{f}" for f in files]
        assert [p["path"] for p in stats["parts"]] == [f"dive3/{f}" for f in files]
        assert by == results[0][0]
        lats = [S.LocationFix.FromString(b).latitude for _, b in by["/auv/gps"]]
        assert lats == pytest.approx([LAT0 + k * 1e-5 for k in range(5)], abs=1e-12)
        assert [t for t, _ in by["/auv/gps"]] == [T0 + k * NS for k in range(5)]
    # unpacked, the folder opens in rosbags with every message, byte for byte
    done = unpack(tmp_path / "0.mcap", tmp_path / "out")
    assert not (done.refused or done.mismatched or done.repeated)
    with Reader(tmp_path / "out" / "dive3") as r, Reader(tmp_path / "dive3") as original:
        assert [(t, bytes(d)) for _, t, d in r.messages()] == [(t, bytes(d)) for _, t, d in original.messages()]
        assert r.message_count == 5


def test_a_folder_that_is_no_bag_and_one_outside_are_refused_in_one_line(tmp_path):
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "x.db3").write_bytes(b"")
    with pytest.raises(ManifestError, match=r"logs/ is a folder without metadata.yaml, not a ROS 2 bag folder"):
        load_manifest(manifest(tmp_path, "logs/"))
    inner = tmp_path / "trial"
    inner.mkdir()
    write_ros2(tmp_path / "dive3", humble_store(), [navsat(humble_store(), T0, LAT0, LON0)])
    with pytest.raises(ManifestError, match=r"outside the manifest's folder .*--allow-outside") as err:
        load_manifest(manifest(inner, "../dive3/"))
    assert "\n" not in str(err.value)
    allowed = load_manifest(manifest(inner, "../dive3/"), allow_outside=True)
    assert allowed.logs()[0].parts == ("../dive3/dive3.db3", "../dive3/metadata.yaml")


# ---------------------------------------------------------------- 2. msg_paths: custom types without definitions

def write_custom_bag(folder: Path) -> list[tuple[float, float, float, float, bool]]:
    """A Humble-era ROS 2 database of my_auv_msgs/DvlPing (no definitions in it) and one NavSatFix; the pings."""
    from rosbags.typesys import get_types_from_msg
    store = humble_store()
    store.register(get_types_from_msg(DVL_PING, "my_auv_msgs/msg/DvlPing"))
    T = store.types
    pings = [(0.5 + k / 10, -0.1 * k, 0.02, 4.0 + k, k != 2) for k in range(4)]
    items = [navsat(store, T0, LAT0, LON0)]
    for k, (vx, vy, vz, alt, valid) in enumerate(pings):
        t = T0 + (k + 1) * NS
        items.append(("/dvl/ping", "my_auv_msgs/msg/DvlPing", t, T["my_auv_msgs/msg/DvlPing"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=t // NS, nanosec=0),
                                            frame_id="dvl"),
            velocity=T["geometry_msgs/msg/Vector3"](x=vx, y=vy, z=vz), altitude=alt, valid=valid)))
    write_ros2(folder, store, items)
    with sqlite3.connect(next(folder.glob("*.db3"))) as con:
        con.execute("DELETE FROM message_definitions")   # as a Humble bag: no definitions
    return pings


@pytest.mark.parametrize("kind", ["msg", "idl", "folder"])
def test_msg_paths_give_custom_types_and_without_them_each_message_is_a_counted_skip(tmp_path, kind):
    pings = write_custom_bag(tmp_path / "bag")
    # without definitions: the NavSatFix is archived, every ping refused with one reason, no KeyError
    by, stats, _ = recorded(tmp_path, manifest(tmp_path, "bag/"), "none.mcap")
    assert "/auv/dvl" not in by and len(by["/auv/gps"]) == 1
    assert stats["skipped"] == 4 and stats["parsed"] == 1   # the NavSatFix (its fix and status)
    with ArchiveReader(tmp_path / "none.mcap") as r:
        lines = [m.message.message for m in r.messages(["/diagnostics"])]
    assert len(lines) == 4 and all("no definition of my_auv_msgs/DvlPing" in x and "msg_paths" in x for x in lines)
    assert not any("KeyError" in x for x in lines)
    # with them
    pkg = tmp_path / "defs" / "my_auv_msgs" / "msg"
    pkg.mkdir(parents=True)
    if kind == "idl":
        (pkg / "DvlPing.idl").write_text(DVL_PING_IDL)
        paths = '["defs/my_auv_msgs/msg/DvlPing.idl"]'
    else:
        (pkg / "DvlPing.msg").write_text(DVL_PING)
        paths = '["defs/my_auv_msgs/msg/DvlPing.msg"]' if kind == "msg" else '["defs"]'
    by, stats, _ = recorded(tmp_path, manifest(tmp_path, "bag/", f"msg_paths = {paths}"))
    assert stats["skipped"] == 0
    got = [S.DvlVelocity.FromString(b) for _, b in by["/auv/dvl"]]
    assert [t for t, _ in by["/auv/dvl"]] == [T0 + (k + 1) * NS for k in range(4)]
    for msg, (vx, vy, vz, alt, valid) in zip(got, pings):
        assert (msg.velocity_x_mps, msg.velocity_y_mps, msg.velocity_z_mps) == (vx, vy, vz)
        assert (msg.altitude_m, msg.valid, msg.frame) == (alt, valid, S.DvlVelocity.INSTRUMENT)


@pytest.mark.parametrize(("value", "why"), [
    ('"defs"', "msg_paths = 'defs' must be a list of paths"),
    ('["defs", 3]', "must be a list of paths"),
    ('["../elsewhere.msg"]', "outside the manifest's folder"),
    ('["nowhere/x/msg/A.msg"]', "msg_paths: nowhere/x/msg/A.msg not found"),
    ('["defs/a\\u001b[31m.msg"]', "control character"),
])
def test_msg_paths_are_checked_like_every_manifest_value(tmp_path, value, why):
    write_custom_bag(tmp_path / "bag")
    (tmp_path / "defs").mkdir()
    with pytest.raises(ManifestError) as err:
        load_manifest(manifest(tmp_path, "bag/", f"msg_paths = {value}"))
    assert why in str(err.value) and "\n" not in str(err.value)


def test_a_definition_that_cannot_be_used_is_one_line(tmp_path):
    write_custom_bag(tmp_path / "bag")
    (tmp_path / "DvlPing.msg").write_text(DVL_PING)            # not in a package's msg folder: no type name
    (tmp_path / "pkg" / "msg").mkdir(parents=True)
    (tmp_path / "pkg" / "msg" / "Bad.msg").write_text("float64[ broken\n")
    for path, why in (("DvlPing.msg", "must lie in its package's msg folder"), ("pkg", "Bad.msg cannot be used")):
        code, err, _ = run_child("record", str(manifest(tmp_path, "bag/", f'msg_paths = ["{path}"]')),
                                 "-o", str(tmp_path / f"{path}.mcap"))
        assert code != 0 and why in err and "Traceback" not in err, err


# ---------------------------------------------------------------- 3. Imu keeps its rates

def test_imu_keeps_angular_velocity_and_linear_acceleration_in_frd(tmp_path):
    ts = ros1_typestore()
    T = ts.types
    V3 = T["geometry_msgs/msg/Vector3"]

    def imu(t_ns: int, frame: str, w: tuple, a: tuple, no_rates: bool = False) -> tuple:
        cov = np.zeros(9)
        return ("/imu", "sensor_msgs/msg/Imu", t_ns, T["sensor_msgs/msg/Imu"](
            header=ros_header(ts, t_ns, frame), orientation=enu_quaternion(ts, 30.0), orientation_covariance=cov,
            angular_velocity=V3(x=w[0], y=w[1], z=w[2]),
            angular_velocity_covariance=np.full(9, -1.0) if no_rates else cov,
            linear_acceleration=V3(x=a[0], y=a[1], z=a[2]), linear_acceleration_covariance=cov))

    write_ros1(tmp_path / "imu.bag", ts, [imu(T0, "imu_link", (0.01, 0.02, 0.3), (0.1, -0.2, 9.81)),
                                         imu(T0 + NS, "imu_frd", (0.01, 0.02, 0.3), (0.1, -0.2, -9.81)),
                                         imu(T0 + 2 * NS, "imu_link", (1.0, 1.0, 1.0), (0.5, 0.0, 9.8), True)])
    by, _, _ = recorded(tmp_path, manifest(tmp_path, "imu.bag"))
    flu, frd, rateless = (S.InsState.FromString(b) for _, b in by["/auv/ins"])
    # FLU (REP-103) -> FRD: y and z negated; a frame named _frd as it is
    assert (flu.angular_velocity_x_radps, flu.angular_velocity_y_radps, flu.angular_velocity_z_radps) == \
        (0.01, -0.02, -0.3)
    assert (flu.linear_acceleration_x_mps2, flu.linear_acceleration_y_mps2, flu.linear_acceleration_z_mps2) == \
        (0.1, 0.2, -9.81)
    assert (frd.angular_velocity_z_radps, frd.linear_acceleration_y_mps2, frd.linear_acceleration_z_mps2) == \
        (0.3, -0.2, -9.81)
    assert flu.heading_deg == pytest.approx(30.0)
    # covariance[0] = -1 (REP-145): no angular velocity, which stays absent; the acceleration is kept
    assert not rateless.HasField("angular_velocity_x_radps") and rateless.linear_acceleration_x_mps2 == 0.5
    # an InsState written before these fields reads as before, the rates absent
    old = S.InsState(heading_deg=12.0).SerializeToString()
    assert not S.InsState.FromString(old).HasField("angular_velocity_z_radps")


# ---------------------------------------------------------------- 4. each topic its own source

def _odometry(ts: Any, topic: str, t_ns: int, north: float, east: float) -> tuple:
    _, msgtype, t, msg = odometry(ts, t_ns, east, north, 0.0, enu_quaternion(ts, 63.0), 1.1)
    return topic, msgtype, t, msg


def test_two_odometry_topics_are_two_sources_drawn_as_two_tracks(tmp_path, capsys, monkeypatch):
    from mcap.reader import make_reader
    ts = ros1_typestore()
    items = [navsatfix(ts, T0 + k * NS, *geodetic(0.5 * k, 1.0 * k)) for k in range(21)]
    for k in range(100):   # two estimators of one vehicle, interleaved clocks 10 ms apart
        t = T0 + k * 200_000_000 + 50_000_000
        items.append(_odometry(ts, "/odometry/filtered", t, 0.1 * k, 0.2 * k))
        items.append(_odometry(ts, "/odometry/gps", t - 10_000_000, 0.1 * k + 3.0, 0.2 * k))
    write_ros1(tmp_path / "ugv.bag", ts, items)
    toml = manifest(tmp_path, "ugv.bag", f"origin = [{LAT0}, {LON0}]", vehicle="ugv")
    by, _, _ = recorded(tmp_path, toml, "direct.mcap")
    # first by name keeps /ugv/ins; the other is a source of its own, every message of each on its own topic
    assert len(by["/ugv/ins"]) == len(by["/ugv/ins/odometry_gps"]) == 100
    assert [t for t, _ in by["/ugv/ins/odometry_gps"]] == [T0 + k * 200_000_000 + 40_000_000 for k in range(100)]
    first = S.InsState.FromString(by["/ugv/ins/odometry_gps"][0][1])
    assert first.latitude > S.InsState.FromString(by["/ugv/ins"][0][1]).latitude   # 3 m further north
    # the mcap library reads every message in log-time order per channel, no topic with two clocks
    with open(tmp_path / "direct.mcap", "rb") as f:
        last: dict[str, int] = {}
        for _, channel, message in make_reader(f, validate_crcs=True).iter_messages(log_time_order=False):
            assert message.log_time >= last.get(channel.topic, 0), channel.topic
            last[channel.topic] = message.log_time
    r = review(tmp_path, toml, capsys, monkeypatch)
    for rrd in (r.results_rrd, r.trial_rrd):
        drawn = tracks(rrd)
        assert set(drawn) == {("ugv", "gps"), ("ugv", "ins"), ("ugv", "ins_odometry_gps")}
        assert len(track_vertices(rrd, drawn[("ugv", "ins_odometry_gps")])) == 20


# ---------------------------------------------------------------- 5. Water Linked JSON in a string topic

def wl_velocity(tov_us: int, vx: float, altitude: float, valid: bool) -> str:
    return json.dumps({
        "time": 106.3, "vx": vx, "vy": -0.01, "vz": 0.005, "fom": 0.002,
        "covariance": [[1e-5, 0, 0], [0, 1e-5, 0], [0, 0, 1e-5]], "altitude": altitude,
        "transducers": [{"id": i, "velocity": 0.1, "distance": altitude if altitude > 0 else -1, "rssi": -30,
                         "nsd": -100, "beam_valid": valid} for i in range(4)],
        "velocity_valid": valid, "status": 0, "format": "json_v3.1", "type": "velocity",
        "time_of_validity": tov_us, "time_of_transmission": tov_us + 150_000})


def test_water_linked_json_in_a_string_topic_is_the_dvl_on_the_bags_clock(tmp_path):
    store = humble_store()
    String = store.types["std_msgs/msg/String"]
    dvl_clock = T0 // 1000 + 37_000_000   # the DVL's clock, 37 s ahead of the bag's (unsynchronised)
    items = [
        ("/dvl/json_data", "std_msgs/msg/String", T0 + NS, String(data=wl_velocity(dvl_clock + 1_000_000, 0.4, 3.2,
                                                                                      True))),
        ("/dvl/json_data", "std_msgs/msg/String", T0 + 2 * NS, String(data=wl_velocity(dvl_clock + 2_000_000, 0.0,
                                                                                          -1.0, True))),
        ("/dvl/json_data", "std_msgs/msg/String", T0 + 3 * NS, String(data=json.dumps(
            {"ts": 49056.5, "x": 12.9, "y": 0.3, "z": 1.2, "std": 0.4, "roll": 0.1, "pitch": 0.2, "yaw": 3.1,
             "type": "position_local", "status": 0, "format": "json_v3.1"}))),
    ]
    write_ros2(tmp_path / "bag", store, items, "mcap")
    by, stats, _ = recorded(tmp_path, manifest(tmp_path, "bag/"))
    assert [t for t, _ in by["/auv/dvl"]] == [T0 + NS, T0 + 2 * NS]   # the bag's receive stamps
    good, no_bottom = (S.DvlVelocity.FromString(b) for _, b in by["/auv/dvl"])
    assert S.to_ns(good.device_time) == (dvl_clock + 1_000_000) * 1000   # the DVL's own clock, kept
    assert (good.velocity_x_mps, good.altitude_m, good.valid, good.figure_of_merit) == (0.4, 3.2, True, 0.002)
    assert good.source_format == "waterlinked:json" and good.frame == S.DvlVelocity.BODY_FRD
    # altitude -1: the DVL's "no altitude": the ping kept, not valid (whatever its velocity flag), altitude NaN
    assert math.isnan(no_bottom.altitude_m) and not no_bottom.valid
    assert S.to_ns(no_bottom.device_time) == (dvl_clock + 2_000_000) * 1000
    # every message archived as itself; the dead-reckoning report gives none of ours, said (not "no vendor format")
    assert stats["parsed"] == 3 and stats["skipped"] == 0 and stats["ignored"] == 1
    assert len(by["/auv/ros/dvl/json_data"]) == 3
    assert not any("no vendor format" in r for r in stats["ignored_reasons"])


# ---------------------------------------------------------------- 6. a ROS 2 MCAP bag with a chunk bomb

def _record(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def _s(text: str) -> bytes:
    return struct.pack("<I", len(text.encode())) + text.encode()


def _chunk(messages: list[tuple[int, bytes]], compression: str = "", payload: bytes | None = None,
           declared: int | None = None) -> bytes:
    records = b"".join(_record(0x05, struct.pack("<HIQQ", 1, i, t, t) + data) for i, (t, data) in
                       enumerate(messages))
    body = records if payload is None else payload
    start, end = (messages[0][0], messages[-1][0]) if messages else (0, 0)
    size = len(records) if declared is None else declared
    crc = zlib.crc32(records) if payload is None else 0
    return _record(0x06, struct.pack("<QQQI", start, end, size, crc) + _s(compression)
                   + struct.pack("<Q", len(body)) + body)


def ros2_mcap(chunks: list[bytes]) -> bytes:
    """A ROS 2 MCAP storage file of std_msgs/String on /dvl/json_data, without summary (as a cut recording)."""
    schema = _record(0x03, struct.pack("<H", 1) + _s("std_msgs/msg/String") + _s("ros2msg")
                     + struct.pack("<I", 11) + b"string data")
    channel = _record(0x04, struct.pack("<HH", 1, 1) + _s("/dvl/json_data") + _s("cdr") + struct.pack("<I", 0))
    head = b"\x89MCAP0\r\n" + _record(0x01, _s("ros2") + _s("test"))
    tail = _record(0x0F, struct.pack("<I", 0)) + _record(0x02, struct.pack("<QQI", 0, 0, 0)) + b"\x89MCAP0\r\n"
    return head + schema + channel + b"".join(chunks) + tail


def _pings(store: Any, start: int, n: int) -> list[tuple[int, bytes]]:
    String = store.types["std_msgs/msg/String"]
    return [(T0 + (start + k) * NS, store.serialize_cdr(String(data=wl_velocity(T0 // 1000 + (start + k) * 10**6,
                                                                                0.3, 2.0, True)),
                                                          "std_msgs/msg/String")) for k in range(n)]


@pytest.mark.parametrize("declared", ["3 GiB", "honest"])
def test_a_ros2_mcap_chunk_bomb_is_refused_in_bounded_memory(tmp_path, declared):
    store = humble_store()
    bomb = zstd_bomb(3 * GIB)
    size = 3 * GIB if declared == "3 GiB" else 4096
    data = ros2_mcap([_chunk(_pings(store, 0, 5)), _chunk(_pings(store, 5, 5), "zstd", bomb, size),
                      _chunk(_pings(store, 10, 5))])
    assert len(data) < 200_000
    (tmp_path / "dive.mcap").write_bytes(data)
    messages = list(read_bag(tmp_path / "dive.mcap"))
    assert [m.bag_time_ns for m in messages if not m.problem] == [T0 + k * NS for k in (*range(5), *range(10, 15))]
    (bad,) = [m for m in messages if m.problem]
    assert ("over the 64 MiB limit" if declared == "3 GiB" else "does not decompress within") in bad.problem
    code, err, peak_kb = run_child("record", str(manifest(tmp_path, "dive.mcap")), "-o", str(tmp_path / "a.mcap"))
    print(f"\nrecord, ROS 2 MCAP with a 3 GiB zstd chunk ({declared}): peak RSS {peak_kb // 1024} MB")
    assert code == 0 and "Traceback" not in err, err
    assert peak_kb < 400 * 1024
    with ArchiveReader(tmp_path / "a.mcap") as r:
        stats = r.metadata_json("recording")["files"][0]
        assert sum(1 for _ in r.messages(["/auv/dvl"])) == 10
        (line,) = [m.message.message for m in r.messages(["/diagnostics"])]
    assert stats["skipped"] == 1 and "MCAP storage, byte" in line


def test_our_mcap_storage_reads_a_sound_bag_as_rosbags_does(tmp_path):
    from rosbags.rosbag2 import Reader
    store = humble_store()
    items = [navsat(store, T0 + k * NS, LAT0, LON0 + k * 1e-5) for k in range(30)]
    write_ros2(tmp_path / "bag", store, items, "mcap")
    ours = [(m.topic, m.msgtype, m.bag_time_ns, m.message.longitude) for m in read_bag(tmp_path / "bag/metadata.yaml")]
    with Reader(tmp_path / "bag") as r:
        theirs = [(c.topic, c.msgtype.replace("/msg/", "/"), t,
                   store.deserialize_cdr(d, c.msgtype).longitude) for c, t, d in r.messages()]
    assert ours == theirs and len(ours) == 30
