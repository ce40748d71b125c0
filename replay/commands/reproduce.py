"""Reproduce a source paper's result: `anfis` runs paper A's detection table on the sample (or a given)
trial; `kmcdf` runs seed 003's Fig. 2 (KMCDF against GAR, EAR, LMS, LHC).

Prints the tables beside the paper's numbers (or one JSON object with --json);
`kmcdf` also writes the figure as a PNG and as a Rerun .rrd.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from contextlib import AbstractContextManager, nullcontext
from typing import Any

from replay.errors import UserError
from replay.reproduce import anfis
from replay.reproduce.kmcdf import (
    format_claims,
    format_curves,
    format_sensitivity,
    reproduce,  # seed 003's figure; paper A's table is anfis.reproduce
    save_png,
    save_rrd,
    sensitivity,
)
from replay.run.batch import dask_client
from replay.run.outputs import claim_outputs
from replay.stack.positioning.kmcdf import KmcdfParams


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `auvreplay reproduce`."""
    parser.add_argument("which", choices=["anfis", "kmcdf"], help="the paper result to reproduce")
    parser.add_argument("--trial", help="anfis: a trial directory, manifest or archive (default: the sample trial)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="anfis: override a stack parameter, as for `replay`")
    parser.add_argument("--trials", type=int, default=1000, help="Monte Carlo trials per point")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    parser.add_argument("--png", default="out/reproduce_kmcdf.png", help="figure path ('' for none)")
    parser.add_argument("--rrd", default="out/reproduce_kmcdf.rrd", help="Rerun path ('' for none)")
    parser.add_argument("--force", action="store_true",
                        help="replace an existing --png / --rrd file (default: refuse to overwrite it)")
    parser.add_argument("--sensitivity", action="store_true",
                        help="also the KMCDF success at the paper's points over the phase noise")
    parser.add_argument("--phase-noise", type=float, default=0.1,
                        help="phase-difference noise sigma in rad (seed 003 gives none; default 0.1)")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                        help="worker processes (results do not depend on it)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="kmcdf: run the points on Dask, at a scheduler (tcp://host:8786) or 'local' "
                             "(a LocalCluster of --workers processes); results do not depend on it")


def run(args: argparse.Namespace) -> int:
    """Run the reproduction and report it."""
    if args.which == "anfis":
        return _run_anfis(args)
    if args.trials < 1:
        raise UserError("--trials must be at least 1")
    if args.phase_noise <= 0:
        raise UserError("--phase-noise must be positive")

    claim_outputs([args.png, args.rrd], args.force)
    params = KmcdfParams(sigma_phase_rad=args.phase_noise)
    with _dask(args.scheduler, args.workers) as client:
        result = reproduce(args.trials, args.seed, params, workers=args.workers, client=client)
        table = sensitivity(args.trials, args.seed, params, workers=args.workers, client=client) \
            if args.sensitivity else None
    if args.png:
        save_png(result, args.png)
    if args.rrd:
        save_rrd(result, args.rrd)
    if args.json:
        out = result.to_json()
        if table is not None:
            out["sensitivity"] = table
        json.dump(out, sys.stdout, indent=2)
        print()
        return 0
    print(format_curves(result))
    print()
    print(format_claims(result))
    if table is not None:
        print()
        print(format_sensitivity(table))
    written = [p for p in (args.png, args.rrd) if p]
    if written:
        print(f"\nwrote {', '.join(written)}")
    return 0


def _dask(scheduler: str | None, workers: int) -> AbstractContextManager[Any]:
    """A Dask client when --scheduler is given (see replay.run.batch.dask_client), else None."""
    if scheduler is None:
        return nullcontext(None)
    return dask_client(scheduler, workers)


def _run_anfis(args: argparse.Namespace) -> int:
    """Paper A's table: record (if needed) and replay the trial in both ANFIS model modes."""
    modes = anfis.reproduce(args.trial, args.set)
    if args.json:
        json.dump(anfis.json_object(modes), sys.stdout, indent=2, sort_keys=True)
        print()
    else:
        print(anfis.format_report(modes))
    return 0
