"""Recording throughput: `recorders.record.record`, serial and with worker processes, against the bare mcap writer.

Records a trial (default: the bundled samples/lake_trial, every vehicle's GPS,
INS, DVL, modem and USBL logs) with `record()`, the whole step: reading the
logs, decoding, converting, writing messages, diagnostics, attachments and
metadata. The comparators write the very messages that recording produced,
already encoded, with the same attachments (every original log) and metadata:

  bare mcap writer   mcap.writer.Writer.add_message (zstd chunks, CRCs), the
                     library's own per-message path with no decoding at all
  ours, bytes in     formats.mcap_writer.ArchiveWriter.write_serialized, the
                     same job through our writer

`record()` runs twice per round: in-process (workers=1) and with N decoding
processes, the main process and N - 1 forked workers taking the logs in
manifest order while the main process writes (default: as many as the
automatic mode picks, at least 2; --workers N to choose); the two archives
are checked to be byte-identical.

Ratios are against the bare writer (goal for recording: >= 50 %), and the
parallel row also against the serial one. Timings are medians of interleaved
rounds (one of each per round), so a load change on the shared machine hits
all four alike. Beside the wall time, each row's CPU time (getrusage: this
process, and the forked workers once they are reaped) says what the work
costs whatever else runs: under load, wall ratios move with the load from
round to round, CPU figures much less; the parallel row splits it into the
main process's and the workers'.

With --timeline, one more record(workers=N) is traced: when each log's
decode starts and ends in which process, when the main process writes, waits
for a worker or takes a result over, and how long forking, closing the
archive and stopping the workers take (the trace's own cost, a few us an
event, is in the figures).

Run: .venv/bin/python bench/bench_record.py [--manifest PATH] [--repeats N] [--workers N] [--timeline]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import resource
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from common import print_table
from mcap.reader import SeekingReader
from mcap.writer import CompressionType, Writer

import recorders.record as recording
import recorders.record_parallel as parallel_recording
from formats.mcap_writer import ArchiveWriter
from formats.schemas import MESSAGE_CLASSES
from recorders.manifest import load_manifest
from recorders.record import record, resolve_workers
from recorders.record_parallel import available_cores

Recorded = tuple[list, list, list, list]  # messages, channels, attachments, metadata


def recorded_content(path: Path) -> Recorded:
    """What an archive holds, in file order: raw messages, channels with schemas, attachments, metadata."""
    with open(path, "rb") as f:
        reader = SeekingReader(f)
        raw = [(c.topic, m.data, m.log_time, m.publish_time) for _, c, m in reader.iter_messages(log_time_order=False)]
        summary = reader.get_summary()
        channels = [(c.topic, summary.schemas[c.schema_id]) for c in summary.channels.values()]
        attachments = [(a.name, a.media_type, a.data, a.log_time, a.create_time) for a in reader.iter_attachments()]
        metadata = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
    return raw, channels, attachments, metadata


def write_bare(path: Path, content: Recorded) -> None:
    """The recorded messages, attachments and metadata through mcap's own writer."""
    raw, channels, attachments, metadata = content
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, enable_crcs=True, enable_data_crcs=True)
        w.start(profile="", library="bench")
        schema_ids: dict[str, int] = {}
        ids = {}
        for topic, schema in channels:
            if schema.name not in schema_ids:
                schema_ids[schema.name] = w.register_schema(schema.name, schema.encoding, schema.data)
            ids[topic] = w.register_channel(topic, "protobuf", schema_ids[schema.name])
        for name, media, data, log_time, create_time in attachments:
            w.add_attachment(create_time, log_time, name, media, data)
        for topic, data, log_time, publish_time in raw:
            w.add_message(ids[topic], log_time, data, publish_time)
        for name, values in metadata:
            w.add_metadata(name, values)
        w.finish()


def write_ours_bytes(path: Path, content: Recorded, classes: dict[str, type]) -> None:
    """The same job through ArchiveWriter.write_serialized."""
    raw, channels, attachments, metadata = content
    with ArchiveWriter(path) as w:
        for topic, schema in channels:
            w.channel(topic, classes[schema.name])
        for name, media, data, log_time, create_time in attachments:
            w.add_attachment(name, data, media, log_time, create_time)
        for topic, data, log_time, publish_time in raw:
            w.write_serialized(topic, data, log_time, publish_time)
        for name, values in metadata:
            w.add_metadata(name, values)




