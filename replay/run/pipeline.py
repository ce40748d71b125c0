"""Running a replay: archive in, the engine, results MCAP, metrics CSV/JSON and review data out."""

from __future__ import annotations

import csv
import hashlib
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from formats import schemas as S
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from replay.engine.core import Engine, pace
from replay.engine.layout import plan_trial
from replay.errors import UserError
from replay.events import Listener, RunResults
from replay.review.collector import ReviewCollector
from replay.run.config import RunConfig, canonical_json, run_id, to_dict
from replay.run.metrics import format_table, metrics_table, run_metrics
from replay.run.results_writer import ResultsWriter
from replay.stack.training import TrainingSet

SENSORS = ("gps", "ins", "dvl", "modem/range", "usbl")
NS = 1_000_000_000


@dataclass
class RunOutcome:
    """What one replay produced."""

    run_id: str
    metrics: dict[str, Any]
    results: dict[str, RunResults]
    output: Path | None
    notes: list[str]
    wall_s: float
    review: Any = None
    messages: int = 0
    extra: dict[str, Any] = field(default_factory=dict)


def file_sha256(path: str | Path) -> str:
    """sha256 of a file, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def package_version() -> str:
    """The installed auvreplay version."""
    try:
        return metadata.version("auvreplay")
    except metadata.PackageNotFoundError:
        return "0+unknown"


def default_output(archive: str | Path, rid: str) -> Path:
    """<archive stem>-replay-<run id>.mcap in the current directory."""
    return Path(f"{Path(archive).stem}-replay-{rid}.mcap")


def replay_archive(archive: str | Path, config: RunConfig | None = None, output: str | Path | None = None,
                   write_output: bool = True, review: bool = False, listeners: Sequence[Listener] = (),
                   training_set: TrainingSet | None = None) -> RunOutcome:
    """Replay an archive with a configuration; see the module docstring for what comes out.

    `listeners` hear the run too, after the review collector and the results writer;
    `training_set` (another run's `RunResults.training_set`) is what `stack.training_source`
    "given" or "both" trains on.
    """
    config = config or RunConfig()
    sha = file_sha256(archive)
    version = package_version()
    rid = run_id(config, sha, version)
    out_path = Path(output) if output is not None else (default_output(archive, rid) if write_output else None)
    wall0 = time.monotonic()
    with ArchiveReader(archive) as reader:
        summary = reader.summary()
        if not summary.message_count or summary.start_ns is None:
            raise UserError(f"{archive}: the archive holds no messages")
        layout = plan_trial(reader.metadata_json("trial"), {t: v["count"] for t, v in summary.topics.items()})
        t0_ns = summary.start_ns
        topics = [t for t in summary.topics
                  if t == "/diagnostics" or any(t == f"/{v}/{s}" for v in layout.roles for s in SENSORS)]
        window = config.engine.window_s
        start_ns = t0_ns + round(window[0] * NS) if window else None
        end_ns = t0_ns + round(window[1] * NS) + 1 if window else None
        heard: list[Listener] = []
        collector = None
        if review:
            collector = ReviewCollector(rid, reader.metadata_json("trial") or {}, t0_ns, layout)
            heard.append(collector)
        writer = ArchiveWriter(out_path) if out_path is not None else None
        try:
            if writer is not None:
                heard.append(ResultsWriter(writer, rid, t0_ns))
            engine = Engine(layout, config, t0_ns, [*heard, *listeners], training_set)
            for m in reader.messages(topics, start_ns, end_ns):
                engine.push(m.topic, m.log_time_ns, m.message)
                if config.engine.rate > 0:
                    pace(config.engine.rate, wall0, engine.last_s)
            results = engine.finish()
            end_s = max(engine.last_s, 0.0)
            metrics = run_metrics(engine.scores(), results, rid, end_s)
            wall = time.monotonic() - wall0
            metrics["wall_s"] = wall
            if writer is not None:
                _write_run_metadata(writer, config, rid, sha, version, archive, wall, metrics, t0_ns, engine)
                writer.close()
        except BaseException:
            if writer is not None:
                writer.abort()
            raise
        problems = list(reader.problems)
    notes = list(engine.notes) + [f"archive: {p}" for p in problems]
    outcome = RunOutcome(rid, metrics, results, out_path, notes, wall, None, engine.messages)
    if collector is not None:
        outcome.review = collector.finish(metrics)
    if out_path is not None:
        save_metrics(metrics, out_path)
    return outcome


def _write_run_metadata(writer: ArchiveWriter, config: RunConfig, rid: str, sha: str, version: str,
                        archive: Any, wall: float, metrics: dict[str, Any], t0_ns: int, engine: Engine) -> None:
    for note in engine.notes:
        writer.write(f"/replay/{rid}/events", S.Log(timestamp=S.timestamp(t0_ns), level=3, message=note,
                                                    name="engine"), t0_ns)
    writer.add_metadata("run", {
        "run_id": rid, "configuration": canonical_json(config), "package_version": version,
        "input_sha256": sha, "input_file": Path(archive).name, "input_path": str(Path(archive).resolve()),
        "wall_time_s": f"{wall:.3f}",
        "trial_start_ns": str(t0_ns), "metrics": json.dumps(metrics, sort_keys=True),
        "parameters": json.dumps(to_dict(config), sort_keys=True),
    })


def save_metrics(metrics: dict[str, Any], output: Path) -> tuple[Path, Path]:
    """<output>.metrics.csv (one row per method) and <output>.metrics.json."""
    csv_path = output.with_suffix(".metrics.csv")
    json_path = output.with_suffix(".metrics.json")
    rows = metrics_table(metrics)
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["method"])
        w.writeheader()
        w.writerows(rows)
    json_path.write_text(json.dumps(metrics, indent=2, sort_keys=True))
    return csv_path, json_path


__all__ = ["RunOutcome", "format_table", "replay_archive", "save_metrics"]
