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
from replay.stack.config import ConfigError

# command name -> (module, one-line help). Only the chosen command's module is imported (it imports
# what it needs at its top), so `auvreplay info` does not pay for numpy, pandas, rerun or dask.
COMMANDS: dict[str, tuple[str, str]] = {
    "record": ("replay.commands.record", "archive a trial's logs into one MCAP file"),
    "info": ("replay.commands.info", "what is inside an archive"),
    "capture": ("replay.commands.capture", "live sensor streams into a crash-safe archive as they arrive"),
    "recover": ("replay.commands.recover", "salvage every intact chunk of a damaged archive"),
    "feed": ("replay.commands.feed", "play a recorded trial's logs out as live streams (tests, dry runs)"),
    "replay": ("replay.commands.replay", "replay an archive through every method side by side"),
    "batch": ("replay.commands.batch", "replay many archives under a parameter sweep on Dask (local or a cluster)"),
    "compare": ("replay.commands.compare", "two replay runs side by side"),
    "export": ("replay.commands.export", "one topic to CSV or Parquet, or position tracks to GeoJSON or KML"),
    "report": ("replay.commands.report", "a run's shareable report: one self-contained HTML file"),
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


def chosen_command(argv: list[str]) -> str | None:
    """The command named by the first argument that is not an option, if it is one of COMMANDS."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in COMMANDS else None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The top-level parser: every command listed, the arguments of `command` (or of all, when None)."""
    parser = argparse.ArgumentParser(
        prog="auvreplay",
        description="Record, replay and review multi-AUV cooperative-navigation trials.",
    )
    parser.add_argument("--version", action="version", version=f"auvreplay {package_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, text) in COMMANDS.items():
        if command is not None and name != command:
            sub.add_parser(name, help=text)
            continue
        # the table names the module: a dynamic import, so that only the command run is loaded
        mod = importlib.import_module(module)
        p = sub.add_parser(name, help=text, description=(mod.__doc__ or text).strip())
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, run the command and return its exit code."""
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(chosen_command(argv))
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args._run(args) or 0)
    except (UserError, FormatError, OSError) as exc:
        print(f"auvreplay {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except ConfigError as exc:
        print(f"auvreplay {args.command}: error: configuration: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"auvreplay {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
