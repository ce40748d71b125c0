"""Archives in memory: written into a BytesIO, recorded into one and read or replayed from bytes, as files are.

`evaluate` records each simulated trial into memory and replays it from its bytes (no archive written), and
records one seed's sweep trials together, decoding a log of the same bytes once (`record(reuse=...)`). Each
of those is judged here against the file path byte for byte: the archive, what the reader gives, the replay.
"""

from __future__ import annotations

import io
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from formats.records import FormatError
from recorders.manifest import load_manifest
from recorders.record import ReusedLogs, record
from replay.run import evaluate as ev
from replay.run.config import load_config
from replay.run.evaluate import TrialSpec, same_seed
from replay.run.pipeline import replay_archive
from samples.scenario import Scenario
from samples.simulator import simulate_trial
from samples.writer import log_files, same_inputs, write_trial

T0 = 1_700_000_000 * 10**9
DURATION_S = 240.0


def _write(target: Path | io.BytesIO, times: list[int], chunk_size: int) -> None:
    """Messages on two topics at the given times, metadata and an attachment, into a path or a stream."""
    with ArchiveWriter(target, chunk_size=chunk_size) as w:
        w.add_metadata("trial", {"name": "t", "n": len(times)})
        for i, t in enumerate(times):
            if i % 3:
                w.write("/a/gps", S.location_fix(t, "a", 45.0 + i * 1e-6, 126.0, float(i),
                                                 (1.0, 0, 0, 0, 1.0, 0, 0, 0, 4.0), 2), t)
            else:
                w.write("/b/gps/status", S.GnssStatus(timestamp=S.timestamp(t), frame_id="b", satellites=i % 30), t)
        w.add_attachment("a/gps.log", b"$GPGGA,1*00\r\n" * (len(times) + 1), "text/plain", T0, T0)


def _read(reader: ArchiveReader) -> tuple[object, ...]:
    s = reader.summary()
    return (s.message_count, s.start_ns, s.end_ns, s.topics, reader.metadata_json("trial"),
            [(m.topic, m.log_time_ns, m.message.SerializeToString()) for m in reader.messages()],
            [(a.name, a.data) for a in reader.attachments()], reader.problems)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(0, 10**12), min_size=0, max_size=300), st.sampled_from([512, 4096, 1 << 20]))
def test_a_stream_gets_the_file_bytes_and_reads_back_as_the_file(tmp_path_factory: pytest.TempPathFactory,
                                                                 offsets: list[int], chunk_size: int) -> None:
    path = tmp_path_factory.mktemp("mem") / "a.mcap"
    times = [T0 + o for o in offsets]
    _write(path, times, chunk_size)
    buffer = io.BytesIO()
    _write(buffer, times, chunk_size)
    assert not buffer.closed                      # the caller's stream stays open, holding the archive
    data = buffer.getvalue()
    assert data == path.read_bytes()
    with ArchiveReader(data) as mem, ArchiveReader(path) as disk:
        assert _read(mem) == _read(disk)
        assert mem.path == Path("<bytes>")


def test_bytes_that_are_no_archive_are_refused_in_one_line() -> None:
    with pytest.raises(FormatError, match="empty"):
        ArchiveReader(b"")
    with pytest.raises(FormatError, match="no MCAP magic"):
        ArchiveReader(b"not an archive at all")


def test_a_failed_write_leaves_the_stream_to_its_owner() -> None:
    buffer = io.BytesIO()
    with pytest.raises(RuntimeError), ArchiveWriter(buffer) as w:
        w.add_metadata("trial", {"name": "t"})
        raise RuntimeError("stop")
    assert not buffer.closed and buffer.getvalue()[:8] == b"\x89MCAP0\r\n"


def _trial_dir(root: Path, drift_rate: float | None, seed: int = 7) -> Path:
    trial = simulate_trial(TrialSpec(seed, drift_rate, DURATION_S).scenario(), seed)
    write_trial(trial, root, logs_only=True)
    return root / "trial.toml"


def test_recorded_into_memory_and_with_reused_logs_the_archive_is_the_files(tmp_path: Path) -> None:
    """A seed's sweep: the archive recorded into memory, with the logs of the trials before reused, is the
    archive `record` writes to a file alone; only the logs that changed are decoded again."""
    reuse: ReusedLogs = {}
    seen: set[tuple[str, bytes]] = set()
    for k, rate in enumerate((None, 0.3, 0.5)):
        manifest = load_manifest(_trial_dir(tmp_path / f"t{k}", rate))
        seen |= {(log.path, (manifest.root / log.path).read_bytes()) for log in manifest.logs()}
        record(manifest, tmp_path / f"t{k}.mcap", workers=1)
        plain, reused = io.BytesIO(), io.BytesIO()
        summary = record(manifest, plain, workers=1)
        again = record(manifest, reused, reuse=reuse)
        on_disk = (tmp_path / f"t{k}.mcap").read_bytes()
        assert plain.getvalue() == on_disk and reused.getvalue() == on_disk
        assert [f.as_json() for f in again.files] == [f.as_json() for f in summary.files]
        # a log is decoded once per bytes it had: a drift rate changes the follower's acoustic log only
        assert len(reuse) == len(seen) <= len(manifest.logs()) + k


