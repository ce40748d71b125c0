"""Issue 14, archives: every hostile case replayed with its input built here; 0 tracebacks, bounded memory.

A command either exits 0 with one `warning:` line saying what it skipped, or
exits 1 with one `error:` line saying why; the reader never raises on damage.
"""

from __future__ import annotations

import json
import os
import random
import struct
from collections.abc import Callable
from pathlib import Path

import lz4.frame
import pytest
import zstandard
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from formats import schemas as S
from formats.mcap_chunks import ChunkError, chunk_payload
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from tests.hostile import GIB, record_offsets, rewrite, run_child, set_declared_size, zstd_bomb

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "samples" / "lake_trial"
REPLAY = ["--set", "methods=dead_reckoning", "--window", "0", "700"]
RSS_LIMIT_KB = 400 * 1024
T0 = 1_476_237_600 * 10**9


@pytest.fixture(scope="module")
def trial(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("hostile") / "trial.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), out)
    return out


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """In-process `auvreplay ARGV`: (exit code, stdout, stderr); an exception fails the test."""
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def one_line(err: str, kind: str) -> str:
    lines = [ln for ln in err.splitlines() if f": {kind}: " in ln]
    assert "Traceback" not in err and len(lines) == 1, err
    return lines[0]


# -- size bombs: a 134 KB chunk of 4 GiB, a declared 16 GiB ------------------------------------------------------
def test_zstd_bomb_is_refused_in_bounded_memory(trial, tmp_path, capsys):
    bomb = zstd_bomb()
    assert len(bomb) < 200_000
    path = rewrite(trial, tmp_path / "bomb.mcap", first_chunk=bomb)
    rc, err, rss = run_child("replay", str(path), *REPLAY, "-o", str(tmp_path / "r.mcap"))
    assert rc == 0 and "skipped 1 chunk" in one_line(err, "warning") and rss < RSS_LIMIT_KB, (err, rss)
    rc, _, err = run_cli(capsys, "export", str(path), "--topic", "/follower/gps", "-o", str(tmp_path / "g.csv"))
    assert rc == 0 and "skipped 1 chunk" in one_line(err, "warning")


def test_recover_skips_a_zstd_bomb_in_bounded_memory(trial, tmp_path):
    # recover decompresses through the same bounded path as the reader: the bomb is a damaged chunk
    path = rewrite(trial, tmp_path / "bomb.mcap", first_chunk=zstd_bomb(content_size=True))
    rc, err, rss = run_child("recover", str(path), "-o", str(tmp_path / "fixed.mcap"))
    assert rc == 0 and rss < RSS_LIMIT_KB, (err, rss)
    assert (tmp_path / "fixed.mcap").stat().st_size > 0


def test_zstd_frame_that_says_more_than_the_chunk_is_not_allocated():
    # python-zstandard allocates what a frame header says, whatever the output limit: the header is checked first
    bomb = zstd_bomb(80 << 20, content_size=True)
    raw = struct.pack("<BQQQQI", 6, 0, 0, 0, 1 << 20, 0) + struct.pack("<I", 4) + b"zstd" \
        + struct.pack("<Q", len(bomb)) + bomb
    with pytest.raises(ChunkError, match="zstd frame holds 80 MiB, the chunk declares 1 MiB"):
        chunk_payload(raw, 0, 1 << 20, 0, True, 64 << 20)


def test_declared_16_gib_chunk_is_refused(trial, tmp_path):
    path = tmp_path / "declared.mcap"
    path.write_bytes(trial.read_bytes())
    with ArchiveReader(path) as r:   # the chunk that holds the follower's ranges: without them nothing scores
        ranges = next(c.id for c in r._index.channels.values() if c.topic == "/follower/modem/range")
        scored = next(ci.chunk_start_offset for ci in r._index.chunk_indexes if ranges in ci.message_index_offsets)
    set_declared_size(path, scored, 16 * GIB)
    rc, err, rss = run_child("replay", str(path), *REPLAY, "-o", str(tmp_path / "r.mcap"))
    # the chunk held the window's scored follower data: the replay runs on what is left (the trial still holds
    # positions) and its warning names the refused chunk
    assert rc == 0 and "16.0 GiB uncompressed, over the 64 MiB limit" in one_line(err, "warning"), err
    assert rss < RSS_LIMIT_KB


def test_chunk_payload_checks_what_comes_out_against_what_it_declares():
    data = b"\x05" + bytes(8) * 3
    for body, compression in ((zstandard_frame(data), "zstd"), (lz4_frame(data), "lz4")):
        raw = struct.pack("<BQQQQI", 6, 0, 0, 0, len(data), 0) + struct.pack("<I", len(compression)) \
            + compression.encode() + struct.pack("<Q", len(body)) + body
        assert chunk_payload(raw, 0, len(data), 0, True, 1 << 20) == data
        for wrong in (len(data) - 1, len(data) + 1):
            with pytest.raises(ChunkError):
                chunk_payload(raw, 0, wrong, 0, True, 1 << 20)
        with pytest.raises(ChunkError, match="over the"):
            chunk_payload(raw, 0, len(data), 0, True, len(data) - 1)


def zstandard_frame(data: bytes) -> bytes:
    return zstandard.ZstdCompressor(write_content_size=False).compress(data)


def lz4_frame(data: bytes) -> bytes:
    return lz4.frame.compress(data)


def test_absurd_record_length_ends_the_scan_with_a_message(trial, tmp_path, capsys):
    data = bytearray(trial.read_bytes())
    offset, _ = record_offsets(trial, 0x06)[2]
    struct.pack_into("<Q", data, offset + 1, 2**63)
    path = tmp_path / "length.mcap"
    path.write_bytes(bytes(data[: len(data) - 100]))  # no footer: the sequential scan meets the length
    rc, _, err = run_cli(capsys, "info", str(path))
    assert rc == 0 and "declares 8589934592.0 GiB" in one_line(err, "warning")


# -- damage as data: messages, encodings, schemas, lz4 chunks ---------------------------------------------------
def _garbage(rate: float, topic: str | None = None):
    def damage(t: str, data: bytes, rng: random.Random) -> bytes:
        if (topic is None or t == topic) and rng.random() < rate:
            return rng.randbytes(max(len(data), 1))
        return data
    return damage


def test_every_follower_gps_message_garbage(trial, tmp_path, capsys):
    path = rewrite(trial, tmp_path / "g.mcap", message=_garbage(1.0, "/follower/gps"))
    rc, out, err = run_cli(capsys, "replay", str(path), "--set", "methods=dead_reckoning,chi_square", "--window",
                           "0", "700", "--json", "-o", str(tmp_path / "r.mcap"))
    # the follower's INS and the leaders' GPS are positions: the replay runs, says what it skipped, and scores
    # no epoch (no GPS to label one)
    assert rc == 0 and "/follower/gps:" in one_line(err, "warning")
    obj = json.loads(out)
    assert obj["epochs"] == 0 and set(obj["methods"]) >= {"dead_reckoning", "chi_square"}
    rc, out, err = run_cli(capsys, "export", str(path), "--topic", "/follower/gps", "-o", str(tmp_path / "g.csv"))
    assert rc == 0 and "do not decode" in one_line(err, "warning")


def test_one_in_97_messages_garbage(trial, tmp_path, capsys):
    path = rewrite(trial, tmp_path / "g.mcap", message=_garbage(1 / 97), seed=3)
    rc, out, err = run_cli(capsys, "replay", str(path), *REPLAY, "-o", str(tmp_path / "r.mcap"))
    line = one_line(err, "warning")
    assert rc == 0 and "do not decode" in line and "scored epochs" in out
    with ArchiveReader(path) as r:
        n = sum(1 for _ in r.messages())
        skipped = sum(r.damage.messages.values())
    with ArchiveReader(trial) as r:
        total = sum(1 for _ in r.messages())
    assert skipped > 0 and n + skipped <= total


def _library_archive(path: Path, compression: CompressionType, encoding: str = "protobuf",
                     schema_data: bytes | None = None, schema_name: str = "auvreplay.GnssStatus") -> Path:
    """An archive by the mcap library's writer: one /x/gps/status channel, 200 messages."""
    with open(path, "wb") as f:
        w = Writer(f, compression=compression, chunk_size=2000)
        w.start()
        data = schema_data if schema_data is not None else \
            build_file_descriptor_set(S.GnssStatus).SerializeToString()
        sid = w.register_schema(schema_name, "protobuf", data)
        cid = w.register_channel("/x/gps/status", encoding, sid)
        for k in range(200):
            w.add_message(cid, T0 + k, S.GnssStatus(satellites=k).SerializeToString(), T0 + k)
        w.finish()
    return path


def test_lz4_chunks_read_and_a_bad_one_is_skipped(tmp_path, capsys):
    path = _library_archive(tmp_path / "lz4.mcap", CompressionType.LZ4)
    with ArchiveReader(path) as r:
        assert [m.message.satellites for m in r.messages()] == list(range(200)) and r.warning() is None
    data = bytearray(path.read_bytes())
    offset, length = record_offsets(path, 0x06)[1]
    data[offset + length - 20: offset + length - 4] = bytes(16)  # inside the lz4 data of the second chunk
    path.write_bytes(bytes(data))
    rc, out, err = run_cli(capsys, "export", str(path), "--topic", "/x/gps/status", "-o", str(tmp_path / "x.csv"))
    assert rc == 0 and "skipped 1 chunk" in one_line(err, "warning")
    assert 100 < int(out.split()[1]) < 200


def test_json_channel_and_garbage_schema_are_skipped_and_counted(tmp_path, capsys):
    path = _library_archive(tmp_path / "json.mcap", CompressionType.ZSTD, encoding="json")
    rc, out, err = run_cli(capsys, "export", str(path), "--topic", "/x/gps/status", "-o", str(tmp_path / "j.csv"))
    assert rc == 0 and "200 of encoding 'json', not protobuf" in one_line(err, "warning")
    path = _library_archive(tmp_path / "schema.mcap", CompressionType.ZSTD, schema_data=bytes(range(256)) * 4,
                            schema_name="lab.Garbage")
    rc, out, err = run_cli(capsys, "export", str(path), "--topic", "/x/gps/status", "-o", str(tmp_path / "s.csv"))
    assert rc == 0 and "200 of an unreadable schema 'lab.Garbage'" in one_line(err, "warning")


def test_a_sensor_topic_of_another_schema_is_not_fed_to_the_engine(trial, tmp_path, capsys):
    path = tmp_path / "swap.mcap"
    with ArchiveReader(trial) as r, ArchiveWriter(path) as w:
        for m in r.messages():
            topic = {"/leader1/ins": "/leader1/x", "/leader1/gps/status": "/leader1/ins"}.get(m.topic, m.topic)
            w.write(topic, m.message, m.log_time_ns)
        for name in ("trial", "recording"):
            w.add_metadata(name, r.metadata(name))
    rc, out, err = run_cli(capsys, "replay", str(path), *REPLAY, "-o", str(tmp_path / "r.mcap"))
    assert rc == 0 and "of schema 'auvreplay.GnssStatus', not auvreplay.InsState" in one_line(err, "warning")


# -- metadata and attachment records ----------------------------------------------------------------------------
def test_flipped_byte_in_metadata_is_a_skipped_record(trial, tmp_path, capsys):
    data = bytearray(trial.read_bytes())
    for offset, length in record_offsets(trial, 0x0C):
        data[offset + length // 2] = 0xFF  # not UTF-8 (the record has no CRC)
    path = tmp_path / "meta.mcap"
    path.write_bytes(bytes(data))
    rc, out, err = run_cli(capsys, "info", str(path))
    assert rc == 0 and "metadata record" in one_line(err, "warning")
    rc, out, err = run_cli(capsys, "replay", str(path), *REPLAY, "-o", str(tmp_path / "r.mcap"))
    # without the trial metadata the roles are guessed (every DVL a follower) and said; the run goes on
    assert rc == 0 and "roles guessed" in err and "metadata records" in one_line(err, "warning")
    rc, out, err = run_cli(capsys, "unpack", str(path), str(tmp_path / "logs"))
    assert rc == 0 and "metadata record" in one_line(err, "warning") and len(out.splitlines()) == 20


def test_metadata_of_the_wrong_shape(trial, tmp_path, capsys):
    path = tmp_path / "shape.mcap"
    with ArchiveReader(trial) as r, ArchiveWriter(path) as w:
        for m in r.messages():
            w.write(m.topic, m.message, m.log_time_ns)
        w.add_metadata("trial", {"name": ["x"], "vehicles": [{"name": ["a"]}, 7, {"name": "follower", "role": 3}]})
        w.add_metadata("recording", {"files": [1, "x", {"path": 3}, {"path": "a.log", "parsed": "many"}]})
    rc, out, err = run_cli(capsys, "info", str(path))
    assert rc == 0 and "a.log" in out and "3 log entries" in one_line(err, "warning")
    rc, out, err = run_cli(capsys, "replay", str(path), *REPLAY, "-o", str(tmp_path / "r.mcap"))
    assert rc == 0 and "roles guessed" in err


def test_two_attachments_of_one_name_do_not_overwrite(tmp_path, capsys):
    path = tmp_path / "twice.mcap"
    with ArchiveWriter(path) as w:
        w.write("/a/gps", S.location_fix(T0, "a", 1.0, 2.0), T0)
        w.add_attachment("a/gps.log", b"first")
        w.add_attachment("a/gps.log", b"second")
    rc, out, err = run_cli(capsys, "unpack", str(path), str(tmp_path / "out"))
    assert rc == 1 and "a second attachment named 'a/gps.log'" in err and "Traceback" not in err
    assert (tmp_path / "out" / "a" / "gps.log").read_bytes() == b"first"


def test_attachment_crc_damage_is_skipped(tmp_path, capsys):
    path = tmp_path / "att.mcap"
    with ArchiveWriter(path) as w:
        w.write("/a/gps", S.location_fix(T0, "a", 1.0, 2.0), T0)
        w.add_attachment("a.log", b"x" * 100)
        w.add_attachment("b.log", b"y" * 100)
    data = bytearray(path.read_bytes())
    offset, _ = record_offsets(path, 0x09)[0]
    data[offset + 60] ^= 1
    path.write_bytes(bytes(data))
    rc, out, err = run_cli(capsys, "unpack", str(path), str(tmp_path / "out"))
    assert rc == 0 and "CRC mismatch" in one_line(err, "warning") and out.strip().endswith("b.log")


# -- truncation -------------------------------------------------------------------------------------------------
def test_truncated_archives_say_so_or_refuse_with_a_reason(trial, tmp_path, capsys):
    data = trial.read_bytes()
    for cut in (3_000_000, len(data) // 7, len(data) - 5, len(data) - 3000):
        path = tmp_path / f"cut{cut}.mcap"
        path.write_bytes(data[:cut])
        rc, out, err = run_cli(capsys, "replay", str(path), *REPLAY, "-o", str(tmp_path / f"r{cut}.mcap"))
        if rc == 0:
            assert "read sequentially" in one_line(err, "warning")
        else:
            assert rc == 1 and "nothing to replay" in one_line(err, "error") and "read sequentially" in err
        rc, out, err = run_cli(capsys, "info", str(path))
        assert rc == 0 and "read sequentially" in one_line(err, "warning")


def _without(trial: Path, path: Path, drop: Callable[[str], bool]) -> Path:
    with ArchiveReader(trial) as r, ArchiveWriter(path) as w:
        for m in r.messages():
            if not drop(m.topic):
                w.write(m.topic, m.message, m.log_time_ns)
        w.add_metadata("trial", r.metadata("trial"))
    return path


def test_replay_with_no_follower_runs_what_it_can_and_names_the_rest(trial, tmp_path, capsys):
    path = _without(trial, tmp_path / "leaders.mcap", lambda t: t.startswith("/follower/"))
    rc, out, err = run_cli(capsys, "replay", str(path), "--set", "methods=dead_reckoning,ackf", "--window", "0",
                           "700", "--json", "-o", str(tmp_path / "r.mcap"))
    assert rc == 0 and (tmp_path / "r.mcap").exists()
    skipped = json.loads(out)["skipped"]
    assert skipped["dead_reckoning"] == "needs DVL velocities on the vehicle"
    assert skipped["ackf"] == "needs DVL velocities on the vehicle and modem ranges from a leader with a position"


def test_replay_of_a_trial_without_any_position_exits_1_with_the_reason(trial, tmp_path, capsys):
    path = _without(trial, tmp_path / "blind.mcap", lambda t: t.endswith(("/gps", "/ins")))
    rc, out, err = run_cli(capsys, "replay", str(path), *REPLAY, "-o", str(tmp_path / "r.mcap"))
    assert rc == 1 and "no position of any kind" in one_line(err, "error") and not (tmp_path / "r.mcap").exists()


def test_reader_never_raises_on_random_bytes_after_the_magic():
    rng = random.Random(5)
    for _ in range(200):
        blob = b"\x89MCAP0\r\n" + rng.randbytes(rng.randrange(0, 400))
        path = Path(f"/tmp/_hostile_{os.getpid()}.mcap")
        path.write_bytes(blob)
        with ArchiveReader(path) as r:
            list(r.messages()), r.summary(), r.metadata("trial"), list(r.attachments())
        path.unlink()
