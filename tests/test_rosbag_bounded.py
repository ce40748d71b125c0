"""Bags read in bounded memory and time: ROS 1 chunks checked before they are inflated, each inflated once;
every value of a ROS 2 database row checked.

Every bag is built here (tests.hostile.ros1_bag writes ROS 1 bags field by field; ROS 2 databases come
from rosbags' writer, then rows are spoiled with sqlite3). Peak RSS is the child's own (VmHWM).
"""

from __future__ import annotations

import bz2
import sqlite3
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import formats.rosbag as rb
from formats.mcap_reader import ArchiveReader
from formats.nmea.framing import nmea_checksum
from formats.rosbag import MAX_CHUNK_BYTES, read_bag
from tests.hostile import GIB, ros1_bag, ros_string, run_child

T0 = 1_476_259_200 * 10**9   # 2016-10-12T08:00:00Z
LIMIT_KB = 400 * 1024


def gga(i: int) -> bytes:
    body = f"GPGGA,08{i // 60:02d}{i % 60:02d}.00,4542.{i:04d},N,12636.0000,E,1,08,0.9,10.0,M,0.0,M,,"
    return f"${body}*{nmea_checksum(body):02X}".encode()


def _fixes(start: int, n: int) -> list[tuple[int, bytes]]:
    return [(T0 + (start + i) * 10**9, ros_string(gga(start + i))) for i in range(n)]


def _manifest(folder: Path, bag: str) -> Path:
    path = folder / "trial.toml"
    path.write_text(f'[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\nrole = "leader"\n'
                    f'[[vehicles.logs]]\nformat = "rosbag"\npath = "{bag}"\n'
                    f'[vehicles.logs.topics]\n"/nmea" = "gps:nmea"\n')
    return path


