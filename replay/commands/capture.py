"""Capture live sensor streams into a crash-safe archive as they arrive (optionally watched in Rerun)."""

from __future__ import annotations

import argparse
import signal
import sys
import time

from recorders.capture.session import CaptureOptions, CaptureSession
from recorders.capture.status import status_block
from recorders.manifest import load_manifest


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay capture`."""
    parser.add_argument("manifest", help="a trial manifest whose logs name a live `source`")
    parser.add_argument("-o", "--output", required=True, help="the archive (grows as OUTPUT.part until a clean stop)")
    parser.add_argument("--flush-s", type=_positive, default=1.0,
                        help="close, write and fsync a chunk at least this often (default 1 s)")
    parser.add_argument("--duration", type=_positive, default=None, metavar="S", help="stop after S seconds")
    parser.add_argument("--quiet-s", type=_positive, default=5.0,
                        help="warn when a source gives nothing for this long (default 5 s)")
    parser.add_argument("--status-s", type=_positive, default=1.0, help="status refresh on a terminal (default 1 s)")


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


def run(args: argparse.Namespace) -> int:
    """Capture until Ctrl-C, SIGTERM or --duration; then write the summary and rename the part file."""
    manifest = load_manifest(args.manifest)
    status = _StatusLines(args.status_s)
    options = CaptureOptions(flush_s=args.flush_s, duration_s=args.duration, quiet_s=args.quiet_s)
    session = CaptureSession(manifest, args.output, options, report=status.note)
    stop: list[bool] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(True))

    def should_stop() -> bool:
        status.draw(session)
        return bool(stop)

    summary = session.run(should_stop)
    status.draw(session, force=True)
    records = sum(f.messages for f in summary.recording.files)
    print(f"auvreplay capture: {summary.path}: {records} messages from {len(summary.sources)} sources",
          file=sys.stderr)
    return 0
