"""MCAP archive writing and reading: round trips, ordering, windows, damage."""

from __future__ import annotations

import hashlib
import math
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from formats.records import FormatError

T0 = 1_476_259_200_000_000_000  # 2016-10-12T08:00:00Z


def one_of_each(t_ns: int) -> list[tuple[str, object]]:
    """One message of every archive schema with every field set to a checked value."""
    ts = S.timestamp(t_ns)
    snap = S.AnfisSnapshot(time=ts, leader="leader1", epoch=7, training_rmse=1.83, inputs=3,
                           mfs_per_input=2, rule_structure="grid", threshold=5.49, trainer="hybrid")
    snap.membership.add(input=0, index=1, a=0.5, b=2.0, c=1.0)
    snap.consequents.extend([0.1 * i for i in range(32)])
    snap.input_min.extend([0.0, 0.1, 9.0])
    snap.input_max.extend([40.0, 200.0, 90.0])
    dvl = S.DvlVelocity(timestamp=ts, frame_id="follower", frame=S.DvlVelocity.BODY_FRD,
                        velocity_x_mps=1.25, velocity_y_mps=-0.03, velocity_z_mps=0.01,
                        error_velocity_mps=0.002, altitude_m=7.5, valid=True,
                        figure_of_merit=float("nan"), sound_speed_mps=1481.0, source_format="pd0")
    dvl.beam_range_m.extend([8.1, 8.2, float("nan"), 8.0])
    return [
        ("/follower/gps", S.location_fix(t_ns, "follower", 45.71234567, 126.61234567, 1.5,
                                         (3.24, 0, 0, 0, 3.24, 0, 0, 0, 9.0), S.COVARIANCE_DIAGONAL_KNOWN)),
        ("/follower/gps/status", S.GnssStatus(timestamp=ts, frame_id="follower", fix_quality=1, satellites=9,
                                              hdop=0.9, source_format="nmea:GGA", heading_deg=float("nan"))),
        ("/follower/ins", S.InsState(timestamp=ts, frame_id="follower", latitude=45.7, longitude=126.6,
                                     depth_m=2.0, roll_deg=0.5, pitch_deg=-1.0, heading_deg=271.5,
                                     velocity_north_mps=0.1, velocity_east_mps=-1.5, velocity_down_mps=0.0,
                                     heading_std_deg=0.5, position_std_north_m=3.0, position_std_east_m=3.0,
                                     status="0x00000001", source_format="phins")),
        ("/follower/dvl", dvl),
        ("/follower/modem/range", S.AcousticRange(timestamp=ts, source="leader1", destination="follower",
                                                  source_address=1, destination_address=3, travel_time_s=0.4,
                                                  range_m=600.0, sound_speed_mps=1500.0, kind="ping")),
        ("/buoy3/usbl", S.UsblObservation(timestamp=ts, node="buoy3", target="follower", travel_time_s=0.3,
                                          range_m=450.0, bearing_deg=45.0, elevation_deg=-3.0, phase_x_rad=1.2,
                                          phase_y_rad=-0.4, relative_east_m=318.0, relative_north_m=318.0,
                                          relative_up_m=-20.0)),
        ("/diagnostics", S.Log(timestamp=ts, level=3, message="bad checksum", name="leader1/gps.log",
                               file="leader1/gps.log", line=12)),
        ("/replay/r1/follower/anfis", S.location_fix(t_ns, "follower", 45.7, 126.6)),
        ("/replay/r1/follower/detections", S.Detection(timestamp=ts, follower="follower", leader="leader1",
                                                       method="anfis", flagged=True, score=12.0, threshold=5.49,
                                                       feature_innovation_m=11.0, feature_mahalanobis2=9.5,
                                                       feature_r_adapted_m2=30.0, label=1)),
        ("/replay/r1/anfis/leader1", snap),
    ]


def test_every_message_type_round_trips(tmp_path):
    path = tmp_path / "all.mcap"
    written = one_of_each(T0)
    with ArchiveWriter(path) as w:
        for i, (topic, msg) in enumerate(written):
            w.write(topic, msg, T0 + i, T0 + i + 5)
    with ArchiveReader(path) as r:
        got = list(r.messages())
        assert not r.problems
    assert [m.topic for m in got] == [t for t, _ in written]
    for (_, msg), item in zip(written, got):
        assert item.schema == msg.DESCRIPTOR.full_name
        # NaN != NaN, so compare the serialized bytes
        assert item.message.SerializeToString() == msg.SerializeToString()
        assert item.publish_time_ns == item.log_time_ns + 5
    dvl = next(m.message for m in got if m.topic == "/follower/dvl")
    assert dvl.beam_range_m[1] == 8.2 and math.isnan(dvl.beam_range_m[2])
    assert next(m.message for m in got if m.topic == "/replay/r1/anfis/leader1").membership[0].b == 2.0


