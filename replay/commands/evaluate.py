"""Compare detectors honestly: simulated trials, trained on one seed, scored on the others, closed loop.

Every seed is simulated (the sample trial's scenario, or `--scenario FILE`),
written as vendor logs, recorded and replayed (as `simulate`, `record` and
`replay` do), with every method of the configuration: the logs in a scratch
directory (in memory where the system has /dev/shm, removed after each trial),
the archive in memory only (none is written).
The train seed (default: the first) is never scored. Per method, pooled over the test seeds after t_a: open-loop AUC and
FNR at FPR 1, 2 and 5 %; closed-loop recall per injected anomaly kind among
the epochs labelled anomalous (dropout: none, a dropout leaves no range to
flag); error p50/p90 against GPS. Then the test seeds again with every
scripted drift at each `--drift-rate` (m/s): drift recall per rate and method.
`--training given` (the default) trains every test trial's detectors on what
the train seed's run trained on (its window, and the new methods' hybrid
database), never on the test trial's own window; `both` on the two; `own` on
each test trial's own window (the train seed is then not run).
`--conditions all|FILE` runs the condition matrix instead (replay.run.matrix):
every condition of issue 26 (or of FILE) with and without USBL fixes, the
train seed simulated under each, the test seeds' drifts taking the
`--drift-rate` rates in turn; per condition the label-noise floor and per
method the open-loop AUC and FNR at FPR 1/2/5 % (operating point on the test
ROC, the same for every method), closed-loop FPR and FNR, recall per kind
and drift recall per rate, error p50/p90.
Trials run on a LocalCluster of `--workers` processes (127.0.0.1), on the
scheduler at `--scheduler`, or here one after another with `--workers 1`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from typing import TYPE_CHECKING, Any

from replay.errors import UserError
from replay.run.batch import dask_client, parse_seeds
from replay.run.config import load_config
from replay.run.config_ranges import EVALUATE_MAX_DURATION_S, SEED_MAX, evaluate_max_workers
from replay.run.evaluate import DEFAULT_DRIFT_RATES, evaluate
from replay.run.matrix import evaluate_matrix
from replay.stack.methods import runnable_names
from samples.scenario import ScenarioError, load_scenario

if TYPE_CHECKING:
    from replay.run.evaluate import Evaluation
    from replay.run.matrix import Matrix
    from samples.scenario import Scenario


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay evaluate`."""
    parser.add_argument("--seeds", required=True, metavar="SEEDS",
                        help="simulated trials: 100-109, 3,5,8 or a mix")
    parser.add_argument("--train-seed", type=int, metavar="S", help="the seed trained on, never scored "
                        "(default: the first of --seeds)")
    parser.add_argument("--drift-rate", metavar="R1,R2,...",
                        help="drift rates (m/s) of the sweep (default 0.1,0.2,0.3,0.5,1.0; 'none' for no sweep)")
    parser.add_argument("--training", choices=("given", "both", "own"), default="given",
                        help="what test trials train on: the train seed's set (default), both, or their own window")
    parser.add_argument("-c", "--config", help="replay configuration TOML applied to every trial")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one replay parameter, as for `replay`")
    parser.add_argument("--duration", type=float, metavar="S", help="simulated trial length (default 1700 s)")
    parser.add_argument("--scenario", metavar="FILE",
                        help="scenario TOML for every trial, as for `simulate` (default: the sample trial's)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="a running Dask scheduler (tcp://host:8786); default: a LocalCluster")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                        help="LocalCluster worker processes (one thread each); 1: no Dask, one trial at a time")
    parser.add_argument("--conditions", metavar="all|FILE",
                        help="the condition matrix: issue 26's conditions (all) or FILE's, each with and without USBL")
    parser.add_argument("--json", action="store_true", help="print one JSON object with the figures")


def _rates(text: str | None) -> list[float]:
    """The sweep's drift rates from `--drift-rate`."""
    if text is None:
        return list(DEFAULT_DRIFT_RATES)
    if text.strip().lower() == "none":
        return []
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise UserError(f"--drift-rate {text!r}: expected rates in m/s like 0.1,0.3,0.5") from None


TRAINING_TEXT = {"given": "every test trial on the train seed's training set",
                 "both": "every test trial on the train seed's training set and its own window",
                 "own": "every test trial on its own window (the train seed not run)"}


def _scenario(path: str | None) -> Scenario | None:
    """The `--scenario` file, read and checked here (a bad file is one line, before any trial runs)."""
    if path is None:
        return None
    try:
        return load_scenario(path)
    except OSError as exc:
        raise UserError(f"cannot read scenario {path}: {exc.strerror or exc}") from None
    except ScenarioError as exc:
        raise UserError(f"scenario: {exc}") from None


def _cell(v: Any) -> str:
    return "-" if v is None else f"{v:.3f}"


def text_report(ev: Evaluation) -> str:
    """The figures as two terminal tables and a summary line with the wall time."""
    kinds = ("stale", "drift", "outlier", "dropout")
    head = ["method", "auc", "fnr@1%", "fnr@2%", "fnr@5%", *(f"rec_{k}" for k in kinds), "fpr_closed",
            "err_p50_m", "err_p90_m"]
    rows = [[m, _cell(f["auc"]), _cell(f["fnr_at_fpr_1"]), _cell(f["fnr_at_fpr_2"]), _cell(f["fnr_at_fpr_5"]),
             *(_cell(f["recall_by_kind"][k]) for k in kinds), _cell(ev.closed_loop_fpr.get(m)),
             _cell(f["error_p50_m"]), _cell(f["error_p90_m"])]
            for m, f in ev.methods.items()]
    lines = _table(head, rows)
    if ev.sweep:
        methods = list(dict.fromkeys(r["method"] for r in ev.sweep))
        rates = list(dict.fromkeys(r["rate_mps"] for r in ev.sweep))
        cell = {(r["rate_mps"], r["method"]): r for r in ev.sweep}
        sweep_rows = [[f"{rate:g}", str(max(cell[(rate, m)]["epochs"] for m in methods if (rate, m) in cell)),
                       *(_cell(cell[(rate, m)]["recall"]) if (rate, m) in cell else "-" for m in methods)]
                      for rate in rates]
        lines += ["", "drift recall (closed loop) against drift rate:"]
        lines += _table(["rate_mps", "epochs", *methods], sweep_rows)
    lines += ["", *ev.notes,
              (f"train seed {ev.train_seed}, never scored; test seeds {_seeds(ev.seeds)}; training: "
               f"{TRAINING_TEXT[ev.training]}; {ev.trials} trials simulated, recorded and replayed in "
               f"{ev.wall_s:.1f} s wall ({ev.workers}; {ev.cpu_s:.0f} CPU-s in the scored trials)")]
    return "\n".join(lines)


def _seeds(seeds: tuple[int, ...]) -> str:
    if len(seeds) > 2 and list(seeds) == list(range(seeds[0], seeds[0] + len(seeds))):
        return f"{seeds[0]}-{seeds[-1]}"
    return ",".join(map(str, seeds))


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(head)]
    def line(cells: list[str]) -> str:
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))
    return [line(head), "  ".join("-" * w for w in widths), *(line(r) for r in rows)]


