"""Archive a trial: every log of the manifest into one MCAP file, with a summary table."""

from __future__ import annotations

import argparse
import sys
import time
from typing import TextIO

from formats.nmea.counts import describe as describe_counts
from recorders.clock import iso_utc
from recorders.manifest import ManifestError, load_manifest
from recorders.record import RecordingSummary, record
from replay.errors import UserError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay record`."""
    parser.add_argument("manifest", help="the trial manifest (TOML)")
    parser.add_argument("-o", "--output", required=True, help="the archive to write (.mcap)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar, no table")
    parser.add_argument("--force", action="store_true", help="replace the output archive if it exists")
    parser.add_argument("--allow-outside", action="store_true",
                        help="read logs whose paths resolve outside the manifest's folder")
    parser.add_argument("--workers", type=_worker_count, default=None, metavar="N",
                        help="processes decoding the logs (default: automatic, one per core for a trial "
                             "of 1 MiB or more, else in-process); the archive is the same for any N")


def _worker_count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {value}")
    return value


class _ProgressBar:
    """A one-line progress bar on stderr, drawn only on a terminal and at most 10 times a second."""
    def __init__(self) -> None:
        self.enabled = sys.stderr.isatty()
        self.last = 0.0

    def __call__(self, name: str, done: int, total: int) -> None:
        now = time.monotonic()
        if not self.enabled or (now - self.last < 0.1 and done < total):
            return
        self.last = now
        frac = done / total if total else 1.0
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r{name[-40:]:<40} [{bar:<30}] {100 * frac:5.1f}%")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def print_summary(summary: RecordingSummary, out: TextIO | None = None) -> None:
    """The per-file table: parsed, skipped, bad checksum, time span."""
    out = out or sys.stdout
    rows = [("file", "vehicle", "sensor/format", "parsed", "skipped", "bad crc", "ignored", "start", "end")]
    for f in summary.files:
        rows.append((f.path, f.vehicle, f"{f.sensor or 'any'}/{f.format}", str(f.parsed), str(f.skipped),
                     str(f.bad_checksum), str(f.ignored), iso_utc(f.start_ns) or "-", iso_utc(f.end_ns) or "-"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for k, r in enumerate(rows):
        print("  ".join(c.rjust(w) if 3 <= i <= 6 else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))), file=out)
        if k == 0:
            print("  ".join("-" * w for w in widths), file=out)
    for f in summary.files:
        for reason, count in sorted(f.ignored_reasons.items()):
            print(f"note: {f.path}: {count} not archived: {reason}", file=out)
        if f.parts:
            print(f"note: {f.path}: one log of {len(f.parts)} files: {', '.join(p['path'] for p in f.parts)}",
                  file=out)
        for note in f.notes:
            print(f"note: {note}", file=out)
        if f.sentences:
            print(f"note: {f.path}: {describe_counts(f.sentences)}", file=out)
        if f.out_of_order or f.duplicates:
            print(f"note: {f.path}: {f.out_of_order} out-of-order and {f.duplicates} duplicated times kept as logged",
                  file=out)


def run(args: argparse.Namespace) -> int:
    """Record the trial; exit 0 even when records were skipped (they are counted and reported)."""
    try:
        manifest = load_manifest(args.manifest, allow_outside=args.allow_outside)
        summary = record(manifest, args.output, progress=None if args.quiet else _ProgressBar(),
                         workers=args.workers, replace=args.force)
    except ManifestError as exc:
        raise UserError(str(exc)) from exc
    for part in summary.removed_parts:
        print(f"auvreplay record: removed {part}, the part file of a process that is gone", file=sys.stderr)
    if not args.quiet:
        print_summary(summary)
        print(f"wrote {args.output}: {sum(f.messages for f in summary.files)} messages, "
              f"{len(summary.files)} attachments, {summary.skipped} records skipped")
    return 0
