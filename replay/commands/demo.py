"""The whole job on the sample lake trial: record, replay with every method, metrics, Rerun recording.

Uses the bundled sample trial (the simulator's seed-0 output); with --simulate
it simulates a fresh one first. Outputs go to --out (default ./demo-output).
Opens the viewer when a display is available, else prints the command.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path

from recorders.manifest import load_manifest
from recorders.record import record
from replay.commands.record import print_summary
from replay.commands.view import has_display
from replay.reproduce.anfis import sample_trial_dir
from replay.run.config import load_config
from replay.run.metrics import format_table
from replay.run.outputs import claim_directory, claim_outputs
from replay.run.pipeline import replay_archive, results_paths
from replay.stack.methods import runnable_names
from samples.scenario import Scenario
from samples.simulator import simulate_trial
from samples.writer import write_trial


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay demo`."""
    parser.add_argument("--out", default="demo-output", help="output directory (default ./demo-output)")
    parser.add_argument("--simulate", action="store_true", help="simulate a fresh trial instead of the sample")
    parser.add_argument("--seed", type=int, default=0, help="with --simulate: the seed")
    parser.add_argument("--no-viewer", action="store_true", help="never open the viewer")
    parser.add_argument("--force", action="store_true",
                        help="replace the outputs of an earlier demo in --out (default: refuse)")


def _trial_dir(args: argparse.Namespace, out: Path) -> Path:
    if not args.simulate:

        return sample_trial_dir()

    trial_dir = claim_directory(out / f"trial-seed{args.seed}", args.force)
    print(f"simulating the lake trial (seed {args.seed}) into {trial_dir}")
    write_trial(simulate_trial(Scenario(), args.seed), trial_dir)
    return trial_dir


def run(args: argparse.Namespace) -> int:
    """Record, replay, print, save, open."""
    from replay.views.recording import open_viewer, save_rrd, viewer_command

    out = Path(args.out)
    archive, results, rrd = out / "lake-trial.mcap", out / "lake-trial-results.mcap", out / "lake-trial.rrd"
    claim_outputs([archive, *results_paths(results), rrd], args.force)
    out.mkdir(parents=True, exist_ok=True)
    trial_dir = _trial_dir(args, out)
    print(f"recording {trial_dir / 'trial.toml'} -> {archive}")
    print_summary(record(load_manifest(trial_dir / "trial.toml"), archive))
    print(f"\nreplaying {archive} with every method")
    # the demo shows every method, the new detectors included (a plain `replay` runs paper A's stack)
    outcome = replay_archive(archive, load_config(default_methods=runnable_names()), output=results, review=True,
                             force=args.force)
    m = outcome.metrics
    print(f"run {outcome.run_id}: {m['epochs']} ranging epochs scored after t_a = {m['window'][0]:.0f} s "
          f"({m['anomalous']} anomalous), {m['usbl_epochs']} USBL epochs, {outcome.wall_s:.2f} s")
    print(format_table(m))
    save_rrd([outcome.review], rrd)
    print(f"\nresults: {results}\nmetrics: {results.with_suffix('.metrics.csv')}\nrecording: {rrd}")
    if not args.no_viewer and has_display(os.environ):
        return open_viewer(rrd)
    me = shlex.quote(sys.argv[0]) if sys.argv and sys.argv[0].endswith("auvreplay") else "auvreplay"
    print(f"to look at it: {shlex.join(viewer_command(rrd))}   (or: {me} view {shlex.quote(str(rrd))} --web)")
    return 0
