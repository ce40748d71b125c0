"""Capture live sensor streams into a crash-safe archive as they arrive (optionally watched in Rerun)."""

from __future__ import annotations

import argparse
import queue
import signal
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from recorders.base import Output
from recorders.capture.session import CaptureOptions, CaptureSession
from recorders.capture.status import status_block
from recorders.manifest import LogSpec, Manifest, ManifestError, load_manifest
from recorders.record import trial_metadata
from replay.errors import UserError
from replay.run.config import load_config
from replay.run.online import OnlineRun
from replay.run.outputs import claim_outputs
from replay.run.pipeline import results_paths

if TYPE_CHECKING:
    from replay.views.live import LiveView


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay capture`."""
    parser.add_argument("manifest", help="a trial manifest whose logs name a live `source`")
    parser.add_argument("-o", "--output", required=True, help="the archive (grows as OUTPUT.part until a clean stop)")
    parser.add_argument("--force", action="store_true",
                        help="replace the output (and --results, --rrd files) if they exist")
    parser.add_argument("--flush-s", type=_positive, default=1.0,
                        help="close, write and fsync a chunk at least this often (default 1 s)")
    parser.add_argument("--duration", type=_positive, default=None, metavar="S", help="stop after S seconds")
    parser.add_argument("--quiet-s", type=_positive, default=5.0,
                        help="warn when a source gives nothing for this long (default 5 s)")
    parser.add_argument("--status-s", type=_positive, default=1.0, help="status refresh on a terminal (default 1 s)")
    live = parser.add_argument_group("live view and online estimation (the engine runs as data arrive)")
    live.add_argument("--view", action="store_true", help="spawn a Rerun viewer and stream into it")
    live.add_argument("--connect", metavar="ADDRESS", default=None,
                      help="stream into a running Rerun viewer (e.g. rerun+http://127.0.0.1:9876/proxy)")
    live.add_argument("--rrd", metavar="FILE", default=None, help="also write the live recording to an .rrd file")
    live.add_argument("--results", metavar="FILE", default=None,
                      help="save the online run's results archive (and its metrics) at the end")
    live.add_argument("-c", "--config", default=None, help="replay configuration TOML for the online run")
    live.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a configuration key")


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, not {value}")
    return value


class _StatusLines:
    """The status block on a terminal, redrawn in place; elsewhere only the notes and the final block."""
    def __init__(self, every_s: float) -> None:
        self.live = sys.stderr.isatty()
        self.every_s = every_s
        self.next_s = 0.0
        self.drawn = 0

    def note(self, text: str) -> None:
        self._erase()
        print(f"auvreplay capture: {text}", file=sys.stderr, flush=True)

    def _erase(self) -> None:
        if self.drawn:
            sys.stderr.write(f"\x1b[{self.drawn}F\x1b[J")
            self.drawn = 0

    def draw(self, session: CaptureSession, force: bool = False) -> None:
        now = time.monotonic()
        if not force and (not self.live or now < self.next_s):
            return
        self.next_s = now + self.every_s
        self._erase()
        lines = status_block(session.statuses(), now)
        sys.stderr.write("\n".join(lines) + "\n")
        sys.stderr.flush()
        self.drawn = len(lines) if self.live and not force else 0


class _Online:
    """The capture's decoded messages into the online engine and the live view."""
    def __init__(self, args: argparse.Namespace, manifest: Manifest) -> None:
        viewing = bool(args.view or args.connect or args.rrd)
        topics = sorted({f"/{log.vehicle}/{'modem/range' if log.sensor == 'modem' else log.sensor}"
                         for log in manifest.logs()} | {"/diagnostics"})
        self.view: LiveView | None = None
        self.session: CaptureSession | None = None  # set once it exists: its first receive time starts the run
        self.run = OnlineRun(trial_metadata(manifest), topics, load_config(args.config, args.set),
                             args.results, review=viewing, label=str(args.output),
                             earliest=lambda: self.session.first_receive_ns if self.session else None)
        if viewing:
            # rerun only when a view is asked for (replay.views is the one importer of rerun)
            from replay.views.live import LiveView, open_stream

            view = self.view = LiveView(open_stream(self.run.run_id, args.view, args.connect, args.rrd),
                                        self.run.run_id)
            self.run.factories.append(lambda rid, t0: view.attach(t0))

        # the engine and the view run on their own thread: training at t_a takes seconds, and the capture
        # loop must keep reading meanwhile
        self._queue: queue.Queue = queue.Queue()
        self.error: Exception | None = None
        self._thread = threading.Thread(target=self._work, name="online-run", daemon=True)
        self._thread.start()

    def __call__(self, log: LogSpec, outputs: list[Output]) -> None:
        self._queue.put((log.path, outputs))

    def _work(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self.error is not None:
                continue  # the capture goes on; the error is raised at the end
            try:
                self._one(*item)
            except Exception as exc:  # noqa: BLE001 - kept for finish(), which raises it
                self.error = exc

    def _one(self, path: str, outputs: list[Output]) -> None:
        self.run.add(path, [(o.topic, o.log_time_ns, o.message) for o in outputs])
        if self.view is not None:
            for o in outputs:
                self.view.recorded(o.topic, o.log_time_ns, o.message, o.where.host_time_ns if o.where else None)
            self.view.flush()

    def finish(self, output: str) -> None:
        self._queue.put(None)
        self._thread.join()
        if self.error is not None:
            raise self.error
        outcome = self.run.finish(output)
        if self.view is not None:
            self.view.finish(outcome.review if outcome is not None else None)
        for note in outcome.notes if outcome is not None else ["no message reached the online run"]:
            print(f"auvreplay capture: online run: {note}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Capture until Ctrl-C, SIGTERM or --duration; then write the summary and rename the part file."""
    status = _StatusLines(args.status_s)
    options = CaptureOptions(flush_s=args.flush_s, duration_s=args.duration, quiet_s=args.quiet_s)
    # every output claimed before the first byte is read: an existing file is refused with one line
    claim_outputs([args.output, args.rrd, *(results_paths(Path(args.results)) if args.results else ())], args.force)
    try:
        manifest = load_manifest(args.manifest)
        online = _Online(args, manifest) if args.view or args.connect or args.rrd or args.results else None
        session = CaptureSession(manifest, args.output, options, listener=online, report=status.note,
                                 replace=args.force)
    except ManifestError as exc:
        raise UserError(str(exc)) from None
    if online is not None:
        online.session = session
    stop: list[bool] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(True))

    def should_stop() -> bool:
        status.draw(session)
        return bool(stop)

    summary = session.run(should_stop)
    status.draw(session, force=True)
    if online is not None:
        online.finish(str(summary.path))
    records = sum(f.messages for f in summary.recording.files)
    print(f"auvreplay capture: {summary.path}: {records} messages from {len(summary.sources)} sources",
          file=sys.stderr)
    return 0
