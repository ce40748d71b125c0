"""Blocks over an archive whose topics were written one after another (bench/mission.py's layout): a chunk that
ends one topic and starts another is wanted from the start to the end of the trial, and must not hold its
consumed bytes that long."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from formats import mcap_blocks
from formats import schemas as S
from formats.mcap_blocks import COLUMN_FIELDS
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter

NS = 1_000_000_000


def _write(path: Path, n: int) -> None:
    """INS at 1 Hz for n s, then GPS at 0.1 Hz over the same span, then INS of a second vehicle: small chunks."""
    with ArchiveWriter(path, chunk_size=4096) as w:
        for v in ("a", "b"):
            for k in range(n):
                w.write(f"/{v}/ins", S.InsState(timestamp=S.timestamp(k * NS), frame_id=v, latitude=1e-4 * k,
                                                longitude=2e-4 * k, depth_m=0.5, heading_deg=float(k % 360)), k * NS)
            for k in range(0, n, 10):
                w.write(f"/{v}/gps", S.location_fix(k * NS, v, 1e-4 * k, 2e-4 * k, 0.0), k * NS)


@pytest.mark.parametrize("n", [3000])
def test_blocks_equal_messages_and_runs_let_go_of_taken_bytes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                              n: int) -> None:
    path = tmp_path / "seq.mcap"
    _write(path, n)
    held: list[int] = []
    take = mcap_blocks._take

    def spy(runs: list[Any], before: int | None, *args: Any) -> Any:
        out = take(runs, before, *args)
        held.append(sum(len(r.data) for r in runs))
        return out

    monkeypatch.setattr(mcap_blocks, "_take", spy)
    monkeypatch.setattr(mcap_blocks, "BLOCK_MESSAGES", 256)
    with ArchiveReader(path) as reader:
        ref = [(m.topic, m.log_time_ns, m.message) for m in reader.messages()]
        columnar = [t for t, v in reader.summary().topics.items() if v["schema"] in COLUMN_FIELDS]
        got = []
        for block in reader.blocks(columns=columnar):
            for i in range(len(block)):
                topic = block.topics[block.topic_index[i]]
                got.append((topic, int(block.log_ns[i]), block.message(topic, int(block.row[i]))))
    assert got == ref
    # after each block, what the runs hold: the untaken parts of the slow topics' and the boundaries' chunks,
    # not those chunks whole (4 kB each): def47b4 held 25,008 bytes here, this 19,276
    assert len(held) > 10
    assert max(held[2:]) < 5 * 4096
