"""Two runs side by side: metric differences and the epochs where their detections differ."""

from __future__ import annotations

import argparse
import json

from replay.errors import warn_damage
from replay.run.compare import compare_runs, format_comparison


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay compare`."""
    parser.add_argument("a", help="results archive of run A (from `auvreplay replay -o`)")
    parser.add_argument("b", help="results archive of run B")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--limit", type=int, default=20, help="epochs listed per method (default 20)")


def run(args: argparse.Namespace) -> int:
    """Print the comparison; exit 0 (differences are information, not failure)."""
    result = compare_runs(args.a, args.b)
    if args.json:
        print(json.dumps(result, indent=2, sort_keys=True))
    else:
        print(format_comparison(result, args.limit))
    warn_damage("compare", result["warning"])
    return 0
