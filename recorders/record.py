"""The recording step: a manifest's logs into one archive, with a summary of what was dropped."""

from __future__ import annotations

import bisect
import copy
import hashlib
import mimetypes
import re
from collections import Counter, deque
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack
from dataclasses import asdict, dataclass, field
from dataclasses import replace as replaced
from functools import partial
from pathlib import Path
from typing import Any, BinaryIO, Protocol

import numpy as np

import formats.log_blocks as log_blocks
from formats import schemas as S
from formats.log_blocks import ChangedWhileRead, LogFiles, blocks_of
from formats.mcap_writer import ArchiveWriter
from formats.proto_encode import encode_columns, encode_flat, split
from formats.records import FormatError, Reject, Where
from formats.units import NS, archivable_ns

from .base import Batch, BlockConverter, Columns, Converter, Ignored, LogContext, Note, Output, SourceBatch
from .clock import date_to_ns, iso_utc, log_offset_ns, offset_problem, shift_text
from .manifest import LogSpec, Manifest, ManifestError
from .output_checks import OutputProblem, check_output
from .record_parallel import (
    Capture,
    Captured,
    WorkerDied,
    WorkerPool,
    available_cores,
    can_fork,
    only_thread,
    write_captured,
)
from .registry import block_converters, converters
from .value_checks import MAX_RANGE_M, ValueChecks

# a log's converter as the recorder calls it: whole bytes, blocks or text in, outputs, rejects and skips out
AnyConverter = Callable[..., Iterator[Output | Reject | Ignored | Batch | SourceBatch]]

Progress = Callable[[str, int, int], None]  # (file, bytes done, bytes total)
# automatic mode decodes in-process below this much input: forking workers and
# shipping results back costs more than it saves on a small trial (see bench/bench_record.py)
AUTO_PARALLEL_MIN_BYTES = 1 << 20
# /diagnostics lines kept in full per log and kind of reject; the rest are counted in one line, so the
# memory and the archive of a log of garbage are bounded by this, not by the log
DIAGNOSTICS_PER_KIND = 100
# between the files of a split log, a gap longer than this many mean message spacings (plus a second, for
# logs that write in bursts) is reported: a file is probably missing
SEAM_GAP_SPACINGS = 10
SEAM_GAP_MIN_NS = NS
# distinct record offsets remembered when counting records parsed: converters yield a record's messages
# together (one record or epoch at a time), so a repeat is never further back than this and memory stays bounded
RECORDS_WINDOW = 4096
_KIND = re.compile(r"[^'\":\d(]*")


class MessageSink(Protocol):
    """Where a log's messages go: the archive itself, or a Capture in a worker process."""

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one message."""

    def channel(self, topic: str, message_class: Any) -> int:
        """Register a topic of protobuf messages of `message_class` (once)."""

    def write_serialized(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one serialized message of a registered topic."""

    def write_serialized_batch(self, topic: str, payloads: Sequence[bytes], log_times_ns: Sequence[int],
                               publish_times_ns: Sequence[int] | None = None) -> None:
        """Append serialized messages of a registered topic, in order."""


@dataclass
class FileStats:
    """What one log file gave: records parsed, skipped, bad checksums, time span, order problems."""

    path: str
    vehicle: str
    sensor: str
    format: str
    size: int = 0
    sha256: str = ""
    parsed: int = 0
    messages: int = 0
    skipped: int = 0
    bad_checksum: int = 0
    out_of_order: int = 0
    duplicates: int = 0
    out_of_range: int = 0   # messages refused for a value out of its range (recorders.value_checks)
    bad_ranges: int = 0     # of those, ranges <= 0 or beyond max_range_m
    start_ns: int | None = None
    end_ns: int | None = None
    ignored: int = 0  # records read whole and deliberately not archived (see `ignored_reasons`)
    ignored_reasons: dict[str, int] = field(default_factory=dict)
    # a rotated or split log's files in log order: path, size, sha256, start_ns, end_ns, gap_s (to the previous)
    parts: list[dict] = field(default_factory=list)
    # about the log as a whole (a gap or overlap between a split log's files); /diagnostics holds rejected records
    notes: list[str] = field(default_factory=list)
    # NMEA: every line by sentence address and outcome ({"GPGSV": {"ignored": 3}, ...}, `formats.nmea.counts`)
    sentences: dict[str, dict[str, int]] = field(default_factory=dict)

    def as_json(self) -> dict:
        """The entry stored in the archive's `recording` metadata (`sentences` only for a log that has them)."""
        out = asdict(self)
        out["start"], out["end"] = iso_utc(self.start_ns), iso_utc(self.end_ns)
        if not self.sentences:
            del out["sentences"]
        return out


@dataclass
class RecordingSummary:
    """Per-file statistics of one recording."""

    files: list[FileStats] = field(default_factory=list)
    workers: int = 1  # processes that decoded the logs (1: in-process)
    removed_parts: list[str] = field(default_factory=list)  # stale part files of dead processes removed

    @property
    def skipped(self) -> int:
        """Records skipped over every file."""
        return sum(f.skipped for f in self.files)


