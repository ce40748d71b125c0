"""Replay many archives under every configuration of a sweep, on Dask distributed.

Every archive (and every `--simulate-seeds` trial, simulated and recorded
first) is replayed under every combination of the `--sweep` values, on a
LocalCluster of `--workers` processes or on the scheduler at `--scheduler`.
Writes DIR/runs/<trial>-<run>.mcap (with its metrics CSV/JSON) per run and
one combined table, DIR/metrics.parquet and DIR/metrics.csv, with trial,
configuration and method columns. A run that fails (a corrupt archive, say)
gets a row with its error; the others finish, and the exit code is 1.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import TYPE_CHECKING

from replay.errors import UserError, warn_damage
from replay.run.batch import batch, parse_seeds, parse_sweeps, summary_table, table_paths
from replay.run.outputs import claim_outputs

if TYPE_CHECKING:
    import pandas as pd


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay batch`."""
    parser.add_argument("archives", nargs="*", metavar="ARCHIVE", help="trial archives (.mcap)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="the results directory")
    parser.add_argument("-c", "--config", help="configuration TOML applied to every run")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one parameter in every run, as for `replay`")
    parser.add_argument("--sweep", action="append", default=[], metavar="KEY=V1,V2,...",
                        help="replay under each value (several --sweep: every combination); "
                             "separate with ';' when a value is itself a list")
    parser.add_argument("--window", nargs=2, type=float, metavar=("T0", "T1"),
                        help="replay only [T0, T1] seconds from each trial's start")
    parser.add_argument("--simulate-seeds", metavar="SEEDS",
                        help="also simulate these seeds (0-19, or 1,4,7) into DIR/trials and replay them")
    parser.add_argument("--duration", type=float, metavar="S", help="simulated trial length (default 1700 s)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="a running Dask scheduler (tcp://host:8786); default: a LocalCluster")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                        help="LocalCluster worker processes (one thread each)")
    parser.add_argument("--json", action="store_true", help="print one JSON object with every run's metrics")
    parser.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    parser.add_argument("--force", action="store_true",
                        help="replace the tables (and runs) of an earlier batch in DIR (default: refuse)")


class _Progress:
    """A one-line progress bar on stderr: runs done, failed, elapsed; drawn only on a terminal."""
    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self.t0 = time.monotonic()

    def __call__(self, done: int, total: int, failed: int) -> None:
        if not self.enabled:
            return
        frac = done / total if total else 1.0
        elapsed = time.monotonic() - self.t0
        eta = elapsed / done * (total - done) if done else 0.0
        sys.stderr.write(f"\rbatch [{'#' * int(30 * frac):<30}] {done}/{total} runs, {failed} failed, "
                         f"{elapsed:.0f} s elapsed, ~{eta:.0f} s left ")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _text(df: pd.DataFrame) -> str:
    """A table for the terminal: '-' for missing values, three decimals for figures."""
    import pandas as pd

    def cell(v: object) -> str:
        if v is None or v is pd.NA or (isinstance(v, float) and v != v):
            return "-"
        return f"{v:.3f}" if isinstance(v, float) else str(v)

    return df.astype(object).map(cell).to_string(index=False)


def run(args: argparse.Namespace) -> int:
    """Run the batch, write the tables, print a summary; 1 when any run failed."""
    if not args.archives and not args.simulate_seeds:
        raise UserError("give archives, or --simulate-seeds")
    if args.duration is not None and not args.simulate_seeds:
        raise UserError("--duration applies to --simulate-seeds only")
    overrides = list(args.set)
    if args.window:
        overrides.append(f"window_s=[{args.window[0]!r},{args.window[1]!r}]")
    seeds = parse_seeds(args.simulate_seeds) if args.simulate_seeds else []
    claim_outputs(table_paths(args.output), args.force)
    df, records = batch(args.archives, args.output, args.config, overrides, parse_sweeps(args.sweep), seeds,
                        args.duration, scheduler=args.scheduler, workers=args.workers,
                        progress=_Progress(not args.quiet and not args.json))
    failed = [r for r in records if r["error"] is not None]
    if args.json:
        runs = [{"trial": r["trial"], "archive": r["archive"], "run_id": r["run_id"],
                 "configuration": r["configuration"].text, "output": r["output"], "error": r["error"],
                 "metrics": r["metrics"]} for r in records]
        print(json.dumps({"output": args.output, "runs": runs, "failed": len(failed)}, indent=2))
    elif not args.quiet:
        table = summary_table(df)
        if len(table):
            print(_text(table))
        print(f"{len(records)} runs, {len(failed)} failed; table: {args.output}/metrics.parquet, "
              f"{args.output}/metrics.csv; results: {args.output}/runs/")
    for r in failed:
        conf = r["configuration"].text
        print(f"failed: {r['trial']}" + (f" [{conf}]" if conf else "") + f": {r['error']}", file=sys.stderr)
    # one line for the batch: each damaged archive once, however many configurations replayed it
    damaged = {r["archive"]: r["warning"] for r in records if r.get("warning")}
    warn_damage("batch", "; ".join(f"{archive}: {w}" for archive, w in damaged.items()) or None)
    return 1 if failed else 0
