"""`evaluate` throughput: 50 scored trials (and the train seed) on 2 workers, and fewer on 1 worker, trials/s.

The run is `evaluate --seeds 100-110 --train-seed 100 --drift-rate 0.1,0.2,0.3,0.5`: 10 test seeds, each
replayed as scripted and at 4 drift rates (50 scored trials) after the train seed, every runnable method,
1700 s trials. Each trial is simulated, recorded and replayed on a Dask LocalCluster as the command does.
Printed: the cluster's start (the command pays it too), the wall time of `evaluate` itself, the workers'
CPU seconds (their process time before and after), trials per second, the cores the workers got (CPU over
wall: on a shared machine 2 workers cannot beat it), and 2 workers against 1 as trials/s over trials/s
(1 worker runs a smaller set, `--one-worker-seeds`, as the figure per trial is what is compared).
Goal (issue 28): 50 trials in at most 60 s on 2 workers. The load average is printed with the figures.

Run: `.venv/bin/python bench/bench_evaluate.py [--seeds 100-110] [--one-worker-seeds 100-103]`;
beside another revision: `python bench/against.py ae891f7 bench_evaluate --rounds 1` (the bench uses only
`replay.run.evaluate.evaluate` and `replay.run.batch.dask_client`, so it runs on trees that predate it).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# one BLAS thread in this process too, as the workers get
for _key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_key, "1")
if not os.environ.get("PYTHONPATH"):       # bench/against.py names the tree to time in PYTHONPATH
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.common import print_table
from replay.run.batch import dask_client, parse_seeds
from replay.run.config import load_config
from replay.run.evaluate import evaluate
from replay.stack.methods import runnable_names

RATES = (0.1, 0.2, 0.3, 0.5)


def _warm() -> None:
    """Import the pipeline in a worker, so the run times trials, not imports."""
    import replay.run.evaluate  # noqa: F401


def run(seeds: list[int], workers: int) -> dict[str, float]:
    """One `evaluate` on a fresh LocalCluster: start-up, wall, the workers' CPU s, trials (scored + train)."""
    config = load_config(None, [], default_methods=runnable_names())
    t = time.perf_counter()
    with dask_client(None, workers) as client:
        start = time.perf_counter() - t
        client.run(_warm)
        cpu0 = sum(client.run(time.process_time).values())
        w = time.perf_counter()
        ev = evaluate(seeds, config, seeds[0], RATES, client=client)
        wall = time.perf_counter() - w
        cpu = sum(client.run(time.process_time).values()) - cpu0
    return {"start": start, "wall": wall, "cpu": cpu, "trials": float(ev.trials),
            "scored": float(len(ev.seeds) * (1 + len(RATES)))}


def main() -> None:
    """Run 2 workers, then 1 worker, and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100-110", help="seeds of the 2-worker run (the first is the train seed)")
    ap.add_argument("--one-worker-seeds", default="100-103", help="seeds of the 1-worker run ('none': skip it)")
    args = ap.parse_args()
    load0 = os.getloadavg()
    runs = {"2 workers": run(parse_seeds(args.seeds), 2)}
    if args.one_worker_seeds != "none":
        runs["1 worker"] = run(parse_seeds(args.one_worker_seeds), 1)
    load1 = os.getloadavg()
    rows = []
    for name, f in runs.items():
        rows.append((name, int(f["scored"]), int(f["trials"]), f["start"], f["wall"], f["cpu"],
                     f["cpu"] / f["trials"], f["trials"] / f["wall"], f["cpu"] / f["wall"]))
    print_table(f"evaluate, 1700 s trials, every runnable method, drift rates {','.join(map(str, RATES))}; "
                f"load average {load0[0]:.2f} {load0[1]:.2f} before, {load1[0]:.2f} {load1[1]:.2f} after, "
                f"{os.cpu_count()} cores",
                ["workers", "scored", "trials", "cluster start s", "wall s", "workers' CPU s", "CPU s/trial",
                 "trials/s", "cores used"], rows)
    two = runs["2 workers"]
    print(f"  2 workers: {int(two['scored'])} scored trials in {two['wall']:.1f} s wall "
          f"({two['wall'] + two['start']:.1f} s with the cluster's start; goal: 50 in at most 60 s)")
    if "1 worker" in runs:
        one = runs["1 worker"]
        ratio = (two["trials"] / two["wall"]) / (one["trials"] / one["wall"])
        print(f"  2 workers against 1 (trials/s): {ratio:.2f}x; "
              f"cores the 2 workers got: {two['cpu'] / two['wall']:.2f}")


if __name__ == "__main__":
    main()
