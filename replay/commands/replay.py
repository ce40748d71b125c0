"""Replay an archive through every method side by side; results MCAP, metrics CSV/JSON, optional .rrd."""

from __future__ import annotations

import argparse
import json
import sys

from replay.commands.view import focus_list
from replay.errors import UserError, warn_damage
from replay.run.config import load_config
from replay.run.metrics import format_table
from replay.run.outputs import claim_outputs
from replay.run.pipeline import replay_archive
from replay.run.rebuild import review_from_results


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay replay`."""
    parser.add_argument("archive", help="a trial archive (.mcap) from `auvreplay record`")
    parser.add_argument("-c", "--config", help="configuration TOML (defaults: docs/design.md sections 7-14)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one parameter, e.g. --set r_m=2.5 --set anfis.epochs=50")
    parser.add_argument("--window", nargs=2, type=float, metavar=("T0", "T1"),
                        help="replay only [T0, T1] seconds from the trial start")
    parser.add_argument("--rate", type=float, help="pace at X times real time (default: as fast as possible)")
    parser.add_argument("-o", "--output", help="results archive (default: <archive>-replay-<run>.mcap)")
    parser.add_argument("--rrd", help="also save a Rerun recording of the run")
    parser.add_argument("--compare", metavar="RESULTS.mcap",
                        help="with --rrd: put this earlier run into the same recording, side by side, as run A "
                             "(this run is B, as in `auvreplay compare RESULTS.mcap THIS.mcap`)")
    parser.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
    parser.add_argument("--focus", type=focus_list, default=None, metavar="M1,M2|all",
                        help="with --rrd: the methods shown at first (default: the best of each scoreboard "
                             "group, the best detector, chi_square and anfis; 'all': every method)")
    parser.add_argument("--force", action="store_true",
                        help="replace existing output files (default: refuse to overwrite them)")


def run(args: argparse.Namespace) -> int:
    """Run the replay and print the metrics table (or JSON)."""
    if args.compare and not args.rrd:
        raise UserError("--compare needs --rrd (the comparison is a recording)")
    config = load_config(args.config, args.set, tuple(args.window) if args.window else None, args.rate)
    claim_outputs([args.rrd], args.force)
    outcome = replay_archive(args.archive, config, args.output, review=bool(args.rrd), force=args.force,
                             require_work=True)
    if args.rrd:
        from replay.views.recording import save_rrd

        # A is the first argument everywhere: the earlier run named by --compare is A, this run B
        reviews = [review_from_results(args.compare), outcome.review] if args.compare else [outcome.review]
        save_rrd(reviews, args.rrd, focus=args.focus)
    if args.json:
        print(json.dumps(outcome.metrics, indent=2, sort_keys=True))
    else:
        for note in outcome.notes:
            print(f"note: {note}", file=sys.stderr)
        print(f"run {outcome.run_id}: {outcome.metrics['epochs']} scored epochs after t_a "
              f"({outcome.metrics['anomalous']} anomalous), {outcome.messages} messages in {outcome.wall_s:.2f} s")
        print(format_table(outcome.metrics))
        print(f"results: {outcome.output}" + (f"; recording: {args.rrd}" if args.rrd else ""))
    compared = reviews[0].input_warning if args.rrd and args.compare else None
    warn_damage("replay", "; ".join(filter(None, [outcome.warning, compared])) or None)
    return 0