def test_attachments_and_metadata_round_trip(tmp_path):
    path = tmp_path / "att.mcap"
    rng = np.random.default_rng(1)
    blobs = {"leader1/gps.log": b"$GPGGA,...\r\n", "follower/dvl.pd0": rng.bytes(200_000), "empty.log": b""}
    with ArchiveWriter(path) as w:
        for name, data in blobs.items():
            w.add_attachment(name, data)
        w.add_metadata("trial", {"name": "lake", "vehicles": [{"name": "leader1", "role": "leader"}]})
    with ArchiveReader(path, validate_crcs=True) as r:
        got = {a.name: a.data for a in r.attachments()}
        assert {a.name: a.size for a in r.summary().attachments} == {k: len(v) for k, v in blobs.items()}
        assert r.metadata("trial")["name"] == "lake"
        assert r.metadata_json("trial")["vehicles"][0]["role"] == "leader"
        assert r.metadata("missing") is None
    for name, data in blobs.items():
        assert hashlib.sha256(got[name]).hexdigest() == hashlib.sha256(data).hexdigest()


def write_interleaved(path, n=3000):
    """Two topics written one after the other, each in time order, interleaved in time."""
    with ArchiveWriter(path, chunk_size=4096) as w:
        for i in range(n):
            w.write("/a/gps", S.location_fix(T0 + 2 * i * 10**6, "a", 45.0, 126.0), T0 + 2 * i * 10**6)
        for i in range(n):
            t = T0 + (2 * i + 1) * 10**6
            w.write("/b/gps/status", S.GnssStatus(timestamp=S.timestamp(t), satellites=i % 20), t)


def test_messages_come_in_time_order_over_topics_and_windows(tmp_path):
    path = tmp_path / "order.mcap"
    write_interleaved(path)
    with ArchiveReader(path) as r:
        times = [m.log_time_ns for m in r.messages()]
        assert len(times) == 6000 and times == sorted(times)
        window = list(r.messages(["/b/gps/status"], T0 + 10 * 10**6, T0 + 20 * 10**6))
        assert [m.log_time_ns - T0 for m in window] == [k * 10**6 for k in range(11, 20, 2)]
        s = r.summary()
        assert s.topics == {"/a/gps": {"count": 3000, "schema": "foxglove.LocationFix"},
                            "/b/gps/status": {"count": 3000, "schema": "auvreplay.GnssStatus"}}
        assert (s.start_ns, s.end_ns) == (T0, T0 + 5999 * 10**6)


def test_to_dataframe_has_utc_index_and_scalar_columns(tmp_path):
    path = tmp_path / "df.mcap"
    write_interleaved(path, n=50)
    with ArchiveReader(path) as r:
        df = r.to_dataframe("/a/gps")
        st_df = r.to_dataframe("/b/gps/status")
    assert len(df) == 50 and str(df.index.tz) == "UTC"
    assert df.index[1] - df.index[0] == np.timedelta64(2, "ms")
    assert {"latitude", "longitude", "altitude", "frame_id", "position_covariance_0"} <= set(df.columns)
    assert df["latitude"].iloc[3] == 45.0
    assert st_df["satellites"].tolist()[:4] == [0, 1, 2, 3]
    assert st_df["timestamp"].iloc[0] == st_df.index[0]


def test_truncated_file_yields_complete_chunks_and_reports(tmp_path):
    path = tmp_path / "full.mcap"
    write_interleaved(path)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    with ArchiveReader(cut) as r:
        got = list(r.messages())
        assert r.recovered and any("truncated" in p for p in r.problems)
    assert 1000 < len(got) < 6000
    times = [m.log_time_ns for m in got]
    assert times == sorted(times)
    with ArchiveReader(path) as r:
        full = {(m.topic, m.log_time_ns) for m in r.messages()}
    assert {(m.topic, m.log_time_ns) for m in got} <= full


def test_crc_damage_is_reported_not_raised_as_traceback(tmp_path):
    path = tmp_path / "crc.mcap"
    write_interleaved(path, n=500)
    data = bytearray(path.read_bytes())
    data[200] ^= 0xFF  # inside the first chunk's compressed payload
    path.write_bytes(bytes(data))
    with ArchiveReader(path, validate_crcs=True) as r:
        got = list(r.messages())
        assert len(r.damage.chunks) == 1 and r.warning().startswith("skipped 1 chunk")
    with ArchiveReader(path, validate_crcs=False) as r:
        assert len(got) < len(list(r.messages())) or r.damage.chunks  # the damaged chunk's messages are gone


