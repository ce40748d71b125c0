"""The capture loop: every live log of a manifest read as it arrives, archived raw and decoded, crash-safe.

The archive grows as TRIAL.mcap.part: each read's bytes go in as an
`auvreplay.RawBytes` message stamped with the receive time (ns UTC), and
the stream goes through the log's converter (`decoder.StreamDecoder`) into
the same messages, statistics and diagnostics `record` writes. At least
every `flush_s` the open chunk is closed, written and fsync'd, so a crash
or a power cut loses at most that interval (`auvreplay recover` salvages
the rest). A clean stop reads what the sources still hold (a growing file
up to its size at the stop), decodes what is left, writes the summary and
renames the file to its final name.

Nothing here waits on one source: every source is opened without blocking
(or its open is retried by the loop), a listener's clients are waited on
side by side, and each turn of the loop is bounded, so a stop request is
seen within a turn. When the disk fills (or any write fails) capture stops
with `CaptureStopped`, one line, and the part file stays for `recover`:
what was captured is never deleted.
"""

from __future__ import annotations

import hashlib
import os
import selectors
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from formats import schemas as S
from formats.mcap_writer import ArchiveWriter
from formats.records import Reject

from ..attachments import RAW_PREFIX
from ..base import Output
from ..clock import date_to_ns
from ..manifest import LogSpec, Manifest, ManifestError
from ..manifest_checks import ValueProblem, check_log_paths
from ..record import (
    FileStats,
    LogRecorder,
    RecordingSummary,
    check_formats,
    log_context,
    trial_metadata,
)
from ..registry import converters
from .base import PeerClosed, Source, SourceClosed, SourceError
from .decoder import StreamDecoder
from .sources import make_source
from .status import SourceStatus
from .tail import TailSource

Listener = Callable[[LogSpec, list[Output]], None]
Reporter = Callable[[str], None]
RETRY_MAX_S = 5.0
# a growing file is read until it has nothing new, up to this much per turn of the loop, so that a fast
# writer is kept up with (20 MB/s and more) and the other sources still get their turn
POLL_BUDGET = 8 << 20
# a file is not read further while this much of it waits to be decoded (it waits on disk instead); a socket's
# bytes over it are archived and not decoded live (StreamDecoder.shed)
MAX_BACKLOG = 64 << 20
# decoding is done in slices of about DECODE_SLICE bytes, for at most DECODE_TURN_S a turn, so that
# reading (the archive: nothing lost) never waits on a converter slower than the stream; a clean stop
# decodes whatever is left
DECODE_SLICE = 128 << 10
DECODE_TURN_S = 0.05


class CaptureStopped(OSError):
    """Capture cannot go on writing (a full disk): the part file keeps what was captured, for `recover`."""


@dataclass(frozen=True)
class CaptureOptions:
    """How often to flush (s), when to stop, when a source counts as quiet, how often to decode."""

    flush_s: float = 1.0
    duration_s: float | None = None
    quiet_s: float = 5.0
    decode_s: float = 0.05
    retry_s: float = 0.25


@dataclass
class CaptureSummary:
    """What a capture wrote: the archive, per-log statistics (as `record`'s) and per-source counters."""

    path: Path
    recording: RecordingSummary
    sources: list[SourceStatus] = field(default_factory=list)


def part_path(output: Path) -> Path:
    """Where a capture into `output` grows until it stops cleanly."""
    return output.with_name(output.name + ".part")


def raw_topic(log: LogSpec) -> str:
    """The topic of a live log's raw bytes."""
    return RAW_PREFIX + log.path


class _Live:
    """One live log: its source, decoder, statistics and counters."""

    def __init__(self, log: LogSpec, source: Source, decoder: StreamDecoder, stats: FileStats):
        self.log, self.source, self.decoder, self.stats = log, source, decoder, stats
        self.recorder: LogRecorder | None = None
        self.status = SourceStatus(log.path, log.source)
        self.topic = raw_topic(log)
        self.sha = hashlib.sha256()
        self.is_open = False
        self.retry_at = 0.0
        self.backoff = 0.0
        self.fds: set[int] = set()         # registered with the selector
        self.peers: dict[int, int] = {}    # a source's peer -> its connection number in the archive
        self.dropped_lines = False         # an overlong line was reported once
        self.shed = False                  # a backlog given up by the live decode was reported once


