"""Run bench scripts on this tree and on another commit, interleaved in one run, to compare their figures.

    python bench/against.py d1ccb81 bench_replay bench_record --rounds 2

The other commit is checked out in a temporary git worktree; each round runs
every named bench once on each tree (alternating which goes first), so both
see the same machine load. The scripts' own tables are printed under a
header naming the tree and round: read the figures side by side.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run_bench(tree: Path, name: str, extra: list[str]) -> str:
    """One bench script of `tree`, with that tree first on the import path; its output.

    A bench newer than the other tree runs from this tree, on the other tree's code (its PYTHONPATH).
    """
    env = dict(os.environ, PYTHONPATH=str(tree))
    script = tree / "bench" / f"{name}.py"
    if not script.is_file():
        script = ROOT / "bench" / f"{name}.py"
    out = subprocess.run([sys.executable, str(script), *extra], cwd=tree, env=env,
                         capture_output=True, text=True)
    return out.stdout + (f"\n[exit {out.returncode}]\n{out.stderr[-2000:]}" if out.returncode else "")


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, run the rounds, print every output under its tree and round."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("ref", help="the commit to compare against, e.g. HEAD~1")
    parser.add_argument("benches", nargs="+", help="bench script names, e.g. bench_replay")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--args", default="", help="extra arguments for every script (one string)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-against-") as tmp:
        other = Path(tmp) / "tree"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(other), args.ref], cwd=ROOT, check=True)
        try:
            trees = {"this": ROOT, args.ref: other}
            for rnd in range(args.rounds):
                order = list(trees.items()) if rnd % 2 == 0 else list(trees.items())[::-1]
                for name in args.benches:
                    for label, tree in order:
                        print(f"\n===== {name} | {label} | round {rnd + 1}", flush=True)
                        print(run_bench(tree, name, args.args.split()), flush=True)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(other)], cwd=ROOT, check=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