def _bomb(size: int) -> bytes:
    """bz2 streams in a row inflating to `size` zero bytes (79 bytes per 64 MiB)."""
    one = bz2.compress(bytes(64 << 20), 9)
    return one * (size // (64 << 20))


@pytest.mark.parametrize("declared", ["3 GiB", "honest"])
def test_a_bz2_chunk_that_inflates_to_3_gib_is_refused_in_bounded_memory(tmp_path, declared):
    bomb = _bomb(3 * GIB)
    sizes = {1: 3 * GIB} if declared == "3 GiB" else {}   # else the header gives the real records' size
    bag = ros1_bag([_fixes(0, 20), _fixes(20, 20), _fixes(40, 20)], chunk_data={1: bomb}, declared=sizes)
    (tmp_path / "a.bag").write_bytes(bag)
    assert len(bag) < 12_000
    # at the format level: the bomb chunk's 20 messages are problems, the others decoded, in time order
    messages = list(read_bag(tmp_path / "a.bag"))
    assert [m.bag_time_ns for m in messages] == [T0 + i * 10**9 for i in range(60)]
    bad = [m for m in messages if m.problem]
    assert len(bad) == 20 and all(m.topic == "/nmea" and m.message is None for m in bad)
    expected = "over the 64 MiB limit" if declared == "3 GiB" else "inflates past"
    assert all(expected in m.problem for m in bad)
    # through `record`, in a child: counted skips, 40 fixes archived, bounded memory
    code, err, peak_kb = run_child("record", str(_manifest(tmp_path, "a.bag")), "-o", str(tmp_path / "a.mcap"))
    print(f"\nrecord, 3 GiB bz2 chunk ({declared}): peak RSS {peak_kb // 1024} MB")
    assert code == 0, err
    assert "Traceback" not in err and peak_kb < LIMIT_KB
    with ArchiveReader(tmp_path / "a.mcap") as r:
        files = r.metadata_json("recording")["files"]
        assert sum(1 for _ in r.messages(["/a/gps"])) == 40
    assert files[0]["skipped"] == 20


def test_chunks_whose_times_alternate_are_each_inflated_once(tmp_path, monkeypatch):
    n = 1500
    pad = b"," + bytes(range(32, 127)) * 30   # ~2.8 KB a message: chunks of ~4 MiB
    first = [(T0 + 2 * i * 10**6, ros_string(b"a%06d" % i + pad)) for i in range(n)]
    second = [(T0 + (2 * i + 1) * 10**6, ros_string(b"b%06d" % i + pad)) for i in range(n)]
    (tmp_path / "a.bag").write_bytes(ros1_bag([first, second]))
    calls: list[int] = []
    real = rb._inflate

    def counted(compression: str, body: bytes, size: int) -> bytes:
        calls.append(size)
        return real(compression, body, size)

    monkeypatch.setattr(rb, "_inflate", counted)
    messages = list(read_bag(tmp_path / "a.bag"))
    assert len(calls) == 2 and all(size > 4 << 20 for size in calls)
    assert [m.bag_time_ns for m in messages] == sorted(t for t, _ in first + second)   # merged in time
    assert [m.message.data[:7] for m in messages[:4]] == ["a000000", "b000000", "a000001", "b000001"]
    assert not any(m.problem for m in messages)


def test_chunks_that_do_not_fit_together_are_given_one_after_the_other(tmp_path, monkeypatch):
    # with a merge budget of one chunk, overlapping chunks are still each inflated once: every message comes
    monkeypatch.setattr(rb, "MERGE_BYTES", rb.MAX_CHUNK_BYTES)
    first = [(T0 + 2 * i * 10**6, ros_string(b"a%d" % i)) for i in range(100)]
    second = [(T0 + (2 * i + 1) * 10**6, ros_string(b"b%d" % i)) for i in range(100)]
    (tmp_path / "a.bag").write_bytes(ros1_bag([first, second]))
    messages = list(read_bag(tmp_path / "a.bag"))
    assert sorted(m.bag_time_ns for m in messages) == sorted(t for t, _ in first + second)
    assert len(messages) == 200 and not any(m.problem for m in messages)


@pytest.mark.parametrize("compression", ["bz2", "lz4", "none"])
def test_the_reader_agrees_with_rosbags_on_a_sound_bag(tmp_path, compression):
    from rosbags.rosbag1 import Reader

    chunks = [_fixes(0, 30), _fixes(15, 30), _fixes(100, 5)]   # the first two overlap in time
    (tmp_path / "a.bag").write_bytes(ros1_bag(chunks, compression=compression))
    ours = [(m.bag_time_ns, m.message.data) for m in read_bag(tmp_path / "a.bag")]
    with Reader(tmp_path / "a.bag") as r:
        theirs = [(t, raw) for _, t, raw in r.messages()]
    assert ours == [(t, raw[4:].decode()) for t, raw in theirs]


@settings(max_examples=60, deadline=None)
@given(st.integers(min_value=0, max_value=2), st.sampled_from(["cut", "garbage", "declared"]), st.integers(0, 10**6))
def test_a_damaged_chunk_is_a_problem_per_message_never_an_exception(tmp_path_factory, which, how, seed):
    chunks = [_fixes(0, 10), _fixes(10, 10), _fixes(20, 10)]
    good = bz2.compress(b"x" * 5000)
    data = {"cut": {which: good[: seed % len(good)]}, "garbage": {which: bytes([seed % 256]) * (seed % 900 + 1)},
            "declared": {}}[how]
    declared = {which: seed % (MAX_CHUNK_BYTES * 2)} if how == "declared" else {}
    path = tmp_path_factory.mktemp("bag") / "a.bag"
    path.write_bytes(ros1_bag(chunks, chunk_data=data, declared=declared))
    messages = list(read_bag(path))
    assert len(messages) == 30
    assert all(not m.problem for m in messages if not (10 * which <= (m.bag_time_ns - T0) // 10**9 < 10 * which + 10))


def _db3(folder: Path, n: int = 10) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    String = store.types["std_msgs/msg/String"]
    with Writer(folder / "bag", version=8, storage_plugin=StoragePlugin.SQLITE3) as w:
        conn = w.add_connection("/nmea", String.__msgtype__, typestore=store)
        for i in range(n):
            w.write(conn, T0 + i * 10**9, store.serialize_cdr(String(data=gga(i).decode()), String.__msgtype__))
    return next((folder / "bag").glob("*.db3"))


@pytest.mark.parametrize("spoil", ["timestamp = NULL", "timestamp = 'soon'", "timestamp = 1.5",
                                   "timestamp = -5", "data = NULL", "data = 42"])
def test_a_ros2_row_with_a_bad_value_is_a_counted_skip(tmp_path, spoil):
    db = _db3(tmp_path)
    with sqlite3.connect(db) as con:   # without its NOT NULL and types: a row as another tool may leave it
        con.executescript("ALTER TABLE messages RENAME TO old;"
                          "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp, data);"
                          "INSERT INTO messages SELECT id, topic_id, timestamp, data FROM old; DROP TABLE old;")
        con.execute(f"UPDATE messages SET {spoil} WHERE id = 3")
    messages = list(read_bag(db))
    assert len(messages) == 10
    bad = [m for m in messages if m.problem]
    assert len(bad) == 1 and bad[0].topic == "/nmea" and bad[0].message is None
    target = tmp_path / "t"
    target.mkdir()
    (target / "a.db3").write_bytes(db.read_bytes())
    code, err, _ = run_child("record", str(_manifest(target, "a.db3")), "-o", str(tmp_path / "a.mcap"))
    assert code == 0 and "Traceback" not in err, err
    with ArchiveReader(tmp_path / "a.mcap") as r:
        files = r.metadata_json("recording")["files"]
        assert sum(1 for _ in r.messages(["/a/gps"])) == 9
    assert files[0]["skipped"] == 1