def _prepare(manifest: Manifest, allow_outside: bool = False) -> list[_Live]:
    """A source, decoder and statistics per log; every problem a ManifestError before anything is opened.

    A `tail:` path is relative to the manifest's folder, and inside it (the rule `record` applies to log
    paths) unless `allow_outside`.
    """
    table = converters()
    check_formats(manifest, table)
    out = []
    for log in manifest.logs():
        if not log.source:
            raise ManifestError(f"{manifest.path}: log {log.path} has a path but no live source: give it "
                                "source = \"udp://HOST:PORT\" (or record the files with `auvreplay record`)")
        try:
            source = make_source(log.source)
        except SourceError as exc:
            raise ManifestError(f"{manifest.path}: vehicle {log.vehicle!r}, log {log.path}: {exc}") from None
        if isinstance(source, TailSource):
            try:
                check_log_paths(manifest.root, [source.path], f"{manifest.path}: vehicle {log.vehicle!r}, "
                                f"source {log.source}", allow_outside)
            except ValueProblem as exc:
                raise ManifestError(str(exc)) from None
            source.path = os.path.join(manifest.root, source.path)
        convert = table[(log.sensor, log.format)]
        ctx = log_context(manifest, log)
        try:
            list(convert(b"", ctx))  # bad format options fail now, not at the first byte
        except ValueError as exc:
            raise ManifestError(f"{log.path}: {exc}") from None
        stats = FileStats(log.path, log.vehicle, log.sensor, log.format)
        out.append(_Live(log, source, StreamDecoder(convert, ctx, log.sensor, log.format), stats))
    return out


