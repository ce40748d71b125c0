"""KMCDF benchmarks: one epoch, one Monte Carlo point per method, and the whole Fig. 2.

Prints one table: median wall times over repeats, trials per second, and
ratios (batch per-trial cost against a single epoch; the figure on 2 workers
against the 60 s goal). Run: `.venv/bin/python bench/bench_kmcdf.py [--quick]`.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

# one BLAS thread: threaded LAPACK on 56x56 eigenproblems only spins (set before numpy loads)
for _key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_key, "1")

import numpy as np

from replay.reproduce.kmcdf import reproduce
from replay.stack.positioning.kmcdf import kmcdf_batch, kmcdf_epoch
from replay.stack.positioning.kmcdf_montecarlo import METHODS, node_layout, simulate, success_point


def median_time(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time of `fn` over `repeats` calls, seconds."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bench_epoch(repeats: int) -> float:
    """Median seconds of one N = 6 KMCDF epoch with three abnormal delays."""
    node = node_layout(6)
    sim = simulate(node, 3, repeats, False, np.random.default_rng(0))
    times = []
    for i in range(repeats):
        start = time.perf_counter()
        kmcdf_epoch(node, sim.delays_s[i], sim.phase_x[i], sim.phase_y[i])
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    """Run every benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer repeats, 200-trial figure")
    args = parser.parse_args(argv)
    repeats = 2 if args.quick else 3
    trials = 200 if args.quick else 1000
    rows: list[tuple[str, str, str]] = []

    epoch = bench_epoch(100 if args.quick else 500)
    rows.append(("KMCDF epoch, N = 6, 3 abnormal", f"{epoch * 1e3:.2f} ms", "goal < 2 ms"))
    node = node_layout(6)
    sim = simulate(node, 3, trials, False, np.random.default_rng(1))
    batch = median_time(lambda: kmcdf_batch(node, sim.delays_s, sim.phase_x, sim.phase_y), repeats)
    rows.append((f"KMCDF batch, N = 6, {trials} trials", f"{batch:.3f} s",
                 f"{batch / trials * 1e3:.3f} ms/trial = epoch / {epoch / (batch / trials):.1f}"))
    for method in METHODS:
        t = median_time(lambda m=method: success_point(6, 3, m, trials, 0), repeats)
        rows.append((f"point N = 6, k = 3: {method}", f"{t:.3f} s", f"{trials / t:,.0f} trials/s"))
    for workers in (2, 1):
        start = time.perf_counter()
        reproduce(trials=trials, workers=workers)
        wall = time.perf_counter() - start
        rows.append((f"whole figure, {trials} trials, {workers} worker(s)", f"{wall:.1f} s",
                     f"{wall / 60:.2f} of the 60 s goal"))
    width = max(len(r[0]) for r in rows)
    print(f"{'benchmark':<{width}}  {'median':>10s}  ratio / note")
    for name, value, note in rows:
        print(f"{name:<{width}}  {value:>10s}  {note}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