def _log_path(at: int) -> Callable[[tuple], str]:
    return lambda args: args[at].path


def _part_names(args: tuple) -> str:
    return " ".join(name for name, _ in args[1])


def _cpu(who: int) -> float:
    use = resource.getrusage(who)
    return use.ru_utime + use.ru_stime


def interleaved_cpu(fns: dict[str, Callable[[], object]], repeats: int) -> dict[str, tuple[float, float, float]]:
    """Per function, medians over `repeats` interleaved rounds of (wall s, CPU s of this process, of its children)."""
    times: dict[str, list[tuple[float, float, float]]] = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            start, own, kids = time.perf_counter(), _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN)
            fn()
            times[name].append((time.perf_counter() - start, _cpu(resource.RUSAGE_SELF) - own,
                                _cpu(resource.RUSAGE_CHILDREN) - kids))
    return {name: (statistics.median(t[0] for t in ts), statistics.median(t[1] for t in ts),
                   statistics.median(t[2] for t in ts)) for name, ts in times.items()}


# (module, attribute, label, what the step was about from its arguments, or None): the traced steps
TRACED: list[tuple[Any, str, str, Callable[[tuple], str] | None]] = [
    (recording, "_decode_log", "decode", _log_path(1)),
    (recording, "_decode_streamed", "decode in blocks", _log_path(1)),
    (recording, "_attach", "attach", _part_names),
    (recording, "_attach_streamed", "attach from file", _log_path(2)),
    (recording, "write_captured", "write captured", None),
    (parallel_recording.WorkerPool, "__init__", "fork workers", None),
    (parallel_recording.WorkerPool, "result", "wait for worker", lambda args: str(args[1])),
    (parallel_recording.WorkerPool, "close", "stop workers", None),
    (parallel_recording, "_hand_over", "hand over", lambda args: str(args[1])),
    (parallel_recording, "_take_over", "take over", None),
    (ArchiveWriter, "close", "close archive", None),
]


@contextlib.contextmanager
def traced(events_path: Path) -> Iterator[None]:
    """Every TRACED step logs (process, start, end, CPU, label) to `events_path`, from whichever process runs it."""
    # one O_APPEND descriptor inherited by the forks: each line is one write(), whole under PIPE_BUF
    fd = os.open(events_path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_TRUNC)

    def wrap(real: Callable, label: str, describe: Callable[[tuple], str] | None) -> Callable:
        def step(*args: Any, **kwargs: Any) -> Any:
            what = "" if describe is None else describe(args)
            start, cpu = time.perf_counter(), time.process_time()
            try:
                return real(*args, **kwargs)
            finally:
                os.write(fd, f"{os.getpid()}\t{start}\t{time.perf_counter()}\t"
                             f"{time.process_time() - cpu}\t{label}\t{what}\n".encode())
        return step

    saved = [(owner, attr, getattr(owner, attr)) for owner, attr, _, _ in TRACED]
    try:
        for (owner, attr, label, describe), (_, _, real) in zip(TRACED, saved):
            setattr(owner, attr, wrap(real, label, describe))
        yield
    finally:
        for owner, attr, real in saved:
            setattr(owner, attr, real)
        os.close(fd)


def print_timeline(manifest: Any, out: Path, workers: int, events_path: Path) -> None:
    """One traced record(): each process's steps in time order, then the time each kind of step took."""
    start = time.perf_counter()
    with traced(events_path):
        record(manifest, out, workers=workers)
    wall = time.perf_counter() - start
    rows = []
    for line in events_path.read_text().splitlines():
        pid, t0, t1, cpu, label, what = line.split("\t")
        rows.append((int(pid), float(t0) - start, float(t1) - start, float(cpu), label, what))
    names = {os.getpid(): "main"}
    for pid in sorted({r[0] for r in rows} - {os.getpid()}, key=lambda p: min(r[1] for r in rows if r[0] == p)):
        names[pid] = f"worker {len(names)}"
    print(f"\nTimeline of record(workers={workers}), {1000 * wall:.1f} ms (ms from the call; cpu of the step)")
    totals: dict[tuple[str, str], list[float]] = defaultdict(lambda: [0.0, 0.0, 0])  # wall, cpu, count
    for pid in names:
        print(f"  {names[pid]}")
        for _, t0, t1, cpu, label, what in sorted(r for r in rows if r[0] == pid):
            print(f"    {1000 * t0:7.1f} {1000 * t1:7.1f}  {1000 * (t1 - t0):6.1f} "
                  f"cpu {1000 * cpu:6.1f}  {label} {what}")
            total = totals[(names[pid], label)]
            total[0] += t1 - t0
            total[1] += cpu
            total[2] += 1
        steps = [r for r in rows if r[0] == pid]
        if steps and pid != os.getpid():  # a worker's idle time: between its first and last step, not in one
            busy = sum(r[2] - r[1] for r in steps)
            span = max(r[2] for r in steps) - min(r[1] for r in steps)
            print(f"    busy {1000 * busy:.1f} ms of {1000 * span:.1f}")
    print("  totals")
    for (who, name), (secs, cpu, count) in sorted(totals.items()):
        print(f"    {who:9s} {name:16s} {count:3d}x  {1000 * secs:7.1f} ms  cpu {1000 * cpu:7.1f} ms")