class _Progress:
    """`evaluate: 12/54 trials, 40 s` on stderr, redrawn on a terminal only."""
    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self.t0 = time.monotonic()

    def __call__(self, done: int, total: int) -> None:
        if self.enabled:
            sys.stderr.write(f"\revaluate: {done}/{total} trials, {time.monotonic() - self.t0:.0f} s ")
            if done >= total:
                sys.stderr.write("\n")
            sys.stderr.flush()


MATRIX_DRIFT_RATES = (0.2, 0.3, 0.5)
"""The matrix's drift rates (m/s) unless --drift-rate names others: the slow drifts that are hard."""


def matrix_report(mx: Matrix) -> str:
    """The matrix as one terminal table per condition and a summary line with the wall time."""
    head = ["method", "auc", "fnr@1%", "fnr@2%", "fnr@5%", "fpr_closed", "fnr_closed", "trial_fpr_median",
            "err_p90_m"]
    lines: list[str] = []
    for name, cond in mx.conditions.items():
        rows = []
        for m, f in cond["methods"].items():
            med = _median(mx.trial_fpr.get(name, {}).get(m, []))
            rows.append([m, _cell(f["auc"]), _cell(f["fnr_at_fpr_1"]), _cell(f["fnr_at_fpr_2"]),
                         _cell(f["fnr_at_fpr_5"]), _cell(f["fpr_closed"]), _cell(f["fnr_closed"]), _cell(med),
                         _cell(f["error_p90_m"])])
        lines += [f"{name} (label-noise floor {_cell(cond['label_noise_floor'])}):", *_table(head, rows), ""]
    lines.append(_matrix_time(mx))
    return "\n".join(lines)