def log_context(manifest: Manifest, log: LogSpec, files: tuple[str, ...] | None = None,
                batches: bool = False) -> LogContext:
    """What a converter knows of one log: its vehicle, clock offset, options and files (default: all of them);
    with `batches`, the converter may give `Batch` items (the recording step takes them)."""
    options = dict(log.options)
    if isinstance(options.get("msg_paths"), list):   # relative to the manifest, like the log's own paths
        options["msg_paths"] = [str(manifest.root / p) for p in options["msg_paths"]]
    return LogContext(
        vehicle=log.vehicle, role=manifest.role_of(log.vehicle), path=log.path, trial_date=manifest.date,
        clock_offset_ns=log_offset_ns(log.time_base, log.start_ns, log.clock_offset_s), time_base=log.time_base,
        prefix=log.prefix, options=options,
        address_book=manifest.address_book(),
        sound_speed_mps=float(options.get("sound_speed_mps", manifest.sound_speed_mps)),
        files=tuple(manifest.root / name for name in (log.files() if files is None else files)),
        batches=batches,
    )


@dataclass(frozen=True)
class Converters:
    """Every (sensor, format)'s converter, and those that also take the log in blocks (bounded memory)."""

    whole: dict
    blocks: dict[tuple[str, str], BlockConverter]

    def streamed(self, log: LogSpec) -> BlockConverter | None:
        """The log's block converter, or None when its converter needs the whole log in memory."""
        return self.blocks.get((log.sensor, log.format))


def read_parts(manifest: Manifest, log: LogSpec) -> list[tuple[str, bytes]]:
    """A log's files and their bytes, in manifest order (one file, or the parts of a rotated log)."""
    return [(name, (manifest.root / name).read_bytes()) for name in log.files()]


def _first_time(convert: AnyConverter, data: bytes, ctx: LogContext) -> float:
    """The earliest message time of one file decoded alone (inf without any), for `order = "time"`."""
    try:
        times = [item.log_time_ns for item in convert(data, ctx) if type(item) is Output]
    except FormatError:
        return float("inf")
    return min(times) if times else float("inf")


def _order_parts(manifest: Manifest, log: LogSpec, parts: list[tuple[str, bytes]],
                 convert: AnyConverter) -> list[tuple[str, bytes]]:
    """The parts in log order: as given, or (order = "time") by the first message time of each decoded alone."""
    if log.order != "time" or len(parts) < 2:
        return parts
    firsts = [_first_time(convert, data, log_context(manifest, log, (name,))) for name, data in parts]
    return [p for _, _, p in sorted(zip(firsts, range(len(parts)), parts))]


def _log_files(manifest: Manifest, names: list[str] | tuple[str, ...]) -> LogFiles:
    paths = [manifest.root / name for name in names]
    return LogFiles(paths, [path.stat().st_size for path in paths])


def _over_one_block(convert: BlockConverter, data: bytes, ctx: LogContext
                    ) -> Iterator[Output | Reject | Ignored | Batch]:
    """A block converter over a log held in memory: the log is its one block (`blocks_of`, no copy)."""
    return convert(blocks_of(data), ctx)


def _reading(manifest: Manifest, log: LogSpec,
             tables: Converters) -> BlockConverter | tuple[Converter, list[tuple[str, bytes]]]:
    """How a log is read: its block converter, when it is read from its files in blocks; else its converter and
    its files' bytes in log order, read whole.

    A block converter's log that fits in one block (log_blocks.BLOCK_BYTES in all) is read whole too, as that
    one block: decoded and attached from the same bytes, it is read and hashed once, no change between two
    reads can go unseen, and a worker hands its bytes back instead of the main process reading them again.
    """
    streamed = tables.streamed(log)
    if streamed is None:
        convert = tables.whole[(log.sensor, log.format)]
        parts = read_parts(manifest, log)
    else:
        files = _log_files(manifest, log.files())
        if files.size > log_blocks.BLOCK_BYTES:  # read when the module is, so that a test may set it smaller
            return streamed
        convert = partial(_over_one_block, streamed)
        try:
            parts = list(zip(log.files(), files.read_whole()))
        except ChangedWhileRead as exc:
            raise ManifestError(f"{log.path}: changed while it was recorded ({exc})") from None
    return convert, _order_parts(manifest, log, parts, convert)


def _first_time_streamed(convert: BlockConverter, manifest: Manifest, log: LogSpec, name: str) -> float:
    """`_first_time` of one file read in blocks."""
    try:
        return min((item.log_time_ns for item in convert(_log_files(manifest, [name]).blocks(),
                                                         log_context(manifest, log, (name,)))
                    if type(item) is Output), default=float("inf"))
    except FormatError:
        return float("inf")


def _ordered_names(manifest: Manifest, log: LogSpec, convert: BlockConverter) -> list[str]:
    """`_order_parts` for a log read in blocks: its file names in log order."""
    names = list(log.files())
    if log.order != "time" or len(names) < 2:
        return names
    firsts = [_first_time_streamed(convert, manifest, log, name) for name in names]
    return [name for _, _, name in sorted(zip(firsts, range(len(names)), names))]


def reject_kind(reason: str) -> str:
    """The kind of a reject, for counting: its reason up to the first quote, colon, digit or parenthesis.

    "bad checksum '00', computed 4A" and "malformed sentence address '..'" are one kind each whatever the
    bytes quoted, so that a log of garbage gives a bounded number of kinds (and of diagnostics listed).
    """
    match = _KIND.match(reason)
    return (match.group() if match else "").strip()[:40]