def main(argv: list[str] | None = None) -> int:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--manifest", type=Path, default=ROOT / "samples" / "lake_trial" / "trial.toml")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--workers", type=int, default=None,
                        help="decoding processes of the parallel row (the main one included)")
    parser.add_argument("--timeline", action="store_true", help="then trace one record(workers=N) and print it")
    args = parser.parse_args(argv)
    manifest = load_manifest(args.manifest)
    workers = resolve_workers(manifest, args.workers or max(2, resolve_workers(manifest)))
    with tempfile.TemporaryDirectory() as tmp:
        ours, bare, ours_bytes = Path(tmp) / "ours.mcap", Path(tmp) / "bare.mcap", Path(tmp) / "bytes.mcap"
        parallel = Path(tmp) / "parallel.mcap"
        record(manifest, ours, workers=1)
        content = recorded_content(ours)
        n = len(content[0])
        measured = interleaved_cpu({
            "bare": lambda: write_bare(bare, content),
            "bytes": lambda: write_ours_bytes(ours_bytes, content, MESSAGE_CLASSES),
            "record": lambda: record(manifest, ours, workers=1),
            "parallel": lambda: record(manifest, parallel, workers=workers),
        }, args.repeats)
        t = {name: wall for name, (wall, _, _) in measured.items()}
        cpu = {name: own + kids for name, (_, own, kids) in measured.items()}
        size = ours.stat().st_size
        if parallel.read_bytes() != ours.read_bytes():
            raise SystemExit("the parallel archive differs from the serial one")
        logs = sum(len(c[2]) for c in content[2])
    print_table(
        f"Recording {args.manifest.parent.name}: {n:,} messages from {len(content[2])} logs ({logs / 1e6:.1f} MB), "
        f"archive {size / 1e6:.1f} MB, median of {args.repeats} interleaved rounds",
        ["what", "seconds", "msgs/s", "ratio to bare", "CPU s", "CPU ratio to bare"],
        [[what, t[name], n / t[name], t["bare"] / t[name], cpu[name], cpu["bare"] / cpu[name]] for what, name in (
            ("bare mcap writer, pre-encoded messages + attachments", "bare"),
            ("ours: ArchiveWriter.write_serialized, same bytes", "bytes"),
            ("ours: record() from the logs, in-process (workers=1)", "record"),
            (f"ours: record(workers={workers}): main + {workers - 1} forked", "parallel"))],
    )
    _, main_cpu, workers_cpu = measured["parallel"]
    print(f"  record(workers={workers}) CPU: main process {main_cpu:.3f} s, workers {workers_cpu:.3f} s "
          f"(in-process record() {cpu['record']:.3f} s)")
    print(f"  workers {workers}, cores available {available_cores()} (os.cpu_count() {os.cpu_count()}); "
          f"parallel is {t['record'] / t['parallel']:.2f}x the in-process record(), archives byte-identical")
    ratio = t["bare"] / min(t["record"], t["parallel"])
    print(f"  recording goal: >= 50 % of bare -> {'met' if ratio >= 0.5 else 'NOT met'} ({100 * ratio:.0f} %, "
          f"best of the two record() rows)")
    if args.timeline:
        with tempfile.TemporaryDirectory() as tmp:
            print_timeline(manifest, Path(tmp) / "traced.mcap", workers, Path(tmp) / "events.tsv")
    return 0


if __name__ == "__main__":
    sys.exit(main())
