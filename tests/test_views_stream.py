"""`view` streamed: a replay drawn stretch by stretch holds, once complete, what the bulk recording holds.

The sample trial is replayed message by message (the reference path) with a stretch sent every few hundred
messages, into an .rrd; the same run's ReviewData is saved in bulk; both files are read back with Rerun's own
reader and compared entity by entity: every temporal row (its times and every component's cells), and the
last value of every static component.
"""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rerun.chunk import RrdReader

from formats.mcap_reader import ArchiveReader
from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from replay.review.collector import ReviewCollector
from replay.run.config import load_config
from replay.run.pipeline import replay_archive
from replay.views import recording as views
from replay.views.series import SPAN
from replay.views.stream import StreamedRecording, open_stream
from replay.views.tracks import TRAIL_STEP_S, trail_indices
from tests.processes import end_group

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
EVERY = 700        # messages between two stretches: about forty stretches over the sample trial


def _contents(path: Path) -> tuple[dict[str, Counter], dict[str, dict[str, Any]]]:
    """Per entity: its temporal rows as a multiset (times and cells), and the last value of each static component."""
    temporal: dict[str, Counter] = defaultdict(Counter)
    static: dict[str, dict[str, Any]] = defaultdict(dict)
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if ":" in n or n in ("time", "mission_s")]
        cols = {n: batch.column(n).to_pylist() for n in names}
        if chunk.is_static:
            for n in names:
                if ":" in n and cols[n] and cols[n][-1] is not None:
                    static[chunk.entity_path][n] = repr(cols[n][-1])
            continue
        for i in range(batch.num_rows):
            temporal[chunk.entity_path][tuple((n, repr(cols[n][i])) for n in sorted(names)
                                              if cols[n][i] is not None)] += 1
    return temporal, static


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("stream") / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), path)
    return path


@pytest.fixture(scope="module")
def recordings(archive: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, StreamedRecording, float]:
    tmp = tmp_path_factory.mktemp("stream")
    with ArchiveReader(archive) as reader:
        summary = reader.summary()
    end_s = (summary.end_ns - summary.start_ns) / 1e9
    streamed = tmp / "streamed.rrd"
    streamer = StreamedRecording(lambda rid: open_stream(rid, streamed), end_s, every_wall_s=0.0)
    seen = [0]

    def every(collector: ReviewCollector | None, t_s: float) -> None:
        seen[0] += 1
        if seen[0] % EVERY == 0:
            streamer.on_block(collector, t_s)

    outcome = replay_archive(archive, load_config(), write_output=False, review=True, blocks=False, on_block=every)
    streamer.finish(outcome.review)
    assert streamer.rec is not None
    streamer.rec.flush()
    streamer.rec.disconnect()
    bulk = views.save_rrd([outcome.review], tmp / "bulk.rrd")
    return streamed, bulk, streamer, end_s


def test_streamed_recording_holds_the_bulk_recording(recordings: tuple[Path, Path, StreamedRecording, float]) -> None:
    streamed, bulk, streamer, end_s = recordings
    assert streamer.stretches >= 20
    t_s, s_s = _contents(streamed)
    t_b, s_b = _contents(bulk)
    assert set(t_s) == set(t_b)
    assert len(t_b) > 100
    differ = [e for e in t_b if e != SPAN and t_s[e] != t_b[e]]
    assert not differ, differ[:5]
    assert sum(sum(c.values()) for c in t_b.values()) > 50_000
    # the axes' span: the bulk's rows, and the archive's last second sent with the first stretch
    assert t_s[SPAN] - t_b[SPAN] == Counter() or sum((t_s[SPAN] - t_b[SPAN]).values()) <= 2
    assert set(s_s) == set(s_b)
    assert {e: s_s[e] for e in s_b if s_s[e] != s_b[e]} == {}
    assert RrdReader(streamed).recordings()[0].recording_id == RrdReader(bulk).recordings()[0].recording_id


def test_stretches_begin_with_the_first_minute(recordings: tuple[Path, Path, StreamedRecording, float]) -> None:
    streamed, _, _, end_s = recordings
    reader = RrdReader(streamed)
    chunks = [c for c in reader.stream().to_chunks() if not c.is_static]
    # the first temporal rows in the file: the axes' span, then the first stretch's rows, all early in the mission
    first_rows = [c for c in chunks if c.entity_path != SPAN][:20]
    latest = max(max(c.to_record_batch().column("mission_s").to_pylist()) for c in first_rows)
    assert latest < 0.2 * end_s
    span = [c for c in chunks if c.entity_path == SPAN][0].to_record_batch().column("mission_s").to_pylist()
    assert span == [0, round(end_s)]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0.0, 100.0, allow_nan=False), min_size=1, max_size=60),
       st.lists(st.integers(0, 60), max_size=5))
def test_trail_in_stretches_keeps_what_the_whole_keeps(times: list[float], cuts: list[int]) -> None:
    t = np.sort(np.array(times))
    whole = trail_indices(t)
    kept, before = [], None
    edges = sorted({0, t.size, *(min(c, t.size) for c in cuts)})
    for a, b in zip(edges[:-1], edges[1:], strict=False):
        part = t[a:b]
        if not part.size:
            continue
        anchor = float(t[0])
        kept += (a + trail_indices(part, anchor=anchor, after=before)).tolist()
        before = float(np.floor((part[-1] - anchor) / TRAIL_STEP_S))
    assert kept == whole.tolist()


def test_view_streams_a_trial_to_a_running_viewer(archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """`view TRIAL --connect URL` into a Rerun gRPC server on 127.0.0.1 (no viewer, no graphics): the recording
    is saved complete, and the command says when the first stretch went."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    rerun = Path(sys.executable).with_name("rerun")
    server = subprocess.Popen([str(rerun), "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL,
                              start_new_session=True)
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.1)
        out = tmp_path / "live.rrd"
        monkeypatch.delenv("DISPLAY", raising=False)        # --connect alone makes it stream
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        assert main(["view", str(archive), "--connect", f"rerun+http://127.0.0.1:{port}/proxy",
                     "--save", str(out)]) == 0
    finally:
        end_group(server)
    said = capsys.readouterr().out
    assert re.search(r"saved .*live.rrd \(first stretch after [0-9.]+ s, [0-9]+ stretches\)", said), said
    temporal, static = _contents(out)
    assert len(temporal) > 100 and "/mission_span" in temporal
    assert not out.with_name(out.name + ".partial").exists()
