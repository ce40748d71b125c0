"""recover in bounded memory: zstd bombs and chunks over the cap are lost with their reason, large archives stream.

Every archive is built here; peak RSS is the child's own (VmHWM), measured by tests.hostile.run_child.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader

from formats import schemas as S
from formats.mcap_chunks import MAX_CHUNK_BYTES
from formats.mcap_recover import recover
from formats.mcap_writer import ArchiveWriter
from tests.hostile import GIB, chunk_offsets, run_child, set_declared_size, zstd_bomb

T0 = 1_476_237_600 * 10**9
LIMIT_KB = 400 * 1024


class _Bombs:
    """A compressor whose first `n` chunks are a zstd frame inflating to `size` bytes."""

    def __init__(self, n: int, size: int, content_size: bool):
        import zstandard

        self.left, self.bomb = n, zstd_bomb(size, content_size)
        self.real = zstandard.ZstdCompressor(level=3)

    def compress(self, data: bytes) -> bytes:
        if self.left:
            self.left -= 1
            return self.bomb
        return self.real.compress(data)


def _archive(path: Path, bombs: int = 0, bomb_size: int = 0, content_size: bool = False,
             chunks: int = 8, per_chunk: int = 40) -> list[int]:
    """`chunks` chunks of `per_chunk` GPS status messages; the first `bombs` chunks' data replaced by bombs."""
    times = []
    with ArchiveWriter(path, chunk_size=1 << 30) as w:
        if bombs:
            w._zstd = _Bombs(bombs, bomb_size, content_size)
        w.add_metadata("trial", {"name": "t"})
        for c in range(chunks):
            for i in range(per_chunk):
                t = T0 + (c * per_chunk + i) * 10**8
                w.write("/a/gps/status", S.GnssStatus(timestamp=S.timestamp(t), frame_id="a", satellites=i), t)
                times.append(t)
            w.flush()   # one chunk
    return times


def _kept_times(path: Path) -> list[int]:
    with open(path, "rb") as f:
        return sorted(m.log_time for _, _, m in make_reader(f).iter_messages())


@pytest.mark.parametrize("content_size", [False, True])
@pytest.mark.parametrize("declared", ["honest", "1.5 GiB"])
def test_four_zstd_bombs_are_lost_chunks_in_bounded_memory(tmp_path, content_size, declared):
    src = tmp_path / "bombs.mcap"
    times = _archive(src, bombs=4, bomb_size=3 * GIB // 2, content_size=content_size)
    if declared != "honest":   # the header tells the truth about the bomb: over the cap, refused unread
        for offset in chunk_offsets(src)[:4]:
            set_declared_size(src, offset, 3 * GIB // 2)
    assert src.stat().st_size < 400_000
    code, err, peak_kb = run_child("recover", str(src), "-o", str(tmp_path / "fixed.mcap"))
    print(f"\nrecover, 4 bombs ({declared}, content size {content_size}): peak RSS {peak_kb // 1024} MB")
    assert code == 0, err
    assert "Traceback" not in err and peak_kb < LIMIT_KB
    lost = [line for line in err.splitlines() if line.startswith("lost chunk")]
    assert len(lost) == 4
    if declared != "honest":
        assert all("over the 64 MiB limit" in line for line in lost)
    assert _kept_times(tmp_path / "fixed.mcap") == times[4 * 40:]


def test_a_chunk_just_over_the_cap_is_lost_and_one_under_it_kept(tmp_path):
    src = tmp_path / "a.mcap"
    times = _archive(src, chunks=3)
    first = chunk_offsets(src)[0]
    set_declared_size(src, first, MAX_CHUNK_BYTES + 1)
    report = recover(src, tmp_path / "fixed.mcap")
    assert report.chunks_lost == 1 and "over the 64 MiB limit" in report.lost[0].reason
    assert report.lost[0].chunk and report.lost[0].start_ns == times[0]
    assert _kept_times(tmp_path / "fixed.mcap") == times[40:]


def test_a_large_archive_is_recovered_one_chunk_at_a_time(tmp_path):
    """384 MiB of messages in 32 MiB chunks, cut short: recover holds one chunk, not the file's messages."""
    src = tmp_path / "big.mcap"
    payload = bytes(range(256)) * 4096   # 1 MiB, compresses well: the file stays small on disk
    with ArchiveWriter(src, chunk_size=32 << 20) as w:
        for i in range(384):
            t = T0 + i * 10**9
            w.write("/raw/a", S.RawBytes(timestamp=S.timestamp(t), stream="a", offset=i << 20, data=payload), t)
    data = src.read_bytes()
    src.write_bytes(data[: len(data) - 200])   # no summary: recover must scan and rebuild
    code, err, peak_kb = run_child("recover", str(src), "-o", str(tmp_path / "fixed.mcap"))
    print(f"\nrecover, 384 MiB in 12 chunks: peak RSS {peak_kb // 1024} MB")
    assert code == 0, err
    assert peak_kb < LIMIT_KB
    with open(tmp_path / "fixed.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == 384
