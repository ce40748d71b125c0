"""Batch replays on Dask distributed: every archive under every configuration of a sweep.

A batch is a list of tasks (archive x configuration). Each task is a plain,
picklable function call, `replay_task(archive, overrides, out_dir, trial,
config_path)`, that replays one archive into `out_dir/runs/<trial>-<run>.mcap`
and returns a plain dict: the metrics, or the error text when the run failed
(a corrupt archive fails its own runs, never the batch). Tasks run on a Dask
LocalCluster (worker processes, one thread each) or on an existing scheduler;
results are gathered as they complete and assembled in task order, so the
combined table does not depend on the number of workers or on completion
order. Archives, the configuration file and the output directory must be on a
file system the workers share (always true for a LocalCluster).

The simulator's Monte Carlo runs use the same path: `simulate_task` writes and
records one seed's trial, and the replays of that trial depend on its future.

Workers run with one BLAS thread and one training thread (a LocalCluster gets
ONE_THREAD_ENV; Dask's nanny sets the BLAS ones by default,
`distributed.nanny.pre-spawn-environ`, for workers started with `dask worker`;
set AUVREPLAY_TRAINING_THREADS=1 there too) and without Dask's MALLOC_TRIM_THRESHOLD_
(see WORKER_CONFIG; for workers of your own, set
`distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_: null` in their
Dask configuration).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from recorders.manifest import load_manifest
from recorders.record import record
from replay.errors import UserError
from replay.run.config import canonical_json, load_config, run_id
from replay.run.config_ranges import EVALUATE_MAX_SEEDS, SEED_MAX
from replay.run.pipeline import file_sha256, package_version, replay_archive
from replay.stack.scoring import RESULT_KEYS
from samples.scenario import Scenario
from samples.simulator import simulate_trial
from samples.writer import write_trial

if TYPE_CHECKING:
    import pandas as pd
    from distributed import Client

# small linear algebra (2x2 filters, 56x56 KMCDF) only spins with threaded BLAS on 2 cores; a worker
# process per core already uses the cores, so the runner trains its detectors on one thread too
ONE_THREAD_ENV: dict[str, str] = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                                  "AUVREPLAY_TRAINING_THREADS": "1"}
# Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in workers to hand memory back sooner; glibc then trims
# the heap on ANFIS/AQPSO-sized temporaries all the time: +25-40 % CPU per replay (bench_batch). None unsets it.
WORKER_CONFIG: dict[str, Any] = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
LOCAL = "local"
RUN_COLUMNS: tuple[str, ...] = ("trial", "archive", "run_id", "configuration")
COUNT_COLUMNS: tuple[str, ...] = ("epochs", "anomalous", "tp", "tn", "fp", "fn", "capped")
Progress = Callable[[int, int, int], None]          # (done, total, failed)


@dataclass(frozen=True)
class Configuration:
    """One point of a sweep: the swept key=value pairs, in the order the sweeps were given."""
    values: tuple[tuple[str, str], ...] = ()

    @property
    def text(self) -> str:
        """The swept values as `key=value key=value` ('' for the base configuration)."""
        return " ".join(f"{k}={v}" for k, v in self.values)

    def overrides(self) -> list[str]:
        """The swept values as `--set` items."""
        return [f"{k}={v}" for k, v in self.values]


@dataclass(frozen=True)
class BatchTask:
    """One run: an archive under one configuration, and where its results go."""
    trial: str
    archive: str
    configuration: Configuration
    overrides: tuple[str, ...]          # the base --set items, then the swept values
    out_dir: str
    config_path: str | None = None


@dataclass(frozen=True)
class SimulatedSeed:
    """A trial the batch simulates and records before replaying it."""
    seed: int
    duration_s: float | None
    trials_dir: str


def split_values(text: str) -> list[str]:
    """Sweep values: split on ';' when present (values that are lists), else on commas outside brackets."""
    if ";" in text:
        return [v.strip() for v in text.split(";")]
    out, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        depth += (ch in "[(") - (ch in "])")
        if ch == "," and depth == 0:
            out.append(text[start:i].strip())
            start = i + 1
    out.append(text[start:].strip())
    return out


def parse_sweeps(items: Sequence[str]) -> list[tuple[str, list[str]]]:
    """`key=v1,v2,...` items as (key, values); UserError on a malformed item or a repeated key."""
    sweeps: list[tuple[str, list[str]]] = []
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        values = split_values(text)
        if not sep or not key or any(not v for v in values):
            raise UserError(f"--sweep {item!r}: expected key=value1,value2,...")
        if key in {k for k, _ in sweeps}:
            raise UserError(f"--sweep {key}: given twice (give every value in one --sweep)")
        if len(set(values)) != len(values):
            raise UserError(f"--sweep {key}: a value is repeated")
        if key in RUN_COLUMNS + ("method", "error"):
            raise UserError(f"--sweep {key}: not a configuration key")
        sweeps.append((key, values))
    return sweeps


def sweep_configurations(sweeps: Sequence[tuple[str, Sequence[str]]]) -> list[Configuration]:
    """Every combination of the swept values (the first sweep varies slowest); one base point without sweeps."""
    keys = [k for k, _ in sweeps]
    return [Configuration(tuple(zip(keys, combo))) for combo in itertools.product(*(v for _, v in sweeps))]


def parse_seeds(text: str, option: str = "--simulate-seeds", max_count: int = EVALUATE_MAX_SEEDS) -> list[int]:
    """Seeds as `0-19`, `3,5,8` or a mix (`0-3,10`); UserError when malformed, empty, a seed beyond
    [0, SEED_MAX], or more than `max_count` of them (counted before any list is built)."""
    seeds: list[int] = []
    try:
        for part in (p.strip() for p in text.split(",")):
            lo, dash, hi = part.partition("-")
            first, last = (int(lo), int(hi)) if dash else (int(part), int(part))
            if first < 0 or last < first:
                raise ValueError(part)
            if last > SEED_MAX:
                raise UserError(f"{option} {text!r}: seed {last} is beyond {SEED_MAX} (seeds are in [0, 2^32))")
            if len(seeds) + last - first + 1 > max_count:
                raise UserError(f"{option} {text!r}: more than {max_count} seeds (a simulated trial each)")
            seeds.extend(range(first, last + 1))
    except ValueError:
        raise UserError(f"{option} {text!r}: expected seeds like 0-19 or 1,4,7") from None
    if len(set(seeds)) != len(seeds):
        raise UserError(f"{option} {text!r}: a seed is repeated")
    return seeds


def trial_names(archives: Sequence[str | Path], taken: Sequence[str] = ()) -> list[str]:
    """Archive stems, made unique with -2, -3... in the order given (and apart from `taken`)."""
    names: list[str] = []
    for a in archives:
        stem, name, k = Path(a).stem, Path(a).stem, 2
        while name in names or name in taken:
            name, k = f"{stem}-{k}", k + 1
        names.append(name)
    return names


def _check_configurations(config_path: str | None, base: Sequence[str],
                          configs: Sequence[Configuration]) -> None:
    """Load every configuration once here, so a bad key or value stops the batch before any run."""
    seen: dict[str, Configuration] = {}
    for c in configs:
        text = canonical_json(load_config(config_path, [*base, *c.overrides()]))
        if text in seen:
            raise UserError(f"--sweep: {seen[text].text!r} and {c.text!r} are the same configuration")
        seen[text] = c


def plan_batch(archives: Sequence[str | Path], out_dir: str | Path, config_path: str | Path | None = None,
               base_overrides: Sequence[str] = (), sweeps: Sequence[tuple[str, Sequence[str]]] = (),
               trials: Sequence[str] | None = None) -> list[BatchTask]:
    """The task list archives x configurations (archive-major), every configuration checked first."""
    cfg = str(Path(config_path).resolve()) if config_path is not None else None
    if cfg is not None and not Path(cfg).is_file():
        raise UserError(f"{config_path}: no such configuration file")
    configs = sweep_configurations(sweeps)
    _check_configurations(cfg, base_overrides, configs)
    names = list(trials) if trials is not None else trial_names(archives)
    out = str(Path(out_dir).resolve())
    return [BatchTask(name, str(Path(a).resolve()), c, (*base_overrides, *c.overrides()), out, cfg)
            for a, name in zip(archives, names) for c in configs]


def plan_simulated(seeds: Sequence[int], duration_s: float | None, out_dir: str | Path,
                   config_path: str | Path | None = None, base_overrides: Sequence[str] = (),
                   sweeps: Sequence[tuple[str, Sequence[str]]] = (),
                   ) -> tuple[list[BatchTask], dict[str, SimulatedSeed]]:
    """Tasks for simulated seeds: DIR/trials/seed-N (logs) and DIR/trials/seed-N.mcap (archive)."""
    if duration_s is not None and duration_s <= 0:
        raise UserError("--duration must be > 0")
    trials_dir = Path(out_dir).resolve() / "trials"
    archives = [trials_dir / f"seed-{s}.mcap" for s in seeds]
    sims = {str(a): SimulatedSeed(s, duration_s, str(trials_dir)) for a, s in zip(archives, seeds)}
    tasks = plan_batch(archives, out_dir, config_path, base_overrides, sweeps, [f"seed-{s}" for s in seeds])
    return tasks, sims


def replay_task(archive: str, overrides: Sequence[str], out_dir: str, trial: str,
                config_path: str | None = None) -> dict[str, Any]:
    """Worker entry: replay one archive into out_dir/runs/<trial>-<run>.mcap; metrics, or the error text."""
    record: dict[str, Any] = {"trial": trial, "archive": archive, "run_id": "", "output": None,
                              "metrics": None, "error": None, "notes": [], "warning": None}
    try:
        config = load_config(config_path, list(overrides))
        rid = run_id(config, file_sha256(archive), package_version())
        record["run_id"] = rid
        output = Path(out_dir) / "runs" / f"{trial}-{rid}.mcap"
        output.parent.mkdir(parents=True, exist_ok=True)
        # the command claimed DIR's tables, so an earlier batch's runs here are replaced only under --force
        outcome = replay_archive(archive, config, output, force=True)
        record.update(output=str(output), metrics=outcome.metrics, notes=list(outcome.notes), warning=outcome.warning)
    except Exception as exc:  # noqa: BLE001 - a failed run is data for the table; the batch goes on
        record["error"] = describe_error(exc)
    return record


def simulate_task(seed: int, duration_s: float | None, trials_dir: str) -> str:
    """Worker entry: simulate one seed into trials_dir/seed-N, record it; the archive's path."""
    trial_dir = Path(trials_dir) / f"seed-{seed}"
    write_trial(simulate_trial(Scenario().with_options(duration_s, None), seed), trial_dir)
    archive = Path(trials_dir) / f"seed-{seed}.mcap"
    record(load_manifest(trial_dir / "trial.toml"), archive)
    return str(archive)


