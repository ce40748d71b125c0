"""Write a synthetic lake trial: vendor logs per vehicle, a manifest, the exact truth and the labels.

The default is the sample trial (`samples/lake_trial/` is `simulate --seed 0`):
two leaders and one follower boat for 1700 s, GPS on every vehicle, PHINS /
NovAtel SPAN INS, PD0 DVLs, WHOI Micro-Modem pings to alternating leaders,
four EvoLogics USBL buoys, and the anomalies of the source trial (leader 1
stale 100-150 s and drifting 1100-1170 s, leader 2 stale twice, natural stale
segments, outliers, dropouts). `--scenario FILE` reads a scenario TOML (the
`scenario.toml` written into every trial directory is a complete example).

`--tracks ARCHIVE` moves the vehicles along a recorded trial's GPS tracks
(samples/recorded.py) and simulates only the acoustics and the DR sensors
along them: with two or more tracks they are the leaders and the follower
(`--follower NAME`; default the vehicle named follower, else the archive's
first follower, else the first track); with one, that vehicle is the follower
and leader k is its own track k x `--leader-offset` seconds ahead (default
300 s). Gaps between fixes up to `--max-gap` seconds (default 30) are
interpolated; longer ones cut the trial to the longest span every track
covers. The trial lasts that span (or `--duration` if shorter) and is dated
and placed where the archive was; every line the simulation chose is printed.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from replay.errors import UserError
from replay.run.config_ranges import EVALUATE_MAX_DURATION_S
from replay.run.outputs import claim_directory
from samples.recorded import TrackError
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
    parser.add_argument("--tracks", default=None, metavar="ARCHIVE",
                        help="move the vehicles along this archive's GPS tracks (LocationFix); simulate only the "
                             "acoustics and DR sensors")
    parser.add_argument("--follower", default=None, metavar="NAME",
                        help="with --tracks: the vehicle whose track is the follower's (default: the one named "
                             "follower, else the archive's first follower, else the first track)")
    parser.add_argument("--leaders", type=int, default=None, metavar="K",
                        help="with --tracks of one vehicle: leaders made of its track (default 2)")
    parser.add_argument("--leader-offset", type=float, default=None, metavar="S",
                        help="with --tracks of one vehicle: leader k is the track k*S seconds ahead (default 300)")
    parser.add_argument("--max-gap", type=float, default=None, metavar="S",
                        help="with --tracks: longest gap between fixes interpolated over (default 30 s)")
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
        if args.tracks is None:
            if any(v is not None for v in (args.follower, args.leaders, args.leader_offset, args.max_gap)):
                raise ScenarioError("--follower, --leaders, --leader-offset and --max-gap go with --tracks")
            return base.with_options(args.duration, args.followers)
        return _with_tracks(base, args)
    except OSError as exc:
        raise UserError(f"cannot read scenario {args.scenario}: {exc.strerror or exc}") from None
    except ScenarioError as exc:
        raise UserError(f"scenario: {exc}") from None


def _with_tracks(base: Scenario, args: argparse.Namespace) -> Scenario:
    """The scenario moved onto `--tracks`: the whole covered span unless `--duration` cuts it."""
    if args.followers is not None:
        raise ScenarioError("--followers does not go with --tracks: the tracks give one follower")
    tr = base.tracks
    tracks = replace(tr, archive=args.tracks, follower=tr.follower if args.follower is None else args.follower,
                     leaders=tr.leaders if args.leaders is None else args.leaders,
                     leader_offset_s=tr.leader_offset_s if args.leader_offset is None else args.leader_offset,
                     max_gap_s=tr.max_gap_s if args.max_gap is None else args.max_gap)
    duration = EVALUATE_MAX_DURATION_S if args.duration is None else args.duration
    return replace(base, tracks=tracks).with_options(duration, 1)


def run(args: argparse.Namespace) -> int:
    """Simulate and write the trial directory; exit 0 on success."""
    scenario = _scenario(args)
    try:
        trial = simulate_trial(scenario, args.seed)
    except TrackError as exc:
        raise UserError(f"--tracks: {exc}") from None
    except ScenarioError as exc:
        raise UserError(f"scenario: {exc}") from None
    out = claim_directory(args.output, args.force)
    written = write_trial(trial, out)
    if not args.quiet:
        r = trial.ranges
        size = sum(p.stat().st_size for p in written)
        print(f"wrote {len(written)} files ({size / 1e6:.2f} MB) to {out}: {len(trial.vehicles)} vehicles, "
              f"{len(trial.buoys)} buoys, {len(r.t_s)} ranges ({int(r.label.sum())} labelled anomalous), "
              f"{len(trial.usbl.t_s)} USBL epochs; manifest {out / 'trial.toml'}", file=sys.stdout)
    for note in trial.notes if not args.quiet else ():
        print(note, file=sys.stdout)
    return 0
