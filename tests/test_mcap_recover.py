"""recover: every intact chunk kept, also after a damaged one; indexes and summary rebuilt; losses reported."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.mcap_recover import recover
from formats.mcap_writer import ArchiveWriter
from formats.records import FormatError

T0 = 1_476_237_600 * 10**9


def _archive(path: Path, n: int = 1500) -> list[tuple[int, bytes]]:
    """Two topics, times increasing, chunks of ~4 KiB; returns (log time, message bytes) of every message."""
    rng = random.Random(3)
    written = []
    with ArchiveWriter(path, chunk_size=4096) as w:
        w.add_metadata("trial", {"name": "t"})
        for i in range(n):
            t = T0 + i * 10**8
            msg = S.GnssStatus(timestamp=S.timestamp(t), frame_id="a", hdop=rng.random(), satellites=i % 12)
            w.write("/a/gps/status" if i % 3 else "/b/gps/status", msg, t)
            written.append((t, msg.SerializeToString()))
        w.add_attachment("a/gps.log", b"$GPGGA\n" * 50, "text/plain", T0, T0)
    return written


def _chunks(path: Path) -> list:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)


def _read(path: Path) -> list[tuple[int, bytes]]:
    with open(path, "rb") as f:  # the independent reader
        reader = make_reader(f)
        assert reader.get_summary() is not None
        return sorted((m.log_time, m.data) for _, _, m in reader.iter_messages())


def _in_chunk(msgs, chunk) -> set:
    return {m for m in msgs if chunk.message_start_time <= m[0] <= chunk.message_end_time}


@pytest.mark.parametrize("how", ["payload", "header", "zeros"])
def test_a_damaged_middle_chunk_loses_only_itself(tmp_path, how):
    src, out = tmp_path / "a.mcap", tmp_path / "fixed.mcap"
    msgs = _archive(src)
    chunks = _chunks(src)
    bad = chunks[len(chunks) // 2]
    data = bytearray(src.read_bytes())
    at = bad.chunk_start_offset
    if how == "payload":  # compressed bytes: zstd or the CRC fails, the record's length still holds
        data[at + 80:at + 120] = bytes(b ^ 0x5A for b in data[at + 80:at + 120])
    elif how == "header":  # opcode and length gone: found again by resync
        data[at:at + 9] = b"\xff" * 9
    else:  # a run of zeros over the chunk and into the next record, as a bad disk block gives
        data[at:at + bad.chunk_length + 20] = bytes(bad.chunk_length + 20)
    src.write_bytes(bytes(data))
    report = recover(src, out)
    got = _read(out)
    lost = _in_chunk(msgs, bad)
    assert set(got) == set(msgs) - lost and len(got) == len(msgs) - len(lost)
    assert report.chunks_kept == len(chunks) - 1
    first = report.lost[0]
    assert first.start == at and first.end >= at + bad.chunk_length
    if how == "payload":
        assert first.chunk and (first.start_ns, first.end_ns) == (bad.message_start_time, bad.message_end_time)
    else:  # no header to read: the span between the kept chunks around it
        assert first.start_ns <= bad.message_start_time and first.end_ns >= bad.message_end_time
    with ArchiveReader(out) as reader:
        assert not reader.problems
        assert sorted(reader.summary().topics) == ["/a/gps/status", "/b/gps/status"]
        assert [a.data for a in reader.attachments()] == [b"$GPGGA\n" * 50]
        assert reader.metadata("trial") == {"name": "t"}


def test_a_cut_off_file_keeps_its_complete_chunks(tmp_path):
    src, out = tmp_path / "a.mcap", tmp_path / "fixed.mcap"
    msgs = _archive(src)
    chunks = _chunks(src)
    keep = chunks[-3]
    cut = keep.chunk_start_offset + keep.chunk_length // 2
    src.write_bytes(src.read_bytes()[:cut])
    report = recover(src, out)
    kept = set().union(*(_in_chunk(msgs, c) for c in chunks[:-3]))
    assert set(_read(out)) == kept
    assert report.lost[-1].end == cut and "truncated" in report.lost[-1].reason


def test_an_intact_archive_comes_back_whole(tmp_path):
    src, out = tmp_path / "a.mcap", tmp_path / "fixed.mcap"
    msgs = _archive(src, 300)
    report = recover(src, out)
    assert not report.lost and _read(out) == sorted(msgs) and report.had_summary


def test_not_mcap_and_same_file_are_clear_errors(tmp_path):
    (tmp_path / "x.mcap").write_bytes(b"hello")
    with pytest.raises(FormatError, match="not an MCAP file"):
        recover(tmp_path / "x.mcap", tmp_path / "y.mcap")
    with pytest.raises(FormatError, match="other than the input"):
        recover(tmp_path / "x.mcap", tmp_path / "x.mcap")


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), hits=st.integers(1, 6))
def test_random_damage_never_invents_or_raises(tmp_path_factory, seed, hits):
    tmp = tmp_path_factory.mktemp("r")
    src, out = tmp / "a.mcap", tmp / "fixed.mcap"
    msgs = set(_archive(src, 400))
    data = bytearray(src.read_bytes())
    rng = random.Random(seed)
    for _ in range(hits):
        at = rng.randrange(8, len(data))
        data[at:at + rng.randint(1, 64)] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 64)))
    src.write_bytes(bytes(data[:rng.randint(len(data) // 2, len(data))]))
    report = recover(src, out)
    got = _read(out)
    assert set(got) <= msgs and len(got) == report.messages