def _diagnostic(log: LogSpec, reject: Reject, t_ns: int) -> S.Log:
    return S.Log(timestamp=S.timestamp(t_ns), level=S.Log.WARNING, name=log.vehicle, file=log.path,
                 line=reject.where.line or 0,
                 message=f"{log.path} {reject.where.describe()}: {reject.reason}")


class RecordCount:
    """Distinct records (by byte offset) among a log's messages, in memory bounded by RECORDS_WINDOW.

    Exact as long as a record's messages come within RECORDS_WINDOW distinct
    records of each other, as every converter yields them (per record, or per
    epoch as it closes); a set of every offset grew with the log (~80 bytes a record).
    """

    __slots__ = ("count", "last", "seen", "order")

    def __init__(self) -> None:
        self.count = 0
        self.last: int | None = None
        self.seen: set[int] = set()
        self.order: deque[int] = deque()

    def add(self, key: int) -> None:
        """Count `key` unless it is among the last RECORDS_WINDOW distinct ones."""
        self.last = key
        seen = self.seen
        if key in seen:
            return
        seen.add(key)
        order = self.order
        order.append(key)
        self.count += 1
        if len(order) > RECORDS_WINDOW:
            seen.discard(order.popleft())

    def add_many(self, keys: np.ndarray) -> None:
        """`add` of each key in turn but a key equal to the one before it (a record's second message): at once
        when they rise above every key remembered (a log read forward: each one new), else one by one."""
        if not len(keys):
            return
        keys = keys[np.flatnonzero(np.diff(keys, prepend=keys[0] - 1))]
        if int(keys[0]) == self.last:
            keys = keys[1:]
            if not len(keys):
                return
        order, seen = self.order, self.seen
        if (order and int(keys[0]) <= max(order)) or (np.diff(keys) <= 0).any():
            for key in keys.tolist():
                if key != self.last:
                    self.add(key)
            return
        keys = keys.tolist()
        self.count += len(keys)
        self.last = keys[-1]
        order.extend(keys)
        seen.update(keys)
        excess = len(order) - RECORDS_WINDOW
        if excess > RECORDS_WINDOW:  # more gone than kept: the window made again from its last keys
            kept = list(order)[excess:]
            self.order, self.seen = deque(kept), set(kept)
        elif excess > 0:
            seen.difference_update([order.popleft() for _ in range(excess)])