def describe_error(exc: BaseException) -> str:
    """One line for the table's error column: the exception's type and message."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


@contextmanager
def dask_client(scheduler: str | None = None, workers: int = 2) -> Iterator[Client]:
    """A Dask client: a LocalCluster (None or 'local'; processes, one thread each, 127.0.0.1) or an address."""
    from distributed import Client, LocalCluster

    if scheduler not in (None, LOCAL):
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise UserError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        with client:
            yield client
        return
    if workers < 1:
        raise UserError("--workers must be at least 1")
    import dask

    # no dashboard; the scheduler's own HTTP routes (health, metrics) on a free port of 127.0.0.1
    http = {"dashboard": False, "dashboard_address": "127.0.0.1:0"}
    with dask.config.set(WORKER_CONFIG), \
            LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                         dashboard_address=None, scheduler_kwargs=http, silence_logs=logging.ERROR,
                         env=ONE_THREAD_ENV) as cluster, \
            Client(cluster) as client:
        yield client


def _failed_record(task: BatchTask, exc: BaseException, context: str = "") -> dict[str, Any]:
    """The record of a task whose future failed (its simulation, or a worker that died)."""
    return {"trial": task.trial, "archive": task.archive, "run_id": "", "output": None, "metrics": None,
            "error": context + describe_error(exc), "notes": []}


def run_batch(client: Client, tasks: Sequence[BatchTask], simulate: Mapping[str, SimulatedSeed] | None = None,
              progress: Progress | None = None) -> list[dict[str, Any]]:
    """Run every task on the client; one record per task, in task order, each with its configuration."""
    from distributed import as_completed

    sim_futures = {a: client.submit(simulate_task, s.seed, s.duration_s, s.trials_dir, pure=False)
                   for a, s in (simulate or {}).items()}
    futures = [client.submit(replay_task, sim_futures.get(t.archive, t.archive), list(t.overrides), t.out_dir,
                             t.trial, t.config_path, pure=False) for t in tasks]
    index = {f.key: i for i, f in enumerate(futures)}
    records: list[dict[str, Any] | None] = [None] * len(tasks)
    done = failed = 0
    for fut in as_completed(futures):
        i = index[fut.key]
        try:
            rec = fut.result()
        except Exception as exc:  # noqa: BLE001 - a failed simulation or a dead worker is that run's error
            sim = sim_futures.get(tasks[i].archive)
            rec = _failed_record(tasks[i], exc, "simulating the trial: " if sim is not None and sim.status == "error"
                                 else "")
        records[i] = {**rec, "configuration": tasks[i].configuration}
        done, failed = done + 1, failed + (rec["error"] is not None)
        if progress is not None:
            progress(done, len(tasks), failed)
        fut.release()
    return [r for r in records if r is not None]


def batch_table(records: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """The combined table: one row per run and method (one row with the error for a failed run)."""
    import pandas as pd


    keys = list(dict.fromkeys(k for r in records for k, _ in r["configuration"].values))
    rows: list[dict[str, Any]] = []
    for r in records:
        conf: Configuration = r["configuration"]
        head = {"trial": r["trial"], "archive": r["archive"], "run_id": r["run_id"],
                "configuration": conf.text, **dict(conf.values)}
        m = r["metrics"]
        notes = "; ".join(r.get("notes", ()))
        if m is None:
            rows.append({**head, "method": None, "notes": notes, "error": r["error"]})
            continue
        for method, v in m["methods"].items():
            rows.append({**head, "method": method, "epochs": m["epochs"], "anomalous": m["anomalous"],
                         **{k: v.get(k) for k in RESULT_KEYS}, "capped": v.get("capped"),
                         "wall_s": m.get("wall_s"), "notes": notes, "error": None})
    columns = [*RUN_COLUMNS, *keys, "method", "epochs", "anomalous", *RESULT_KEYS, "capped", "wall_s", "notes", "error"]
    df = pd.DataFrame(rows, columns=columns)
    return _typed(df, keys)


def _typed(df: pd.DataFrame, swept: Sequence[str]) -> pd.DataFrame:
    """Nullable integer counts, float figures, strings elsewhere; swept columns numeric when every value is."""
    import pandas as pd


    for c in COUNT_COLUMNS:
        df[c] = pd.to_numeric(df[c]).astype("Int64")
    for c in (*(k for k in RESULT_KEYS if k not in COUNT_COLUMNS), "wall_s"):
        df[c] = pd.to_numeric(df[c]).astype("float64")
    for c in (*RUN_COLUMNS, "method", "notes", "error"):
        df[c] = df[c].astype("string")
    for c in swept:
        try:
            df[c] = pd.to_numeric(df[c])
        except (ValueError, TypeError):
            df[c] = df[c].astype("string")
    return df


def table_paths(out_dir: str | Path) -> tuple[Path, Path]:
    """The combined tables a batch writes: DIR/metrics.parquet and DIR/metrics.csv."""
    return Path(out_dir) / "metrics.parquet", Path(out_dir) / "metrics.csv"


def save_table(df: pd.DataFrame, out_dir: str | Path) -> tuple[Path, Path]:
    """DIR/metrics.parquet and DIR/metrics.csv."""
    parquet, csv = table_paths(out_dir)
    parquet.parent.mkdir(parents=True, exist_ok=True)
    df.to_parquet(parquet, index=False)
    df.to_csv(csv, index=False)
    return parquet, csv


def summary_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per configuration and method, pooled over trials: runs, confusion counts, FPR, FNR, median error."""
    ok = df[df["error"].isna()]
    if ok.empty:
        import pandas as pd

        return pd.DataFrame(columns=["configuration", "method", "runs"])
    g = ok.groupby(["configuration", "method"], sort=False)
    out = g.agg(runs=("run_id", "size"), tp=("tp", "sum"), fp=("fp", "sum"), tn=("tn", "sum"), fn=("fn", "sum"),
                error_p50_m=("error_p50_m", "median"), error_p90_m=("error_p90_m", "median"))
    detecting = g["tp"].count() > 0
    out["fpr"] = (out["fp"] / (out["fp"] + out["tn"])).where(detecting)
    out["fnr"] = (out["fn"] / (out["fn"] + out["tp"])).where(detecting)
    for c in ("tp", "fp", "tn", "fn"):
        out[c] = out[c].where(detecting)
    return out.reset_index()


