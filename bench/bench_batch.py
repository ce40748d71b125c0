"""Batch replays on Dask: 16 sample-trial replays in-process, on 1 worker and on 2 workers; task overhead.

Prints two tables:
- the batch: wall time of N replays of the sample trial (one sweep of the
  stack seed, so every run is a distinct configuration) run in this process
  one after another, through a 1-worker and a 2-worker LocalCluster (cluster
  already started and the stack imported in each worker; both start-ups are
  their own rows), and ratios: speed-up of 2 workers over 1 (goal: at least
  1.7x), the Dask cost per real task (1 worker against in-process, divided by
  N), and the cores the workers actually got (their CPU seconds over the
  wall time: on a shared machine the speed-up cannot beat it);
- the scheduling overhead of a trivial task: direct call, one task's round
  trip (submit, wait), and per task over a burst of submitted tasks.

The machine is shared: the load average is printed with the figures.
Run: `.venv/bin/python bench/bench_batch.py [--replays 16] [--repeats 3] [--fast]`.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

# one BLAS thread in this process too, as the workers get: the comparison is like for like
for _key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_key, "1")

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.common import median_time, print_table
from recorders.manifest import load_manifest
from recorders.record import record
from replay.run.batch import dask_client, plan_batch, replay_task, run_batch

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
FAST = ["methods=dead_reckoning,ckf,ackf,chi_square"]


def noop(x: int) -> int:
    """The trivial task."""
    return x


def bench_batch(archive: Path, out: Path, replays: int, repeats: int, base: list[str]) -> dict[str, float]:
    """Median wall and CPU seconds of the in-process loop and of the batch on 1 and 2 workers, interleaved.

    The three ways take turns in every repeat (rotating which goes first), so
    load that other users put on the machine falls on all of them alike.
    """
    tasks = plan_batch([archive], out, base_overrides=base, sweeps=[("seed", [str(s) for s in range(replays)])])
    figures: dict[str, float] = {}
    with contextlib.ExitStack() as stack:
        clients = {}
        for workers in (1, 2):
            t = time.perf_counter()
            clients[workers] = stack.enter_context(dask_client(None, workers))
            figures[f"start{workers}"] = time.perf_counter() - t
            t = time.perf_counter()
            clients[workers].run(_warm)
            figures[f"warm{workers}"] = time.perf_counter() - t
        _warm()
        runs: dict[str, list[tuple[float, float]]] = {"serial": [], "dask1": [], "dask2": []}
        for r in range(repeats):
            for name in list(runs)[r % 3:] + list(runs)[:r % 3]:
                runs[name].append(_serial(tasks) if name == "serial" else _on_dask(clients[int(name[-1])], tasks))
    for name, values in runs.items():
        figures[name] = statistics.median(w for w, _ in values)
        figures[f"cpu_{name}"] = statistics.median(c for _, c in values)
    return figures


def _serial(tasks: list) -> tuple[float, float]:
    """(wall s, CPU s) of the tasks run one after another in this process."""
    w, c = time.perf_counter(), time.process_time()
    for t in tasks:
        assert replay_task(t.archive, t.overrides, t.out_dir, t.trial)["error"] is None
    return time.perf_counter() - w, time.process_time() - c


def _on_dask(client, tasks: list) -> tuple[float, float]:
    """(wall s, the workers' CPU s) of the tasks through `run_batch`."""
    cpu0 = sum(client.run(time.process_time).values())
    w = time.perf_counter()
    records = run_batch(client, tasks)
    wall = time.perf_counter() - w
    assert all(r["error"] is None for r in records), [r["error"] for r in records]
    return wall, sum(client.run(time.process_time).values()) - cpu0


def _warm() -> None:
    """Import the replay stack in a worker, so the batch times replays, not imports."""
    import replay.run.pipeline  # noqa: F401


def bench_overhead(burst: int, repeats: int) -> list[tuple[str, float, float]]:
    """(what, microseconds per task on 1 worker, on 2 workers) for a trivial task."""
    direct = median_time(lambda: [noop(i) for i in range(burst)], repeats) / burst
    rows: dict[str, list[float]] = {"direct call": [direct, direct], "one task, submit and wait": [],
                                    f"burst of {burst} (submit all, gather)": [],
                                    f"burst of {burst} (as_completed)": []}
    for workers in (1, 2):
        with dask_client(None, workers) as client:
            from distributed import as_completed

            client.gather(client.map(noop, range(50), pure=False))
            rows["one task, submit and wait"].append(
                median_time(lambda: client.submit(noop, 1, pure=False).result(), 50))
            rows[f"burst of {burst} (submit all, gather)"].append(
                median_time(lambda: client.gather(client.map(noop, range(burst), pure=False)), repeats) / burst)
            rows[f"burst of {burst} (as_completed)"].append(
                median_time(lambda: [f.result() for f in as_completed(
                    [client.submit(noop, i, pure=False) for i in range(burst)])], repeats) / burst)
    return [(k, v[0] * 1e6, v[1] * 1e6) for k, v in rows.items()]


def main() -> None:
    """Run both benchmarks and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replays", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3, help="repeats of each whole batch (median)")
    ap.add_argument("--burst", type=int, default=500)
    ap.add_argument("--fast", action="store_true", help="four methods instead of all eight")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        archive = Path(tmp) / "lake.mcap"
        record(load_manifest(SAMPLE / "trial.toml"), archive)
        load0 = os.getloadavg()[0]
        f = bench_batch(archive, Path(tmp) / "out", args.replays, args.repeats, FAST if args.fast else [])
        load1 = os.getloadavg()[0]
    n = args.replays
    methods = "4 methods" if args.fast else "all methods"
    print_table(f"{n} replays of the sample trial ({methods}), median of {args.repeats} interleaved; "
                f"load average {load0:.2f} before, {load1:.2f} after, {os.cpu_count()} cores",
                ["how", "wall s", "s per replay", "CPU s per replay", "cores used", "vs in-process",
                 "vs 1 worker"],
                [("in-process loop", f["serial"], f["serial"] / n, f["cpu_serial"] / n,
                  f["cpu_serial"] / f["serial"], 1.0, "-"),
                 ("Dask, 1 worker", f["dask1"], f["dask1"] / n, f["cpu_dask1"] / n, f["cpu_dask1"] / f["dask1"],
                  f["serial"] / f["dask1"], 1.0),
                 ("Dask, 2 workers", f["dask2"], f["dask2"] / n, f["cpu_dask2"] / n, f["cpu_dask2"] / f["dask2"],
                  f["serial"] / f["dask2"], f["dask1"] / f["dask2"]),
                 ("cluster start, 1 worker", f["start1"], "-", "-", "-", "-", "-"),
                 ("cluster start, 2 workers", f["start2"], "-", "-", "-", "-", "-"),
                 ("imports in each worker", f["warm2"], "-", "-", "-", "-", "-")])
    print(f"  speed-up 2 workers over 1: {f['dask1'] / f['dask2']:.2f}x (goal 1.7x); "
          f"Dask cost per real task (1 worker - in-process) / {n}: {(f['dask1'] - f['serial']) / n * 1e3:+.0f} ms")
    print("  cores used = CPU s / wall s of the processes doing the replays: with other load on the machine "
          "the speed-up cannot exceed the ratio of the cores the workers got")
    rows = bench_overhead(args.burst, max(args.repeats, 3))
    print_table("Scheduling overhead of a trivial task (microseconds per task, median)",
                ["what", "1 worker", "2 workers"], rows)


if __name__ == "__main__":
    main()
