"""Play a recorded trial's logs out as live streams: each log to its own UDP port, TCP socket or pty."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from pathlib import Path

from formats.output_files import write_new_file
from recorders.feed import FeedError, live_manifest, make_targets, play
from recorders.manifest import ManifestError, load_manifest
from replay.errors import UserError
from replay.run.outputs import claim_output

START_WAIT_S = 600.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay feed`."""
    parser.add_argument("manifest", help="the trial manifest (TOML) of recorded logs")
    parser.add_argument("--to", required=True, metavar="TARGET",
                        help="udp://HOST:PORT, tcp-listen://HOST:PORT, tcp://HOST:PORT (log i on PORT+i), or pty")
    parser.add_argument("--rate", type=float, default=1.0, help="times real time (default 1)")
    parser.add_argument("--seconds", type=float, default=None, help="only the first S seconds of the trial")
    parser.add_argument("--manifest-out", default=None, metavar="FILE",
                        help="write the manifest `capture` reads these streams with")
    parser.add_argument("--force", action="store_true", help="replace the --manifest-out file if it exists")
    parser.add_argument("--hold-s", type=float, default=1.0,
                        help="keep the targets open this long after the last byte (default 1 s)")
    parser.add_argument("--start-after", default=None, metavar="FILE",
                        help="wait until FILE exists before playing (start the capture first)")


def _wait_for(path: Path, stop: list[bool]) -> None:
    deadline = time.monotonic() + START_WAIT_S
    while not path.exists() and not stop:
        if time.monotonic() > deadline:
            raise UserError(f"{path} did not appear within {START_WAIT_S:.0f} s")
        time.sleep(0.02)


def run(args: argparse.Namespace) -> int:
    """Print each log's target, then play; exit 0 when every log was sent."""
    if args.manifest_out:
        if os.path.realpath(args.manifest_out) == os.path.realpath(args.manifest):
            raise UserError(f"--manifest-out {args.manifest_out} is the manifest being played: not overwritten")
        claim_output(args.manifest_out, args.force)
    try:
        manifest = load_manifest(args.manifest)
    except ManifestError as exc:
        raise UserError(str(exc)) from None
    live = [log.path for log in manifest.logs() if log.source]
    if live:
        raise UserError(f"{args.manifest}: {live[0]} is a live source; feed plays recorded files")
    try:
        targets = make_targets(args.to, len(manifest.logs()))
    except FeedError as exc:
        raise UserError(str(exc)) from None
    stop: list[bool] = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    try:
        for log, target in zip(manifest.logs(), targets):
            print(f"{log.path} -> {target.source}", flush=True)
        if args.manifest_out:
            text = live_manifest(manifest, targets)
            write_new_file(args.manifest_out, text.encode(), replace=args.force)  # whole or absent for a poller
        if args.start_after:
            _wait_for(Path(args.start_after), stop)
        try:
            stats = play(manifest, targets, args.rate, args.seconds, should_stop=lambda: bool(stop))
        except (FeedError, ManifestError) as exc:
            raise UserError(str(exc)) from None
        print(f"sent {stats.bytes} bytes in {stats.segments} pieces over {stats.seconds:.1f} s", file=sys.stderr,
              flush=True)
        deadline = time.monotonic() + args.hold_s  # readers drain what is still in flight
        while time.monotonic() < deadline and not stop:
            time.sleep(0.02)
    finally:
        for target in targets:
            target.close()
    return 0