def test_replayed_from_bytes_is_replayed_from_the_file(tmp_path: Path) -> None:
    manifest = load_manifest(_trial_dir(tmp_path / "t", None))
    record(manifest, tmp_path / "t.mcap", workers=1)
    data = (tmp_path / "t.mcap").read_bytes()
    config = load_config(None, ["training_window_s=120", "methods=ackf,chi_square"])
    disk = replay_archive(tmp_path / "t.mcap", config, write_output=False)
    mem = replay_archive(data, config, write_output=False)
    lean = replay_archive(data, config, write_output=False, nav_review=False)
    assert disk.run_id == mem.run_id == lean.run_id
    for a in (mem, lean):
        assert a.messages == disk.messages and a.notes == disk.notes
        want = {k: v for k, v in disk.metrics.items() if k not in ("wall_s", "navigation")}
        assert {k: v for k, v in a.metrics.items() if k not in ("wall_s", "navigation")} == want
    assert mem.metrics["navigation"] == disk.metrics["navigation"] and disk.metrics["navigation"]
    assert lean.metrics["navigation"] == {}
    with pytest.raises(ValueError, match="bytes"):
        replay_archive(data, config)                # bytes have no name to write results next to


def test_a_seeds_trials_are_grouped_and_prepared_together_as_alone() -> None:
    base = Scenario()
    other = replace(base, trial=replace(base.trial, name="other"))
    specs = [TrialSpec(1, None, DURATION_S), TrialSpec(2, None, DURATION_S), TrialSpec(1, 0.3, DURATION_S),
             TrialSpec(1, 0.3, DURATION_S, other), TrialSpec(2, 0.5, DURATION_S), TrialSpec(1, 0.5, 200.0)]
    assert same_seed(specs) == [[0, 2], [1, 4], [3], [5]]
    together = ev.prepare_trials([specs[0], specs[2]])
    for p, spec in zip(together, (specs[0], specs[2])):
        alone = ev.prepare_trial(spec)
        assert p.spec == spec and p.archive == alone.archive and p.offset_s == alone.offset_s


def test_a_sweep_trial_takes_only_the_logs_whose_inputs_are_the_same() -> None:
    """`log_files(like=...)` gives the trial's own files byte for byte, sharing what a drift rate leaves."""
    first = simulate_trial(TrialSpec(3, None, DURATION_S).scenario(), 3)
    files = log_files(first)
    for rate in (0.2, 1.0):
        trial = simulate_trial(TrialSpec(3, rate, DURATION_S).scenario(), 3)
        shared = log_files(trial, (first, files))
        assert shared == log_files(trial)
        assert {"vehicles", "buoys", "usbl"} <= same_inputs(trial, first)
        taken = [rel for rel in shared if shared[rel] is files[rel]]
        assert "follower/gps.log" in taken and "buoy1/usbl.log" in taken
    other = simulate_trial(TrialSpec(4, None, DURATION_S).scenario(), 4)    # another seed: nothing in common
    assert same_inputs(other, first) == set()
    assert not [rel for rel, data in log_files(other, (first, files)).items() if data is files[rel] and
                rel != "trial.toml"]


def test_interleaved_channels_in_one_call_write_the_bytes_of_one_by_one(tmp_path: Path) -> None:
    rows = [(i % 3, f"m{i}".encode() * (i % 7 + 1), T0 + i * 10, T0 + i * 10 + 3) for i in range(900)]
    out = []
    for mixed in (False, True):
        buffer = io.BytesIO()
        with ArchiveWriter(buffer, chunk_size=700) as w:
            ids = [w.channel(f"/v{k}/gps", S.LocationFix) for k in range(3)]
            if mixed:
                payloads = [r[1] for r in rows]
                w.write_blob(np.array([ids[k] for k, *_ in rows]), b"".join(payloads),
                             np.cumsum([len(d) for d in payloads]), np.array([r[2] for r in rows]),
                             np.array([r[3] for r in rows]))
            else:
                for k, data, lt, pt in rows:
                    w.write_serialized(ids[k], data, lt, pt)
            with pytest.raises(KeyError):
                w.write_blob(np.array([99]), b"", np.array([0]), np.array([T0]), np.array([T0]))
        out.append(buffer.getvalue())
    assert out[0] == out[1]