class CaptureSession:
    """Captures every live log of a manifest into one archive; `run` loops until told to stop."""

    def __init__(self, manifest: Manifest, output: str | Path, options: CaptureOptions = CaptureOptions(),
                 listener: Listener | None = None, report: Reporter | None = None, allow_outside: bool = False,
                 replace: bool = False):
        self.manifest, self.options = manifest, options
        self.output = Path(output)
        self.listener = listener
        self.report: Reporter = report or (lambda text: None)
        self.part = part_path(self.output)
        self.logs = _prepare(manifest, allow_outside)
        if self.part.exists():
            raise ManifestError(f"{self.part} exists (a capture that did not stop cleanly): "
                                "`auvreplay recover` it or move it away first")
        # the output is claimed for the whole capture (formats.output_files): a second capture or record
        # into it is refused, and at the clean stop an existing file is replaced only with `replace`; a failed
        # close leaves the part file as it is: a capture is never deleted, `recover` reads it
        self.writer = ArchiveWriter(self.output, part_path=self.part, replace=replace, keep_on_error=True)
        fallback = date_to_ns(manifest.date) if manifest.date else 0
        self.writer.add_metadata("trial", trial_metadata(manifest))
        for live in self.logs:
            live.recorder = LogRecorder(self.writer, live.log, live.stats, fallback)
            self.writer.channel(live.topic, S.RawBytes)
        self.writer.flush()  # the raw channels are on disk before any data
        self._selector = selectors.DefaultSelector()
        now = time.monotonic()
        self.started_s = now
        self._next_flush = now + options.flush_s
        self._next_decode = now + options.decode_s
        self._announced = False
        self._busy = False   # a polled source had more than a turn's budget waiting
        self.first_receive_ns: int | None = None  # the first raw message's time: where the archive starts

    # -- sources ----------------------------------------------------------------
    def _open_due(self, now: float) -> None:
        for live in self.logs:
            if live.is_open or now < live.retry_at:
                continue
            try:
                live.source.open()
            except OSError as exc:
                live.backoff = min(max(live.backoff * 2, self.options.retry_s), RETRY_MAX_S)
                live.retry_at = now + live.backoff
                if live.status.state != "retrying" or live.status.error != str(exc):
                    live.status.error = str(exc)
                    self.report(f"{live.log.path}: cannot open {live.log.source} ({exc}); retrying")
                live.status.state = "retrying"
                continue
            live.is_open, live.backoff, live.status.error = True, 0.0, ""
            live.status.opens += 1
            live.status.state = "open"
            if live.status.opens > 1:
                self.report(f"{live.log.path}: {live.log.source} open again")
            self._register(live)
        if not self._announced and all(live.is_open for live in self.logs):
            self._announced = True
            self.report(f"capturing {len(self.logs)} sources into {self.part}")

    def _register(self, live: _Live) -> None:
        """Keep the selector on the source's current descriptors (a listener's change as clients come and go)."""
        fds = set(live.source.descriptors()) if live.is_open and live.source.selectable else set()
        if fds == live.fds:
            return
        for fd in live.fds - fds:
            self._selector.unregister(fd)
        for fd in fds - live.fds:
            self._selector.register(fd, selectors.EVENT_READ, live)
        live.fds = fds

    def _closed(self, live: _Live, why: str, now: float) -> None:
        live.is_open = False
        self._register(live)
        live.source.close()
        for peer in list(live.peers):
            live.decoder.end_peer(peer)
        live.peers.clear()
        live.retry_at = now + self.options.retry_s
        live.status.state = "retrying"
        self.report(f"{live.log.path}: {live.log.source} closed ({why}); reopening")

    def _read(self, live: _Live, now: float, fd: int = -1) -> int:
        """Read what `fd` (a polled source: the source) holds into the archive; the number of bytes."""
        try:
            peer, data = live.source.read_from(fd) if fd >= 0 else (0, live.source.read())
        except PeerClosed as exc:
            self._register(live)
            live.decoder.end_peer(exc.peer)
            live.peers.pop(exc.peer, None)
            self.report(f"{live.log.path}: {live.log.source}: connection {exc.peer} closed ({exc})")
            return 0
        except SourceClosed as exc:
            self._closed(live, str(exc), now)
            return 0
        self._register(live)
        if live.source.streaming and live.status.state == "open":
            live.status.state = "streaming"
        if data:
            self._archive(live, peer, data, now)
        return len(data)

    def _connection(self, live: _Live, peer: int) -> int:
        """The archive's connection number of a source's peer: the source's opens, one more per client."""
        if peer == 0:
            return live.status.opens
        number = live.peers.get(peer)
        if number is None:
            live.status.opens += 1
            number = live.peers[peer] = live.status.opens
        return number

    def _archive(self, live: _Live, peer: int, data: bytes, now: float) -> None:
        """One read's bytes: archived raw with their receive time, and fed to the decoder."""
        t = time.time_ns()
        if self.first_receive_ns is None:
            self.first_receive_ns = t
        st = live.status
        message = S.RawBytes(timestamp=S.timestamp(t), stream=live.log.path, offset=st.bytes, data=data,
                             connection=self._connection(live, peer))
        try:
            self.writer.write(live.topic, message, t)
        except OSError as exc:
            raise self._stopped(exc) from None
        live.sha.update(data)
        live.decoder.feed(data, t, peer)
        if live.source.selectable and live.decoder.backlog > MAX_BACKLOG and live.decoder.shed(MAX_BACKLOG // 2) \
                and not live.shed:
            live.shed = True
            self.report(f"warning: {live.log.path}: {live.log.source} sends faster than it can be decoded live: "
                        f"bytes over a {MAX_BACKLOG >> 20} MiB backlog are archived and not decoded "
                        "(counted as rejects; reported once)")
        st.bytes += len(data)
        st.reads += 1
        st.last_data_s = now
        if st.quiet:
            st.quiet = False
            self.report(f"{live.log.path}: data again")

    # -- decoding, flushing --------------------------------------------------------
    def _stopped(self, exc: OSError) -> CaptureStopped:
        """The one line of a write that failed (a full disk): capture stops, the part file stays."""
        why = os.strerror(exc.errno) if exc.errno else str(exc)
        return CaptureStopped(f"{self.part}: cannot write ({why}); capture stopped, the part file keeps what "
                              f"was captured: `auvreplay recover {self.part} -o FIXED.mcap`")

    def _decode(self, live: _Live, now: float, final: bool = False, budget: int | None = None) -> None:
        items = live.decoder.decode(final, budget)
        if not items:
            return
        recorder = live.recorder
        assert recorder is not None
        outputs = []
        try:
            for item in items:
                recorder.add(item)
                if type(item) is Reject and not live.dropped_lines and "without a newline" in item.reason:
                    live.dropped_lines = True
                    self.report(f"warning: {live.log.path}: {item.reason} (counted as a reject; reported once)")
                if type(item) is Output:
                    outputs.append(item)
        except OSError as exc:
            raise self._stopped(exc) from None
        st = live.status
        st.records += len(outputs)
        st.rejects += sum(1 for item in items if type(item) is Reject)   # Ignored records are not rejects
        if outputs:
            st.last_record_s = now
            if self.listener is not None:
                self.listener(live.log, outputs)

    def _check_quiet(self, now: float) -> None:
        for live in self.logs:
            st = live.status
            last = st.last_data_s if st.last_data_s is not None else self.started_s
            if live.is_open and not st.quiet and now - last > self.options.quiet_s:
                st.quiet = True
                self.report(f"warning: {live.log.path}: no data from {live.log.source} for "
                            f"{now - last:.1f} s")

    def step(self, now: float) -> None:
        """One turn of the loop: open what is due, wait for data until the next deadline, read, decode, flush."""
        self._open_due(now)
        deadline = min(self._next_flush, self._next_decode)
        if any(not live.is_open for live in self.logs):
            deadline = min(deadline, min(live.retry_at for live in self.logs if not live.is_open))
        polled = [live for live in self.logs if live.is_open and not live.source.selectable]
        timeout = max(0.0, deadline - time.monotonic())
        if polled:
            timeout = min(timeout, 0.0 if self._busy else self.options.decode_s)
        events = self._selector.select(timeout)  # epoll waits out the timeout with nothing registered too
        now = time.monotonic()
        for key, _ in events:
            if key.data.is_open:   # a source closed by an earlier event of this turn
                self._read(key.data, now, key.fd)
        self._busy = False
        for live in polled:
            got = 0
            while live.is_open and got < POLL_BUDGET and live.decoder.backlog < MAX_BACKLOG:
                n = self._read(live, now)
                if not n:
                    break
                got += n
            self._busy |= got >= POLL_BUDGET  # more is waiting: no sleep before the next turn
        if now >= self._next_decode:
            until = time.monotonic() + DECODE_TURN_S
            while True:
                due = [live for live in self.logs if live.decoder.pending]
                if not due or time.monotonic() >= until:
                    break
                for live in due:
                    self._decode(live, now, budget=DECODE_SLICE)
            self._next_decode = now + self.options.decode_s
            if due:   # a backlog: decode again next turn, without waiting
                self._next_decode, self._busy = now, True
        if now >= self._next_flush:
            self._flush()
            self._check_quiet(now)
            self._next_flush = now + self.options.flush_s

    def statuses(self) -> list[SourceStatus]:
        """Every source's counters, in manifest order."""
        return [live.status for live in self.logs]

    def _flush(self) -> None:
        try:
            self.writer.flush()
        except OSError as exc:
            raise self._stopped(exc) from None

    def run(self, should_stop: Callable[[], bool] = lambda: False) -> CaptureSummary:
        """Loop until `should_stop()` or the duration; then `finish`. On an error the part file stays.

        A write that fails (a full disk) is CaptureStopped, after the sources are closed.
        """
        try:
            while not should_stop():
                now = time.monotonic()
                if self.options.duration_s is not None and now - self.started_s >= self.options.duration_s:
                    break
                self.step(now)
        except BaseException:
            self.abandon()
            raise
        return self.finish()

    def _drain(self) -> None:
        """What the sources still hold at the stop: a growing file up to its size now, a socket's buffer."""
        now = time.monotonic()
        for live in self.logs:
            if not live.is_open:
                continue
            for peer, data in live.source.drain():
                self._archive(live, peer, data, now)

    def finish(self) -> CaptureSummary:
        """Read what is left, decode it, write statistics and summary, rename the part file to the output.

        On a write that fails the part file stays as it is (CaptureStopped): it is never deleted.
        """
        try:
            self._drain()
            now = time.monotonic()
            for live in self.logs:
                self._decode(live, now, final=True)
                assert live.recorder is not None
                live.recorder.finish()
                live.stats.size = live.status.bytes
                live.stats.sha256 = live.sha.hexdigest()
            summary = RecordingSummary(files=[live.stats for live in self.logs])
            self.writer.add_metadata("recording", {"files": [f.as_json() for f in summary.files]})
            self.writer.add_metadata("capture", {"sources": [s.as_json() for s in self.statuses()],
                                                 "flush_s": self.options.flush_s})
            self.writer.close()
        except CaptureStopped:
            self.abandon()
            raise
        except OSError as exc:
            self.abandon()
            raise self._stopped(exc) from None
        except BaseException:
            self.abandon()
            raise
        self._shutdown()
        return CaptureSummary(self.output, summary, self.statuses())

    def abandon(self) -> None:
        """Flush what was received and leave the part file for `auvreplay recover` (closed, never deleted)."""
        try:
            self.writer.flush()
        except (OSError, ValueError):
            pass
        self.writer.leave()
        self._shutdown()

    def _shutdown(self) -> None:
        for live in self.logs:
            live.source.shutdown()
        self._selector.close()
