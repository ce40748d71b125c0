"""Give the original log files back from an archive, byte for byte."""

from __future__ import annotations

import argparse
import sys

from recorders.attachments import unpack
from replay.errors import warn_damage


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay unpack`."""
    parser.add_argument("file", help="an MCAP archive")
    parser.add_argument("directory", help="where to write the logs (created if missing)")
    parser.add_argument("--force", action="store_true", help="replace files of the same names in DIRECTORY")


def run(args: argparse.Namespace) -> int:
    """Unpack; exit 1 if any attachment was refused, repeated a name or failed its recorded checksum."""
    result = unpack(args.file, args.directory, replace=args.force)
    for path in result.written:
        print(path)
    for name in result.refused:
        print(f"auvreplay unpack: refused attachment {name!r}: it would land outside {args.directory}",
              file=sys.stderr)
    for name in result.mismatched:
        print(f"auvreplay unpack: {name}: sha256 differs from the one recorded", file=sys.stderr)
    for name in result.incomplete:
        print(f"auvreplay unpack: {name}: bytes missing from the captured stream (written with a gap)",
              file=sys.stderr)
    for name in result.repeated:
        print(f"auvreplay unpack: a second attachment named {name!r}: not written over the first",
              file=sys.stderr)
    warn_damage("unpack", result.warning)
    return 1 if result.refused or result.mismatched or result.incomplete or result.repeated else 0