class LogRecorder:
    """Writes one log's outputs and diagnostics, keeping its statistics."""

    def __init__(self, writer: MessageSink, log: LogSpec, stats: FileStats, fallback_ns: int,
                 part_starts: list[int] | None = None):
        self.writer, self.log, self.stats = writer, log, stats
        self.pending: list[Reject] = []  # rejects seen before any time is known
        self.last_ns: dict[str, int] = {}
        self.records = RecordCount()
        self.fallback_ns = fallback_ns
        self.hint_ns: int | None = None  # the earliest own time of a message refused at record time
        self.checks = ValueChecks(float(log.options.get("max_range_m", MAX_RANGE_M)))
        self.kinds: dict[tuple[bool, str], int] = {}  # rejects per kind, listed or not
        self.ignored: Counter[str] = Counter()
        # a split log: the byte offset where each file starts, and each file's message time span
        self.part_starts = part_starts or []
        self.part_spans: list[list[int]] = [[] for _ in self.part_starts]
        # a log put on UTC by the manifest (an offset, or a start): its first time must land in 1980-2100
        self.offset_ns = log_offset_ns(log.time_base, log.start_ns, log.clock_offset_s)
        self.unchecked = bool(shift_text(log.time_base, self.offset_ns))

    def add(self, item: Output | Reject | Ignored | Batch | SourceBatch) -> None:
        if type(item) is not Output:
            if type(item) is Batch:
                self._add_batch(item)
            elif type(item) is Ignored:
                self.ignored[item.reason] += 1
            elif type(item) is Note:
                self.stats.notes.append(item.reason)
            elif type(item) is SourceBatch:
                self._add_source_batch(item)
            else:
                self._reject(item)  # type: ignore[arg-type]
            return
        if self.unchecked:  # before the value checks, which would refuse each message of a log in 2250 alone
            self._check_shift(item.log_time_ns)
        problem = self.checks.problem(item.message, item.log_time_ns)
        if problem is not None:
            # stamped at the message's own time when it has one: a log whose every message is refused must not
            # move its diagnostics to the fallback (the trial date's midnight) and with them the trial's start
            t_hint = item.log_time_ns if archivable_ns(item.log_time_ns) else None
            self._reject(Reject(item.where if item.where is not None else Where(0), problem), t_hint)
            return
        t = item.log_time_ns
        topic = item.topic
        self.writer.write(topic, item.message, t, item.publish_time_ns)
        st = self.stats
        st.messages += 1
        where = item.where
        key = where.offset if where is not None else -st.messages  # no position: one record each
        records = self.records
        if key != records.last:  # not a record's second message (a fix, then its status): no call
            records.add(key)
        prev = self.last_ns.get(topic)
        if prev is None or t > prev:
            self.last_ns[topic] = t
        elif t < prev:
            st.out_of_order += 1
            self.last_ns[topic] = t
        else:
            st.duplicates += 1
        if st.start_ns is None or t < st.start_ns:
            st.start_ns = t
        if st.end_ns is None or t > st.end_ns:
            st.end_ns = t
        if self.part_starts and where is not None:
            span = self.part_spans[bisect.bisect_right(self.part_starts, where.offset) - 1]
            if not span:
                span += [t, t]
            span[0], span[1] = min(span[0], t), max(span[1], t)
        if self.pending:
            self.flush(t)

    def _add_batch(self, batch: Batch) -> None:
        """A block given as columns: checked, encoded and written as its items one by one would be, or those items
        where one of its messages would be refused (or diagnostics wait for a time)."""
        parts, checks = batch.parts, self.checks
        if batch.one_by_one or self.pending or any(checks.refused_rows(p.message_class, len(p.log_times_ns), p.columns,
                                                   p.log_times_ns).any() for p in parts):
            for item in batch.outputs():
                self.add(item)
            return
        for reason, count in batch.ignored.items():
            self.ignored[reason] += count
        order = np.asarray(batch.order, dtype=np.int64)
        n = len(order)
        if not n:
            return
        log_all = np.empty(n, dtype=np.int64)
        for j, p in enumerate(parts):
            log_all[order == j] = p.log_times_ns
        if self.unchecked:
            self._check_shift(int(log_all[0]))
        writer = self.writer
        if not hasattr(writer, "write_blob"):  # a sink that takes messages one by one
            self._write_parts(parts, order, [encode_columns(p.message_class, len(p.log_times_ns), p.columns)
                                             for p in parts])
        else:
            # every part's messages as rows of bytes, put in write order: one blob, one write_blob per stretch
            # between two parts' first messages (a channel is registered there, as write() registers it)
            encoded = [encode_flat(p.message_class, len(p.log_times_ns), p.columns) for p in parts]
            rows = [np.flatnonzero(order == j) for j in range(len(parts))] if len(parts) > 1 else [np.arange(n)]
            flat, lens = encoded[0] if len(parts) == 1 else _interleaved(encoded, rows, n)
            publish_all = np.empty(n, dtype=np.int64)
            for p, mine in zip(parts, rows):
                publish_all[mine] = p.publish_times_ns
            blob, ends = flat.tobytes(), np.cumsum(lens)
            firsts = sorted((int(mine[0]), j) for j, mine in enumerate(rows) if len(mine))
            ids = np.zeros(n, dtype=np.int64)
            for (first, j), stop in zip(firsts, [f for f, _ in firsts[1:]] + [n]):
                ids[rows[j]] = writer.channel(parts[j].topic, parts[j].message_class)
                at = int(ends[first - 1]) if first else 0
                writer.write_blob(ids[first:stop], memoryview(blob)[at:], ends[first:stop] - at, log_all[first:stop],
                                  publish_all[first:stop])
        self._batch_stats(batch.keys, [(p.topic, p.log_times_ns) for p in parts], log_all)

    def _write_parts(self, parts: list[Columns], order: np.ndarray, encoded: list[tuple[bytes, np.ndarray]]) -> None:
        """A batch's encoded parts written in `order`, a run of one topic in one write_serialized_batch."""
        n = len(order)
        payloads = [split(blob, ends) for blob, ends in encoded]
        times = [(np.asarray(p.log_times_ns).tolist(), np.asarray(p.publish_times_ns).tolist()) for p in parts]
        writer, taken, seen = self.writer, [0] * len(parts), [False] * len(parts)
        starts = [0, *(np.flatnonzero(np.diff(order)) + 1).tolist(), n]
        for start, end, j in zip(starts, starts[1:], order[starts[:-1]].tolist()):
            p, k = parts[j], taken[j]
            if not seen[j]:  # registered at its first message, as write() registers it
                writer.channel(p.topic, p.message_class)
                seen[j] = True
            if end - start == 1:  # topics taking turns (a fix, its status): one message, the lighter call
                writer.write_serialized(p.topic, payloads[j][k], times[j][0][k], times[j][1][k])
                taken[j] = k + 1
            else:
                k2 = taken[j] = k + end - start
                writer.write_serialized_batch(p.topic, payloads[j][k:k2], times[j][0][k:k2], times[j][1][k:k2])

    def _batch_stats(self, keys: Sequence[int] | np.ndarray, topic_times: list[tuple[str, Sequence[int] | np.ndarray]],
                     log_all: np.ndarray) -> None:
        """The statistics `add` keeps, for a batch's messages: `keys` their records (byte offsets) and `log_all`
        their log times, both in write order; `topic_times` each topic's log times in order."""
        st = self.stats
        st.messages += len(log_all)
        keys = np.asarray(keys, dtype=np.int64)
        self.records.add_many(keys)
        for topic, times in topic_times:
            t = np.asarray(times, dtype=np.int64)
            if not len(t):
                continue
            prev = self.last_ns.get(topic)
            steps = np.diff(t) if prev is None else np.diff(t, prepend=prev)
            st.out_of_order += int((steps < 0).sum())
            st.duplicates += int((steps == 0).sum())
            self.last_ns[topic] = int(t[-1])
        low, high = int(log_all.min()), int(log_all.max())
        if st.start_ns is None or low < st.start_ns:
            st.start_ns = low
        if st.end_ns is None or high > st.end_ns:
            st.end_ns = high
        if self.part_starts:
            which = np.searchsorted(np.asarray(self.part_starts), keys, side="right") - 1
            for i in np.unique(which).tolist():
                mine = log_all[which == i]
                span = self.part_spans[i]
                if not span:
                    span += [int(mine[0]), int(mine[0])]
                span[0], span[1] = min(span[0], int(mine.min())), max(span[1], int(mine.max()))

    def _add_source_batch(self, batch: SourceBatch) -> None:
        """Source messages of one topic, counted as `add` counts each; written in one call. They carry no values
        to check: only their times (what `ValueChecks.problem` checks of them), message by message when one is
        outside."""
        times = batch.log_times_ns
        write = getattr(self.writer, "write_serialized_batch", None)
        if not times or write is None or self.unchecked or self.pending or not (
                archivable_ns(min(times)) and archivable_ns(max(times))):
            for item in batch.outputs():
                self.add(item)
            return
        self.writer.source_channel(batch.topic, batch.message)   # type: ignore[attr-defined]
        write(batch.topic, batch.payloads, times, batch.publish_times_ns)
        self._batch_stats([w.offset for w in batch.wheres], [(batch.topic, times)], np.asarray(times, dtype=np.int64))

    def _check_shift(self, t_ns: int) -> None:
        """The log's first message time, its offset or start applied, in 1980-2100; else a ManifestError."""
        self.unchecked = False
        problem = offset_problem(t_ns, self.log.time_base, self.offset_ns)
        if problem is not None:
            raise ManifestError(f"{self.log.path}: {problem}")

    def _reject(self, item: Reject, t_hint: int | None = None) -> None:
        self.stats.skipped += 1
        self.stats.bad_checksum += item.bad_checksum
        key = (item.bad_checksum, reject_kind(item.reason))
        n = self.kinds[key] = self.kinds.get(key, 0) + 1
        if n > DIAGNOSTICS_PER_KIND:
            return
        if t_hint is not None and (self.hint_ns is None or t_hint < self.hint_ns):
            self.hint_ns = t_hint
        t = self.stats.end_ns if self.stats.end_ns is not None else t_hint
        if t is None:
            self.pending.append(item)
        else:
            self.writer.write("/diagnostics", _diagnostic(self.log, item, t), t)

    def flush(self, t_ns: int) -> None:
        for reject in self.pending:
            self.writer.write("/diagnostics", _diagnostic(self.log, reject, t_ns), t_ns)
        self.pending.clear()

    def finish(self) -> None:
        # rejects without a time go at the log's first message, else at its earliest refused message's own time
        # (a log whose every message is refused), and only without either at the fallback (the trial date)
        t = self.stats.start_ns if self.stats.start_ns is not None else \
            self.hint_ns if self.hint_ns is not None else self.fallback_ns
        for (bad_checksum, kind), n in self.kinds.items():
            if n > DIAGNOSTICS_PER_KIND:
                what = "bad checksums" if bad_checksum else f"rejects of kind {kind!r}"
                self.pending.append(Reject(Where(0), f"{n - DIAGNOSTICS_PER_KIND} more {what} not listed "
                                                     f"(the first {DIAGNOSTICS_PER_KIND} are)", bad_checksum))
        self.flush(t)
        st = self.stats
        st.parsed = self.records.count
        st.out_of_range, st.bad_ranges = self.checks.out_of_range, self.checks.bad_ranges
        st.ignored = sum(self.ignored.values())
        st.ignored_reasons = dict(self.ignored)
        self._report_seams()

    def _report_seams(self) -> None:
        """Each file's span in the stats; an overlap, or a gap far longer than the log's mean spacing, reported."""
        st = self.stats
        first, last = st.start_ns, st.end_ns
        spacing = (last - first) / max(st.messages - 1, 1) if first is not None and last is not None else 0.0
        previous: list[int] = []
        for part, span in zip(st.parts, self.part_spans):
            part["start_ns"], part["end_ns"] = (span[0], span[1]) if span else (None, None)
            part["start"], part["end"] = iso_utc(part["start_ns"]), iso_utc(part["end_ns"])
            part["gap_s"] = (span[0] - previous[1]) / NS if span and previous else None
            if span and previous:
                gap = span[0] - previous[1]
                if gap < 0:
                    st.notes.append(f"{part['path']} overlaps the file before it by {-gap / NS:.3f} s")
                elif gap > SEAM_GAP_SPACINGS * spacing + SEAM_GAP_MIN_NS:
                    st.notes.append(f"{part['path']}: {gap / NS:.3f} s gap after the file before it")
            if span:
                previous = span


