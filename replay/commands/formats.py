"""List the vendor formats the recorder reads, per sensor family."""

from __future__ import annotations

import argparse

from recorders.registry import converters, describe, manifest_examples


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay formats`."""
    parser.add_argument("--json", action="store_true", help="print a JSON object: sensor -> formats")


def run(args: argparse.Namespace) -> int:
    """Print the (sensor, format) table with a line of description each."""
    import json


    table = converters()
    if args.json:
        out: dict[str, dict[str, str]] = {}
        for (sensor, fmt), fn in sorted(table.items()):
            out.setdefault(sensor or "any", {})[fmt] = describe(fn)  # containers: no sensor key, "any"
        print(json.dumps(out, indent=2))
        return 0
    print(f"{'sensor':<7} {'format':<12} description")
    for (sensor, fmt), fn in sorted(table.items()):
        print(f"{sensor or 'any':<7} {fmt:<12} {describe(fn)}")
    print("\nContainers ('any': several sensors in one file, no `sensor` key); a manifest entry each:")
    for fmt, example in manifest_examples().items():
        print(f"\n# {fmt}\n{example.strip()}")
    print("\nAny log may be rotated or split: path = \"gps.log.*\" (a glob, name order) or a list of paths;"
          " order = \"time\" sorts the files by their first record time.")
    return 0