def batch(archives: Sequence[str | Path], out_dir: str | Path, config_path: str | Path | None = None,
          base_overrides: Sequence[str] = (), sweeps: Sequence[tuple[str, Sequence[str]]] = (),
          seeds: Sequence[int] = (), duration_s: float | None = None, client: Client | None = None,
          scheduler: str | None = None, workers: int = 2, progress: Progress | None = None,
          ) -> tuple[pd.DataFrame, list[dict[str, Any]]]:
    """Plan, run and save a whole batch (archives and/or simulated seeds); the table and the run records."""
    missing = [str(a) for a in archives if not Path(a).is_file()]
    if missing:
        raise UserError(f"no such archive: {', '.join(missing)}")
    names = trial_names(archives, [f"seed-{s}" for s in seeds])
    tasks = plan_batch(archives, out_dir, config_path, base_overrides, sweeps, names)
    sim_tasks, sims = plan_simulated(seeds, duration_s, out_dir, config_path, base_overrides, sweeps) \
        if seeds else ([], {})
    if not tasks and not sim_tasks:
        raise UserError("nothing to run: give archives or --simulate-seeds")
    if client is None:
        with dask_client(scheduler, workers) as own:
            records = run_batch(own, [*tasks, *sim_tasks], sims, progress)
    else:
        records = run_batch(client, [*tasks, *sim_tasks], sims, progress)
    df = batch_table(records)
    save_table(df, out_dir)
    return df, records


__all__ = ["BatchTask", "Configuration", "SimulatedSeed", "batch", "batch_table", "dask_client", "parse_seeds",
           "parse_sweeps", "plan_batch", "plan_simulated", "replay_task", "run_batch", "save_table",
           "simulate_task", "summary_table", "sweep_configurations", "trial_names"]