def _interleaved(encoded: list[tuple[np.ndarray, np.ndarray]], rows: list[np.ndarray], n: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Parts' messages (each part's bytes one after the other, and their lengths) put in write order, where
    `rows[j]` are part j's messages' places: one blob and each message's length, by one gather of the bytes."""
    lens = np.empty(n, dtype=np.int64)
    source = np.empty(n, dtype=np.int64)  # each message's start in the parts' blobs end to end
    base = 0
    for (blob, part_lens), mine in zip(encoded, rows):
        lens[mine] = part_lens
        source[mine] = base + np.cumsum(part_lens) - part_lens
        base += len(blob)
    starts = np.cumsum(lens) - lens
    at = np.arange(int(lens.sum()), dtype=np.int64) + np.repeat(source - starts, lens)
    return np.concatenate([blob for blob, _ in encoded])[at], lens


def trial_metadata(manifest: Manifest) -> dict:
    """The archive's "trial" metadata record: name, date, vehicles, modem addresses and the manifest itself."""
    return {
        "name": manifest.name,
        "date": manifest.date.isoformat() if manifest.date else "",
        "vehicles": [{"name": v.name, "role": v.role, "modem_address": v.modem_address} for v in manifest.vehicles],
        "modem_addresses": {str(a): n for a, n in manifest.address_book().items()},
        "manifest": manifest.text,
        "manifest_path": manifest.path.name,
    }


