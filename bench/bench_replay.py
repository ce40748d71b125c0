"""Replay speed and memory: the sample trial against real time, and a 24 h mission against a 1 h one.

1. The bundled sample trial (1700 s) recorded once, then replayed with the
   default methods (paper A's stack, ANFIS and AQPSO-GA training included),
   median of repeats: the factor over real time (goal: at least 3000x), and the CPU seconds of
   this process and of the children it forked to train detectors (`replay.stack.forked`).
   `--all-methods` adds a row with every method (the new detectors too, as
   `evaluate` and `demo` run them).
2. Synthetic missions (INS 50 Hz, DVL 5 Hz, GPS 1 Hz, ranging 0.4 Hz) of 1 h
   and 24 h, each replayed in a fresh process: peak RSS side by side
   (goal: the 24 h peak within 1.2x of the 1 h peak) and messages/s, beside
   our reader's decode throughput over every topic in the same process
   (goal: replay at least 0.5x of it), by wall and by CPU time.
   `--hours` shortens the long mission for a quick look; `--mission-dir`
   keeps the generated archives there and reuses them; `--against TREE`
   replays each mission with another checkout too (e.g. a `git worktree` of
   main), in alternating order, so both figures come from the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import print_table

# VmHWM, not ru_maxrss: the latter keeps the parent's high-water mark across fork and exec (the decode pass runs
# first, so the peak is at least the reader's)
CHILD = """
import json, sys, time
sys.path.insert(0, {root!r})
from formats.mcap_reader import ArchiveReader
from replay.run.pipeline import replay_archive
t, c = time.perf_counter(), time.process_time()
with ArchiveReader({archive!r}) as reader:
    decoded = sum(1 for _ in reader.messages())     # our reader's decode over every topic: the bound
decode_wall, decode_cpu = time.perf_counter() - t, time.process_time() - c
t, c = time.perf_counter(), time.process_time()
out = replay_archive({archive!r}, output={output!r}, force=True)
wall, cpu = time.perf_counter() - t, time.process_time() - c
hwm = next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM"))
print(json.dumps({{"wall_s": wall, "cpu_s": cpu, "messages": out.messages, "peak_mb": hwm / 1024,
                  "decoded": decoded, "decode_wall_s": decode_wall, "decode_cpu_s": decode_cpu}}))
"""

def timed(fn: Callable[[], object], repeats: int) -> tuple[float, float, float]:
    """Medians over `repeats` calls of fn: wall, CPU of this process, and CPU of the children it forked (the
    detectors trained side by side at t_a). With the cores free, the wall is about this process's CPU plus the
    children's CPU beyond the training it did itself; under load the wall says little, the CPU more."""
    walls, cpus, children = [], [], []
    for _ in range(repeats):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t, c = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - t)
        cpus.append(time.process_time() - c)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        children.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    return statistics.median(walls), statistics.median(cpus), statistics.median(children)


def sample_trial(repeats: int, all_methods: bool = False) -> list[list[object]]:
    """Rows of the sample trial's replay: the default methods, and with `all_methods` every method."""
    from recorders.manifest import load_manifest
    from recorders.record import record
    from replay.engine.config import RunConfig
    from replay.run.config import load_config
    from replay.run.pipeline import replay_archive
    from replay.stack.methods import runnable_names

    configs = [("default methods", RunConfig())]
    if all_methods:
        configs.append(("every method", load_config(default_methods=runnable_names())))
    rows: list[list[object]] = []
    with tempfile.TemporaryDirectory() as d:
        archive = Path(d) / "lake.mcap"
        record(load_manifest(ROOT / "samples/lake_trial/trial.toml"), archive)
        for what, config in configs:
            replay_archive(archive, config, write_output=False)  # warm imports and caches
            # force: every repeat replaces the results the one before wrote in this temporary directory
            wall, cpu, children = timed(
                lambda c=config: replay_archive(archive, c, output=Path(d) / "r.mcap", force=True), repeats)
            rows.append([f"sample trial, {what} (1700 s)", f"{wall:.2f} s", f"{cpu:.2f} s / {children:.2f} s",
                         f"{1700.0 / wall:,.0f}x real time", "goal >= 3000x" if config is configs[0][1] else ""])
        from replay import api

        api.run(archive)       # warm
        wall, cpu, children = timed(lambda: api.run(archive), repeats)
        rows.append(["sample trial, replay.api.run (review data kept)", f"{wall:.2f} s",
                     f"{cpu:.2f} s / {children:.2f} s", f"{1700.0 / wall:,.0f}x real time", "goal >= 3000x"])
    return rows


