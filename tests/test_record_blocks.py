"""Issue 14, `record` in memory bounded by the block, not the log: blocks cut at line ends, the NMEA converter
carrying its epoch and clock across them, archives unchanged, peak RSS flat in the log's size."""

from __future__ import annotations

import random
import shutil
from datetime import date
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import formats.log_blocks as log_blocks
import recorders.record as recording
from formats.log_blocks import Block, ChangedWhileRead, LogFiles, blocks_of, cut_blocks
from formats.nmea.sentences import encode_gga, encode_rmc
from recorders.base import LogContext
from recorders.gps import convert_nmea, convert_nmea_blocks
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record, reject_kind
from tests.hostile import damage_lines, run_child

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "samples" / "lake_trial"
GPS = (SAMPLE / "follower" / "gps.log").read_bytes()
CTX = LogContext(vehicle="v", trial_date=date(2016, 10, 12))
RSS_LIMIT_KB = 400 * 1024


def _plain(items) -> list:
    """Outputs as comparable values (protobuf messages by their bytes), Rejects as they are."""
    return [(i.topic, i.message.SerializeToString(), i.log_time_ns, i.publish_time_ns, i.where)
            if hasattr(i, "message") else i for i in items]


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=600).map(lambda b: b.replace(b"\x00", b"\n")), st.integers(1, 80),
       st.lists(st.integers(1, 50), max_size=8))
def test_blocks_are_the_log_cut_after_line_ends(data, size, piece_sizes):
    pieces, at = [], 0
    for n in piece_sizes:
        pieces.append(data[at:at + n])
        at += n
    pieces.append(data[at:])
    blocks = list(cut_blocks(pieces, size))
    assert b"".join(b.data for b in blocks) == data
    offset = lines = 0
    for i, block in enumerate(blocks):
        assert (block.offset, block.lines) == (offset, lines)
        assert block.data
        if i < len(blocks) - 1:  # a line end closes it, or it is a full block without one
            assert block.data.endswith(b"\n") or (len(block.data) == size and b"\n" not in block.data)
        offset, lines = offset + len(block.data), lines + block.data.count(b"\n")