def _iter_outputs(convert: AnyConverter, data: Any, ctx: LogContext,
                  log: LogSpec) -> Iterator[Output | Reject | Ignored | Batch | SourceBatch]:
    try:
        yield from convert(data, ctx)
    except FormatError as exc:
        raise ManifestError(f"{log.path}: {exc}") from exc


def check_formats(manifest: Manifest, table: dict) -> None:
    """Raise ManifestError naming the known formats when a log's (sensor, format) has no converter in `table`."""
    for log in manifest.logs():
        if (log.sensor, log.format) not in table:
            known = sorted(f for s, f in table if s == log.sensor)
            raise ManifestError(f"{manifest.path}: vehicle {log.vehicle!r}, log {log.path}: format {log.format!r} "
                                f"is not a {log.sensor} format; known: {', '.join(known)}")


def _input_bytes(manifest: Manifest) -> int:
    total = 0
    for log in manifest.logs():
        try:
            total += sum((manifest.root / name).stat().st_size for name in log.files())
        except OSError:  # reading it will give the error, in order, as the serial path does
            pass
    return total


def resolve_workers(manifest: Manifest, workers: int | None = None) -> int:
    """How many processes will decode: `workers` (at most one per log), or automatic when None.

    Automatic is in-process for a trial under AUTO_PARALLEL_MIN_BYTES, on one
    core, or when other threads run (a batch's thread pool, say); else one
    process per core: this one and a forked worker for each other core. Where
    processes cannot be forked it is always 1.
    """
    logs = len(manifest.logs())
    if workers is None:
        cores = available_cores()
        if cores < 2 or not only_thread() or _input_bytes(manifest) < AUTO_PARALLEL_MIN_BYTES:
            return 1
        workers = cores
    elif workers < 1:
        raise ValueError(f"workers must be at least 1, not {workers}")
    return max(1, min(workers, logs)) if can_fork() else 1