def _median(values: list[float | None]) -> float | None:
    known = [v for v in values if v is not None]
    return float(statistics.median(known)) if known else None


def _matrix_time(mx: Matrix) -> str:
    return (f"evaluate: {len(mx.conditions)} conditions, train seed {mx.train_seed}, test seeds {_seeds(mx.seeds)}: "
            f"{mx.trials} trials in {mx.wall_s:.1f} s wall ({mx.workers}; {mx.cpu_s:.0f} CPU-s in the scored trials)")


def _run_matrix(args: argparse.Namespace, seeds: list[int]) -> int:
    config = load_config(args.config, args.set, default_methods=runnable_names())
    rates = MATRIX_DRIFT_RATES if args.drift_rate is None else _rates(args.drift_rate)
    progress = _Progress(not args.json)
    scenario = _scenario(args.scenario)
    if args.scheduler is None and args.workers == 1:
        mx = evaluate_matrix(seeds, config, args.conditions, args.train_seed, rates, args.duration,
                             progress=progress, scenario=scenario)
    else:
        with dask_client(args.scheduler, args.workers) as client:
            mx = evaluate_matrix(seeds, config, args.conditions, args.train_seed, rates, args.duration,
                                 client=client, progress=progress, scenario=scenario)
    if args.json:
        print(json.dumps(mx.to_json(), indent=2))
        # each trial's closed-loop FPR is not in the JSON's fixed shape: its median per condition goes here
        for name, per_method in mx.trial_fpr.items():
            medians = ", ".join(f"{m} {_cell(_median(v))}" for m, v in per_method.items())
            print(f"{name}: median over trials of fpr_closed: {medians}", file=sys.stderr)
        print(_matrix_time(mx), file=sys.stderr)
    else:
        print(matrix_report(mx))
    return 0


def _check_numbers(args: argparse.Namespace) -> None:
    """--train-seed, --duration and --workers within their ranges (replay.run.config_ranges), one line each."""
    if args.train_seed is not None and not 0 <= args.train_seed <= SEED_MAX:
        raise UserError(f"--train-seed {args.train_seed}: expected a seed in [0, {SEED_MAX}]")
    d = args.duration
    if d is not None and not (math.isfinite(d) and 0 < d <= EVALUATE_MAX_DURATION_S):
        raise UserError(f"--duration {d:g}: expected a trial length in (0, {EVALUATE_MAX_DURATION_S:.0f}] s "
                        "(at most a day)")
    most = evaluate_max_workers()
    if args.scheduler is None and not 1 <= args.workers <= most:
        raise UserError(f"--workers {args.workers}: expected 1 to {most} (four processes per core)")


def run(args: argparse.Namespace) -> int:
    """Run the evaluation and print its tables (or the JSON object); 0 on success."""
    seeds = parse_seeds(args.seeds, "--seeds")
    _check_numbers(args)
    if args.conditions is not None:
        return _run_matrix(args, seeds)
    config = load_config(args.config, args.set, default_methods=runnable_names())   # every detector is judged
    rates = _rates(args.drift_rate)
    scenario = _scenario(args.scenario)
    progress = _Progress(not args.json)
    if args.scheduler is None and args.workers == 1:
        ev = evaluate(seeds, config, args.train_seed, rates, args.duration, args.training, progress=progress,
                      scenario=scenario)
    else:
        with dask_client(args.scheduler, args.workers) as client:
            ev = evaluate(seeds, config, args.train_seed, rates, args.duration, args.training, client=client,
                          progress=progress, scenario=scenario)
    if args.json:
        print(json.dumps(ev.to_json(), indent=2))
        print(f"evaluate: {ev.trials} trials in {ev.wall_s:.1f} s wall ({ev.workers}; {ev.cpu_s:.0f} CPU-s in the "
              "scored trials)", file=sys.stderr)
    else:
        print(text_report(ev))
    return 0
