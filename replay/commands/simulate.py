"""Write a synthetic lake trial: vendor logs per vehicle, a manifest, the exact truth and the labels.

The default is the sample trial (`samples/lake_trial/` is `simulate --seed 0`):
two leaders and one follower boat for 1700 s, GPS on every vehicle, PHINS /
NovAtel SPAN INS, PD0 DVLs, WHOI Micro-Modem pings to alternating leaders,
four EvoLogics USBL buoys, and the anomalies of the source trial (leader 1
stale 100-150 s and drifting 1100-1170 s, leader 2 stale twice, natural stale
segments, outliers, dropouts). `--scenario FILE` reads a scenario TOML (the
`scenario.toml` written into every trial directory is a complete example).
"""

from __future__ import annotations

import argparse
import sys

from replay.errors import UserError
from replay.run.outputs import claim_directory
from samples.scenario import Scenario, ScenarioError, load_scenario
from samples.simulator import simulate_trial
from samples.writer import write_trial


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay simulate`."""
    parser.add_argument("-o", "--output", required=True, help="the trial directory to write")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0: the sample trial)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="trial length in seconds (default 1700)")
    parser.add_argument("--followers", type=int, default=None, metavar="K",
                        help="number of followers (default 1)")
    parser.add_argument("--scenario", default=None, metavar="FILE",
                        help="scenario TOML (anomalies, sensors, buoys...); options above override it")
    parser.add_argument("--force", action="store_true", help="write into a directory that is not empty")
    parser.add_argument("--quiet", action="store_true", help="print nothing on success")


def _scenario(args: argparse.Namespace) -> Scenario:

    try:
        base = load_scenario(args.scenario) if args.scenario else Scenario()
        if args.seed < 0:
            raise ScenarioError("--seed must be >= 0")
        if args.duration is not None and args.duration <= 0:
            raise ScenarioError("--duration must be > 0")
        if args.followers is not None and args.followers < 1:
            raise ScenarioError("--followers must be >= 1")
        return base.with_options(args.duration, args.followers)
    except OSError as exc:
        raise UserError(f"cannot read scenario {args.scenario}: {exc.strerror or exc}") from None
    except ScenarioError as exc:
        raise UserError(f"scenario: {exc}") from None


def run(args: argparse.Namespace) -> int:
    """Simulate and write the trial directory; exit 0 on success."""
    scenario = _scenario(args)
    out = claim_directory(args.output, args.force)
    trial = simulate_trial(scenario, args.seed)
    written = write_trial(trial, out)
    if not args.quiet:
        r = trial.ranges
        size = sum(p.stat().st_size for p in written)
        print(f"wrote {len(written)} files ({size / 1e6:.2f} MB) to {out}: {len(trial.vehicles)} vehicles, "
              f"{len(trial.buoys)} buoys, {len(r.t_s)} ranges ({int(r.label.sum())} labelled anomalous), "
              f"{len(trial.usbl.t_s)} USBL epochs; manifest {out / 'trial.toml'}", file=sys.stdout)
    return 0