def _decode_log(manifest: Manifest, log: LogSpec, parts: list[tuple[str, bytes]], convert: AnyConverter, fallback: int,
                sink: MessageSink, progress: Progress | None) -> tuple[FileStats, bytes]:
    """Convert one log's files (already in log order, see `_order_parts`) into `sink`; its statistics and bytes."""
    data = parts[0][1] if len(parts) == 1 else b"".join(d for _, d in parts)
    stats = FileStats(log.path, log.vehicle, log.sensor, log.format, len(data), hashlib.sha256(data).hexdigest())
    starts: list[int] = []
    if log.parts:
        offset = 0
        for name, part in parts:
            stats.parts.append({"path": name, "size": len(part), "sha256": hashlib.sha256(part).hexdigest()})
            starts.append(offset)
            offset += len(part)
    rec = LogRecorder(sink, log, stats, fallback, starts)
    step = max(len(data) // 50, 1 << 16)
    next_report = step
    ctx = replaced(log_context(manifest, log, tuple(n for n, _ in parts), batches=True), source_batches=True)
    for item in _iter_outputs(convert, data, ctx, log):
        rec.add(item)
        if progress is not None and item.where is not None and item.where.offset >= next_report:
            progress(log.path, item.where.offset, len(data))
            next_report = item.where.offset + step
    rec.finish()
    stats.sentences = ctx.counts.as_dict()
    return stats, data


def _decode_streamed(manifest: Manifest, log: LogSpec, names: list[str], convert: BlockConverter, fallback: int,
                     sink: MessageSink, progress: Progress | None) -> FileStats:
    """`_decode_log` of a log read from its files in blocks: one block of it in memory at a time."""
    files = _log_files(manifest, names)
    stats = FileStats(log.path, log.vehicle, log.sensor, log.format, files.size)
    starts: list[int] = []
    if log.parts:
        offset = 0
        for size in files.sizes:
            starts.append(offset)
            offset += size
    rec = LogRecorder(sink, log, stats, fallback, starts)
    step = max(files.size // 50, 1 << 16)
    next_report = step
    ctx = log_context(manifest, log, tuple(names), batches=True)
    try:
        for item in _iter_outputs(convert, files.blocks(), ctx, log):
            rec.add(item)
            if progress is not None and item.where is not None and item.where.offset >= next_report:
                progress(log.path, item.where.offset, files.size)
                next_report = item.where.offset + step
    except ChangedWhileRead as exc:
        raise ManifestError(f"{log.path}: changed while it was recorded ({exc})") from None
    stats.sha256 = files.sha256
    if log.parts:
        stats.parts = [{"path": name, "size": d.size, "sha256": d.sha256} for name, d in zip(names, files.digests)]
    rec.finish()
    stats.sentences = ctx.counts.as_dict()
    return stats


def _decoded_names(log: LogSpec, stats: FileStats) -> list[str]:
    """The files of a decoded log, in the order decoded."""
    return [part["path"] for part in stats.parts] if stats.parts else [log.path]


def _attach_streamed(writer: ArchiveWriter, manifest: Manifest, log: LogSpec, names: list[str],
                     fallback: int) -> list[str]:
    """`_attach` of a log's files read from disk in pieces; their SHA-256s, to check against those decoded."""
    digests = []
    for name in names:
        files = _log_files(manifest, [name])
        media = mimetypes.guess_type(name)[0] or "application/octet-stream"
        try:
            writer.add_attachment_stream(name, files.size, files.pieces(), media, fallback, fallback)
        except ChangedWhileRead as exc:
            raise ManifestError(f"{log.path}: changed while it was recorded ({exc})") from None
        digests.append(files.sha256)
    return digests


def _same_bytes(log: LogSpec, stats: FileStats, attached: list[str]) -> None:
    """Raise ManifestError when the files attached are not the bytes decoded (one changed in between)."""
    decoded = [part["sha256"] for part in stats.parts] if stats.parts else [stats.sha256]
    if decoded != attached:
        raise ManifestError(f"{log.path}: changed while it was recorded (the bytes attached are not those decoded)")


def _record_here(manifest: Manifest, writer: ArchiveWriter, log: LogSpec, tables: Converters, fallback: int,
                 progress: Progress | None) -> FileStats:
    """One log decoded in this process straight into the archive, after its attachment."""
    how = _reading(manifest, log, tables)
    if not isinstance(how, tuple):
        names = _ordered_names(manifest, log, how)
        attached = _attach_streamed(writer, manifest, log, names, fallback)
        stats = _decode_streamed(manifest, log, names, how, fallback, writer, progress)
        _same_bytes(log, stats, attached)
        return stats
    convert, parts = how
    _attach(writer, parts, fallback)
    return _decode_log(manifest, log, parts, convert, fallback, writer, progress)[0]


def _capture(manifest: Manifest, log: LogSpec, tables: Converters, fallback: int) -> Captured:
    """One log decoded and converted, its messages serialized for writing later."""
    sink = Capture()
    how = _reading(manifest, log, tables)
    if not isinstance(how, tuple):  # read again for its attachment by the main process, and checked the same
        stats = _decode_streamed(manifest, log, _ordered_names(manifest, log, how), how, fallback, sink, None)
        return sink.finish(stats)
    convert, parts = how
    stats, data = _decode_log(manifest, log, parts, convert, fallback, sink, None)
    captured = sink.finish(stats)
    # the log's bytes go back with its messages: the attachment is then the very bytes decoded, and the
    # main process neither reads the file again nor hashes it to make sure (one copy each side is cheaper)
    captured.data = data
    return captured


def _capture_log(manifest: Manifest, tables: Converters, fallback: int, index: int) -> Captured:
    """In a worker: one log decoded and converted, its messages serialized for the main process."""
    return _capture(manifest, manifest.logs()[index], tables, fallback)


def _attach(writer: ArchiveWriter, parts: list[tuple[str, bytes]], fallback: int) -> None:
    """The log attached byte for byte: each file of a split log on its own, in log order."""
    for name, data in parts:
        media = mimetypes.guess_type(name)[0] or "application/octet-stream"
        writer.add_attachment(name, data, media, fallback, fallback)


def _attach_captured(writer: ArchiveWriter, manifest: Manifest, log: LogSpec, captured: Captured,
                     fallback: int) -> None:
    """A captured log's attachment: the bytes it came back with, or its files read again and checked the same."""
    if captured.data is None:
        _same_bytes(log, captured.stats, _attach_streamed(writer, manifest, log, _decoded_names(log, captured.stats),
                                                          fallback))
    else:
        _attach(writer, _captured_parts(log, captured), fallback)


def _captured_parts(log: LogSpec, captured: Captured) -> list[tuple[str, bytes]]:
    """A worker's log bytes cut back into its files, by the sizes its statistics give."""
    stats, data = captured.stats, captured.data or b""
    if not stats.parts:
        return [(log.path, data)]
    out, start = [], 0
    for part in stats.parts:
        out.append((part["path"], data[start:start + part["size"]]))
        start += part["size"]
    return out


def _record_serial(manifest: Manifest, writer: ArchiveWriter, tables: Converters, fallback: int,
                   summary: RecordingSummary, progress: Progress | None, reuse: ReusedLogs | None = None) -> None:
    for log in manifest.logs():
        stats = _record_here(manifest, writer, log, tables, fallback, progress) if reuse is None \
            else _record_reused(manifest, writer, log, tables, fallback, progress, reuse)
        summary.files.append(stats)
        if progress is not None:
            progress(log.path, stats.size, stats.size)


ReusedLogs = dict[tuple[str, str, int, tuple[str, ...]], Captured]
"""Logs decoded before, kept by `record(reuse=...)`: (manifest's sha256, log path, fallback time, its files' sha256s)
-> what the log gave. `evaluate`'s drift sweep re-records a seed whose logs are all the same but one."""


def _record_reused(manifest: Manifest, writer: ArchiveWriter, log: LogSpec, tables: Converters, fallback: int,
                   progress: Progress | None, reuse: ReusedLogs) -> FileStats:
    """`_record_here` of a log read whole, through `reuse`: a log of the same bytes under the same manifest is
    written from what it gave before (the archive is the same bytes: `write_captured`, as with workers)."""
    how = _reading(manifest, log, tables)
    if not isinstance(how, tuple):
        return _record_here(manifest, writer, log, tables, fallback, progress)
    convert, parts = how
    key = (hashlib.sha256(manifest.path.read_bytes()).hexdigest(), log.path, fallback,
           tuple(hashlib.sha256(data).hexdigest() for _, data in parts))
    captured = reuse.get(key)
    if captured is None:
        sink = Capture()
        stats, _ = _decode_log(manifest, log, parts, convert, fallback, sink, progress)
        captured = reuse[key] = sink.finish(stats)
    _attach(writer, parts, fallback)
    write_captured(writer, captured)
    return copy.deepcopy(captured.stats)


def _record_parallel(manifest: Manifest, writer: ArchiveWriter, pool: WorkerPool[Captured], tables: Converters,
                     fallback: int, summary: RecordingSummary, progress: Progress | None) -> None:
    logs = manifest.logs()
    # later logs this process captured while a worker still held an earlier one, or the error that gave
    own: dict[int, Captured | Exception] = {}
    for i, log in enumerate(logs):
        captured = own.pop(i, None)
        if isinstance(captured, Exception):
            raise captured  # at its log's turn, so that an earlier log's error comes first, as in the serial path
        if captured is None:
            try:
                captured = _next_captured(manifest, writer, pool, tables, fallback, summary, progress, own, i)
            except WorkerDied as exc:
                what = f"{logs[exc.task].path}: the worker process decoding it" if exc.task is not None \
                    else "a worker process decoding the logs"
                raise ManifestError(f"{what} {exc.how}") from None
        if captured is not None:
            _attach_captured(writer, manifest, log, captured, fallback)
            write_captured(writer, captured)
            summary.files.append(captured.stats)
        if progress is not None:
            size = summary.files[-1].size
            progress(log.path, size, size)


def _next_captured(manifest: Manifest, writer: ArchiveWriter, pool: WorkerPool[Captured], tables: Converters,
                   fallback: int, summary: RecordingSummary, progress: Progress | None,
                   own: dict[int, Captured | Exception], i: int) -> Captured | None:
    """Log `i` as a worker captured it, or None once this process has recorded it straight into the archive."""
    while not pool.ready(i):
        task = pool.claim()
        if task is None:  # every log is taken: log i is a worker's, wait for it
            break
        log = manifest.logs()[task]
        if task == i:  # nobody had it: decode it here as the serial path does, no copy, no replay
            summary.files.append(_record_here(manifest, writer, log, tables, fallback, progress))
            return None
        try:  # a later log, while a worker holds log i
            own[task] = _capture(manifest, log, tables, fallback)
        except Exception as exc:  # noqa: BLE001 - raised at its turn
            own[task] = exc
    return pool.result(i)


def record(manifest: Manifest, output_path: str | Path | BinaryIO, progress: Progress | None = None,
           workers: int | None = None, replace: bool = True, reuse: ReusedLogs | None = None) -> RecordingSummary:
    """Record every log of the manifest into `output_path`; returns the per-file summary.

    `workers` processes decode the logs (None: automatic, see `resolve_workers`);
    the archive is byte-for-byte the same whatever their number. The output is
    never one of the inputs nor an existing file other than an MCAP archive,
    and an existing archive only with `replace` (see recorders.output_checks);
    a second process writing the same output at the same time is refused
    (formats.output_files); the part file is removed on any failure, and stale
    ones of dead processes before the start. A binary stream (`io.BytesIO`) as
    the output gets the same bytes, and is left open. With `reuse` (one process),
    a log seen before in it is not decoded again (`ReusedLogs`): the same bytes.
    """
    output = Path(output_path) if isinstance(output_path, (str, Path)) else output_path
    try:
        if isinstance(output, Path):
            check_output(output, [manifest.path, *(manifest.root / log.path for log in manifest.logs())], replace)
    except OutputProblem as exc:
        raise ManifestError(str(exc)) from None
    tables = Converters(converters(), block_converters())
    check_formats(manifest, tables.whole)
    live = next((log for log in manifest.logs() if log.source), None)
    if live is not None:
        raise ManifestError(f"{manifest.path}: log {live.path} is a live source ({live.source}): "
                            "use `auvreplay capture`")
    summary = RecordingSummary(workers=1 if reuse is not None else resolve_workers(manifest, workers))
    fallback = date_to_ns(manifest.date) if manifest.date else 0
    writer: ArchiveWriter | None = None
    try:
        with ExitStack() as stack:
            pool = None
            if summary.workers > 1:
                # forked before the writer opens its file, so no worker holds it; this process is one of the
                # decoding processes and starts on the first log while the workers start
                pool = stack.enter_context(WorkerPool(partial(_capture_log, manifest, tables, fallback),
                                                      len(manifest.logs()), summary.workers - 1, caller_first=True))
            # claimed here, atomically: a second run on the same output at once is refused, and without
            # `replace` so is an archive that appeared since check_output
            writer = stack.enter_context(ArchiveWriter(output, replace=replace))
            summary.removed_parts = [str(p) for p in writer.removed_parts]
            # first, so that an archive cut off mid-write still says who is who
            writer.add_metadata("trial", trial_metadata(manifest))
            if pool is None:
                _record_serial(manifest, writer, tables, fallback, summary, progress, reuse)
            else:
                _record_parallel(manifest, writer, pool, tables, fallback, summary, progress)
            writer.add_metadata("recording", {"files": [f.as_json() for f in summary.files]})
    except BaseException:
        # the writer drops its part file on an error inside; this also covers a failed final rename
        if writer is not None and isinstance(output, Path):
            writer.temp_path.unlink(missing_ok=True)
        raise
    return summary