@pytest.mark.parametrize("seed", [None, 1, 2, 3])
def test_nmea_in_blocks_gives_the_whole_logs_outputs(seed):
    data = GPS if seed is None else damage_lines(GPS, seed)
    whole = _plain(convert_nmea(data, CTX))
    assert len(whole) > 3000
    longest = max(map(len, data.split(b"\n")))
    for size in (longest + 1, 1000, 4096, 50_000, len(data) // 2):
        assert _plain(convert_nmea_blocks(blocks_of(data, max(size, longest + 1)), CTX)) == whole, size


def test_nmea_blocks_carry_the_date_over_midnight():
    # an RMC with the date, then a day of GGA only past midnight: the date must go on from block to block
    t0 = 1476316790 * 10**9  # 2016-10-12T23:59:50Z
    text = encode_rmc(t0, 45.7, 126.6) + "".join(
        encode_gga(t0 + k * 10**9, 45.7, 126.6, hdop=0.9) for k in range(1, 40))
    data = text.encode()
    whole = _plain(convert_nmea(data, LogContext(vehicle="v")))
    times = [item[2] for item in whole if isinstance(item, tuple) and item[0] == "/v/gps"]
    assert times[-1] - times[0] == 39 * 10**9  # past midnight, the next day
    for size in (100, 200, 333):
        assert _plain(convert_nmea_blocks(blocks_of(data, size), LogContext(vehicle="v"))) == whole


def test_sample_trial_archive_is_the_same_in_small_blocks(tmp_path, monkeypatch):
    manifest = load_manifest(SAMPLE / "trial.toml")
    record(manifest, tmp_path / "default.mcap", workers=1)
    monkeypatch.setattr(log_blocks, "BLOCK_BYTES", 3000)
    record(manifest, tmp_path / "small.mcap", workers=1)
    record(manifest, tmp_path / "small2.mcap", workers=2)  # logs decoded in a worker: attached from the file
    default = (tmp_path / "default.mcap").read_bytes()
    assert (tmp_path / "small.mcap").read_bytes() == default
    assert (tmp_path / "small2.mcap").read_bytes() == default


def test_a_file_that_changes_size_while_read_is_refused(tmp_path):
    path = tmp_path / "gps.log"
    path.write_bytes(GPS[:5000])
    files = LogFiles([path], [4000])
    with pytest.raises(ChangedWhileRead):
        b"".join(block.data for block in files.blocks(1000))


@pytest.mark.parametrize("started, words", [(4000, "more than 4000 bytes read, 4000 when"),
                                             (6000, "5000 bytes read, 6000 when")])
def test_a_log_read_whole_that_changed_size_is_refused(tmp_path, started, words):
    path = tmp_path / "gps.log"
    path.write_bytes(GPS[:5000])
    assert LogFiles([path], [5000]).read_whole() == [GPS[:5000]]
    with pytest.raises(ChangedWhileRead, match=words):
        LogFiles([path], [started]).read_whole()


def _flip_first_byte(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(bytes([data[0] ^ 1]) + data[1:])


def _append_line(path: Path) -> None:
    with open(path, "ab") as log:
        log.write(b"$GPTXT,01,01,02,late*00\r\n")


@pytest.mark.parametrize("change", [_flip_first_byte, _append_line])
def test_a_log_in_blocks_changed_between_attaching_and_decoding_is_refused(tmp_path, monkeypatch, change):
    shutil.copytree(SAMPLE, tmp_path / "trial")
    manifest = load_manifest(tmp_path / "trial" / "trial.toml")
    monkeypatch.setattr(log_blocks, "BLOCK_BYTES", 3000)  # every log larger than a block: attached from the file
    attach = recording._attach_streamed

    def attach_then_change(writer, manifest, log, names, fallback):
        digests = attach(writer, manifest, log, names, fallback)
        change(manifest.root / names[0])
        return digests

    monkeypatch.setattr(recording, "_attach_streamed", attach_then_change)
    with pytest.raises(ManifestError, match="changed while it was recorded"):
        record(manifest, tmp_path / "out.mcap", workers=1)
    assert not (tmp_path / "out.mcap").exists()


def test_a_log_a_worker_decoded_in_blocks_then_changed_is_refused(tmp_path, monkeypatch):
    # the main process attaches a worker's log from the file: a change after the worker read it must be seen
    shutil.copytree(SAMPLE, tmp_path / "trial")
    manifest = load_manifest(tmp_path / "trial" / "trial.toml")
    monkeypatch.setattr(log_blocks, "BLOCK_BYTES", 3000)
    capture = recording._capture

    def capture_then_change(manifest, log, tables, fallback):
        captured = capture(manifest, log, tables, fallback)
        _flip_first_byte(manifest.root / log.path)
        return captured

    monkeypatch.setattr(recording, "_capture", capture_then_change)
    with pytest.raises(ManifestError, match="changed while it was recorded"):
        record(manifest, tmp_path / "out.mcap", workers=2)
    assert not (tmp_path / "out.mcap").exists()


def test_reject_kinds_ignore_the_bytes_quoted():
    assert reject_kind("bad checksum '00', computed 4A") == reject_kind("bad checksum 'Zq', computed 01") \
        == "bad checksum"
    assert reject_kind("malformed sentence address '\\x01ab'") == "malformed sentence address"
    assert reject_kind("bad GGA sentence: could not convert") == "bad GGA sentence"
    assert Block(b"x").lines == 0


def _trial(folder: Path, write) -> Path:
    folder.mkdir()
    with open(folder / "gps.log", "wb") as log:
        write(log)
    (folder / "trial.toml").write_text(
        '[trial]\nname = "t"\ndate = "2016-10-12"\n\n[[vehicles]]\nname = "a"\nrole = "leader"\n\n'
        '[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\npath = "gps.log"\n')
    return folder / "trial.toml"


def bad_checksums(size: int):
    """A writer of `size` bytes of GGA sentences whose checksums are all wrong."""
    def write(log) -> None:
        line = b"$GPGGA,%06d.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*00\r\n"
        lines = b"".join(line % (k % 86400) for k in range(10_000))
        for _ in range(size // len(lines) + 1):
            log.write(lines)
    return write


def random_bytes(size: int):
    """A writer of `size` random bytes."""
    def write(log) -> None:
        rng = random.Random(size)
        for _ in range(size >> 20):
            log.write(rng.randbytes(1 << 20))
    return write


@pytest.mark.parametrize("kind, small, large", [(bad_checksums, 8 << 20, 24 << 20), (random_bytes, 12 << 20, 36 << 20)])
def test_record_memory_does_not_grow_with_the_log(tmp_path, kind, small, large):
    peaks = {}
    for size in (small, large):
        manifest = _trial(tmp_path / str(size), kind(size))
        rc, err, peaks[size] = run_child("record", str(manifest), "-o", str(tmp_path / f"{size}.mcap"), "--quiet")
        assert rc == 0, err
    # holding the log costs a byte per log byte at least (4 to 7 before blocks); in blocks the peak is about the
    # same from a couple of blocks on (both sizes are several); the full 200 MB runs in bench/bench_record_memory.py
    assert peaks[large] < RSS_LIMIT_KB and peaks[large] - peaks[small] < (large - small) / 2 / 1024, peaks


@pytest.mark.parametrize("files, extra", [('"gps.log.*"', ""), ('["gps.log.2", "gps.log.0", "gps.log.1"]',
                                                                  'order = "time"\n')])
def test_a_rotated_log_in_blocks_is_the_archive_it_is_read_whole(tmp_path, monkeypatch, files, extra):
    # at most a block in all, a log is read whole; larger, its files are read in blocks (and ordered by time so)
    lines = GPS.splitlines(keepends=True)
    a, b = len(lines) // 3, 2 * len(lines) // 3
    for i, piece in enumerate([lines[:a], lines[a:b], lines[b:]]):
        (tmp_path / f"gps.log.{i}").write_bytes(b"".join(piece))
    (tmp_path / "whole.log").write_bytes(GPS)
    (tmp_path / "trial.toml").write_text(
        '[trial]\nname = "t"\ndate = "2016-10-12"\n\n[[vehicles]]\nname = "a"\nrole = "leader"\n\n'
        f'[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\npath = {files}\n{extra}\n'
        '[[vehicles]]\nname = "b"\nrole = "follower"\n\n'
        '[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\npath = "whole.log"\n')
    manifest = load_manifest(tmp_path / "trial.toml")
    record(manifest, tmp_path / "whole.mcap", workers=1)
    monkeypatch.setattr(log_blocks, "BLOCK_BYTES", 3000)
    record(manifest, tmp_path / "blocks.mcap", workers=1)
    record(manifest, tmp_path / "blocks2.mcap", workers=2)
    whole = (tmp_path / "whole.mcap").read_bytes()
    assert (tmp_path / "blocks.mcap").read_bytes() == whole
    assert (tmp_path / "blocks2.mcap").read_bytes() == whole
