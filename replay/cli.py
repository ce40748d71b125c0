"""The `auvreplay` command line: a table of commands, each a module with add_arguments/run.

Exit codes: 0 success, 1 bad input, 2 usage.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from importlib.metadata import PackageNotFoundError, version

from formats.records import FormatError
from replay.errors import UserError

# command name -> (module, one-line help); modules are imported to build the parser,
# so their top level stays light (heavy imports go inside run)
COMMANDS: dict[str, tuple[str, str]] = {
    "record": ("replay.commands.record", "archive a trial's logs into one MCAP file"),
    "info": ("replay.commands.info", "what is inside an archive"),
    "replay": ("replay.commands.replay", "replay an archive through every method side by side"),
    "batch": ("replay.commands.batch", "replay many archives under a parameter sweep on Dask (local or a cluster)"),
    "compare": ("replay.commands.compare", "two replay runs side by side"),
    "export": ("replay.commands.export", "one topic to CSV or Parquet"),
    "unpack": ("replay.commands.unpack", "the original logs back, byte for byte"),
    "formats": ("replay.commands.formats", "the vendor formats supported"),
    "view": ("replay.commands.view", "open a recording (.rrd) or an archive (.mcap) in Rerun"),
    "demo": ("replay.commands.demo", "the whole job on the sample trial"),
    "simulate": ("replay.commands.simulate", "write a synthetic lake trial: vendor logs, manifest, truth"),
    "reproduce": ("replay.commands.reproduce", "the papers' tables and figures (anfis, kmcdf)"),
    "evaluate": ("replay.commands.evaluate", "compare detectors: simulated trials, train on one, test on the others"),
}


def package_version() -> str:
    """The installed auvreplay version."""
    try:
        return version("auvreplay")
    except PackageNotFoundError:
        return "0+unknown"


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every command's subparser."""
    parser = argparse.ArgumentParser(
        prog="auvreplay",
        description="Record, replay and review multi-AUV cooperative-navigation trials.",
    )
    parser.add_argument("--version", action="version", version=f"auvreplay {package_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, text) in COMMANDS.items():
        mod = importlib.import_module(module)
        p = sub.add_parser(name, help=text, description=(mod.__doc__ or text).strip())
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, run the command and return its exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args._run(args) or 0)
    except (UserError, FormatError, OSError) as exc:
        print(f"auvreplay {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"auvreplay {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