@pytest.mark.parametrize("content, words", [(b"", "empty"), (b"hello world, not mcap", "not an MCAP")])
def test_not_mcap_files_raise_format_error(tmp_path, content, words):
    path = tmp_path / "x.mcap"
    path.write_bytes(content)
    with pytest.raises(FormatError, match=words):
        ArchiveReader(path)


def test_interrupted_write_leaves_no_file(tmp_path):
    path = tmp_path / "out.mcap"
    with pytest.raises(RuntimeError):
        with ArchiveWriter(path) as w:
            w.write("/a/gps", S.location_fix(T0, "a", 1.0, 2.0), T0)
            raise RuntimeError("crash")
    assert not path.exists()
    assert os.listdir(tmp_path) == []


def test_unfinished_writer_is_not_at_the_target_name(tmp_path):
    path = tmp_path / "out.mcap"
    w = ArchiveWriter(path)
    w.write("/a/gps", S.location_fix(T0, "a", 1.0, 2.0), T0)
    assert not path.exists() and w.temp_path.exists()
    w.close()
    assert path.exists() and not w.temp_path.exists()


def test_a_topic_keeps_its_type(tmp_path):
    with pytest.raises(TypeError):
        with ArchiveWriter(tmp_path / "t.mcap") as w:
            w.write("/a/gps", S.location_fix(T0, "a", 1.0, 2.0), T0)
            w.write("/a/gps", S.GnssStatus(), T0)


@settings(max_examples=25, deadline=None)
@given(
    lat=st.floats(-90, 90), lon=st.floats(-180, 180), alt=st.floats(allow_nan=True, allow_infinity=True),
    t=st.integers(0, 2**62), name=st.text(max_size=20),
)
def test_location_fix_round_trip_property(tmp_path_factory, lat, lon, alt, t, name):
    path = tmp_path_factory.mktemp("p") / "p.mcap"
    fix = S.location_fix(t, name, lat, lon, alt)
    with ArchiveWriter(path) as w:
        w.write("/p/gps", fix, t)
    with ArchiveReader(path) as r:
        (m,) = list(r.messages())
    assert m.log_time_ns == t and S.to_ns(m.message.timestamp) == t
    assert m.message.SerializeToString() == fix.SerializeToString()


def _assert_ordered_read_is_the_library_s(path, topics: list[str], lo: int, hi: int) -> None:
    """Our decoded messages, in order, are the mcap reader's: the whole archive, then `topics` in [lo, hi)."""
    with ArchiveReader(path) as r:
        for chosen, window in ((None, (None, None)), (topics, (lo, hi))):
            fast = [(m.topic, m.log_time_ns, m.message.satellites) for m in r.messages(chosen, *window)]
            slow = [(c.topic, m.log_time, S.GnssStatus.FromString(m.data).satellites)
                    for _, c, m in r.raw_messages(chosen, *window)]
            assert fast == slow


@settings(max_examples=15, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 50)), min_size=1, max_size=400),
       st.integers(0, 60), st.integers(0, 60))
def test_fast_ordered_read_equals_the_mcap_library(tmp_path_factory, items, a, b):
    """Our chunk merge gives the mcap reader's order, ties and windows included (small chunks, many overlaps)."""
    path = tmp_path_factory.mktemp("o") / "o.mcap"
    with ArchiveWriter(path, chunk_size=256) as w:
        for k, (topic, t) in enumerate(items):
            w.write(f"/v{topic}/gps/status", S.GnssStatus(satellites=k), T0 + t)
    _assert_ordered_read_is_the_library_s(path, ["/v1/gps/status", "/v3/gps/status"], T0 + min(a, b), T0 + max(a, b))


@settings(max_examples=20, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.integers(-1, 3)), min_size=1, max_size=400),
       st.integers(0, 300), st.integers(0, 300), st.sampled_from([200, 2000]))
def test_fast_ordered_read_of_mostly_ordered_writes(tmp_path_factory, items, a, b, chunk_size):
    """Writes in time order with ties and steps back: chunks that follow, touch or overlap; the mcap reader's order."""
    path = tmp_path_factory.mktemp("m") / "m.mcap"
    t = 0
    with ArchiveWriter(path, chunk_size=chunk_size) as w:
        for k, (topic, step) in enumerate(items):
            t = max(0, t + step)
            w.write(f"/v{topic}/gps/status", S.GnssStatus(satellites=k), T0 + t)
    _assert_ordered_read_is_the_library_s(path, ["/v0/gps/status", "/v2/gps/status"], T0 + min(a, b), T0 + max(a, b))
