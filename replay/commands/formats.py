"""List the vendor formats the recorder reads, per sensor family."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay formats`."""
    parser.add_argument("--json", action="store_true", help="print a JSON object: sensor -> formats")


def run(args: argparse.Namespace) -> int:
    """Print the (sensor, format) table with a line of description each."""
    import json

    from recorders.registry import converters, describe

    table = converters()
    if args.json:
        out: dict[str, dict[str, str]] = {}
        for (sensor, fmt), fn in sorted(table.items()):
            out.setdefault(sensor, {})[fmt] = describe(fn)
        print(json.dumps(out, indent=2))
        return 0
    print(f"{'sensor':<7} {'format':<12} description")
    for (sensor, fmt), fn in sorted(table.items()):
        print(f"{sensor:<7} {fmt:<12} {describe(fn)}")
    return 0