def mission_archive(hours: float, workdir: Path) -> tuple[Path, int]:
    """The mission archive of `hours` in `workdir`, written unless it is there already; its message count."""
    from mission import write_mission

    from formats.mcap_reader import ArchiveReader

    archive = workdir / f"mission-{hours:g}h.mcap"
    if archive.exists():
        with ArchiveReader(archive) as r:
            return archive, int(r.summary().message_count)
    part = archive.with_suffix(".part")
    n = write_mission(part, hours * 3600.0)
    part.rename(archive)
    return archive, n


def replay_in_child(archive: Path, tree: Path, output: Path) -> dict[str, float]:
    """Replay `archive` with the code of checkout `tree` in a fresh process: wall, messages and peak RSS."""
    code = CHILD.format(root=str(tree), archive=str(archive), output=str(output))
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", PYTHONPATH=str(tree))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True,
                         cwd=tree)
    out: dict[str, float] = json.loads(res.stdout.strip().splitlines()[-1])
    out["size_mb"] = archive.stat().st_size / 1e6
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--hours", type=float, default=24.0, help="length of the long mission (default 24)")
    parser.add_argument("--skip-mission", action="store_true")
    parser.add_argument("--all-methods", action="store_true", help="also replay with every method of the table")
    parser.add_argument("--skip-sample", action="store_true", help="only the missions")
    parser.add_argument("--mission-dir", type=Path, help="keep the mission archives here and reuse them")
    parser.add_argument("--against", type=Path, help="another checkout whose replay runs each mission too")
    args = parser.parse_args()
    if not args.skip_sample:
        print_table(f"Replay of the sample trial (median of {args.repeats})",
                    ["what", "wall", "CPU here / forked", "speed", "goal"],
                    sample_trial(args.repeats, args.all_methods))
    if args.skip_mission:
        return
    trees = {"this tree": ROOT} | ({f"{args.against}": args.against.resolve()} if args.against else {})
    with tempfile.TemporaryDirectory() as d:
        workdir = args.mission_dir or Path(d)
        workdir.mkdir(parents=True, exist_ok=True)
        results: dict[str, dict[float, dict[str, float]]] = {name: {} for name in trees}
        for k, hours in enumerate((1.0, args.hours)):
            archive, n = mission_archive(hours, workdir)
            order = list(trees.items()) if k % 2 == 0 else list(trees.items())[::-1]
            for name, tree in order:
                results[name][hours] = dict(replay_in_child(archive, tree, Path(d) / f"r-{hours:g}h.mcap"),
                                            generated_messages=n)
    rows = [[name, f"{h:g} h", f"{r['generated_messages']:,}", f"{r['size_mb']:.0f} MB", f"{r['wall_s']:.1f} s",
             f"{r['messages'] / r['wall_s']:,.0f}", f"{r['decoded'] / r['decode_wall_s']:,.0f}",
             f"{(r['messages'] / r['wall_s']) / (r['decoded'] / r['decode_wall_s']):.2f}",
             f"{(r['messages'] / r['cpu_s']) / (r['decoded'] / r['decode_cpu_s']):.2f}", f"{r['peak_mb']:.0f} MB"]
            for h in (1.0, args.hours) for name in trees for r in (results[name][h],)]
    print_table("Replay of synthetic missions (INS 50 Hz, DVL 5 Hz), each in a fresh process; the reader's decode "
                "(ArchiveReader.messages, every topic) in the same process",
                ["tree", "mission", "messages", "archive", "replay wall", "msgs/s", "decode msgs/s", "ratio (wall)",
                 "ratio (CPU)", "peak RSS"], rows)
    print("  goal: replay at least 0.5x the reader's decode throughput")
    for name in trees:
        ratio = results[name][args.hours]["peak_mb"] / results[name][1.0]["peak_mb"]
        print(f"  {name}: peak memory {args.hours:g} h / 1 h = {ratio:.2f} (goal <= 1.2): "
              f"{'met' if ratio <= 1.2 else 'NOT met'}")

if __name__ == "__main__":
    main()
