"""Running a replay: archive in, the engine, results MCAP, metrics CSV/JSON and review data out."""

from __future__ import annotations

import csv
import hashlib
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from formats import schemas as S
from formats.mcap_blocks import COLUMN_FIELDS
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from formats.units import NS
from replay.engine.config import RunConfig
from replay.engine.core import Engine, pace
from replay.engine.layout import TrialLayout, plan_trial
from replay.errors import UserError
from replay.events import Listener, RunResults
from replay.navigation.review import NavigationReview, review_metrics
from replay.navigation.stream import StreamCollector
from replay.review.collector import ReviewCollector
from replay.run.config import canonical_json, run_id, to_dict
from replay.run.heap import fix_mmap_threshold
from replay.run.metrics import format_table, metrics_table, run_metrics
from replay.run.outputs import claim_outputs
from replay.run.results_writer import ResultsWriter
from replay.stack.training import TrainingSet

SENSORS = ("gps", "ins", "dvl", "modem/range", "usbl")
# the schema each topic the engine reads must have (an archive from elsewhere may say otherwise)
SENSOR_SCHEMAS = {"gps": "foxglove.LocationFix", "ins": "auvreplay.InsState", "dvl": "auvreplay.DvlVelocity",
                  "modem/range": "auvreplay.AcousticRange", "usbl": "auvreplay.UsblObservation"}
DIAGNOSTICS_SCHEMA = "foxglove.Log"
# the schemas of a position: every topic of one is a track (GPS fixes, INS and autopilot solutions, node reports)
POSITION_SCHEMAS = ("foxglove.LocationFix", "auvreplay.InsState")
ROLES = ("leader", "follower", "buoy")


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
    warning: str | None = None  # one line: what the archive reader skipped (None: nothing)


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


def trial_metadata(raw: Any) -> dict[str, Any] | None:
    """The archive's `trial` metadata with only vehicles of the recorded shape (a name, a known role or none)."""
    if not isinstance(raw, dict):
        return None
    vehicles = raw.get("vehicles")
    keep = [v for v in (vehicles if isinstance(vehicles, list) else [])
            if isinstance(v, dict) and isinstance(v.get("name"), str) and v.get("role") in ROLES + ("", None)]
    return {**raw, "vehicles": keep}


def _readable_topics(summary: Any, reader: ArchiveReader) -> dict[str, int]:
    """Topic -> count, less the sensor topics whose schema is not the one the engine reads (counted as skipped)."""
    topics = {}
    for t, v in summary.topics.items():
        parts = t.strip("/").split("/", 1)
        want = DIAGNOSTICS_SCHEMA if t == "/diagnostics" else (
            SENSOR_SCHEMAS.get(parts[1]) if len(parts) == 2 else None)
        if want is not None and v["schema"] != want:
            if v["count"]:
                reader.damage.messages[(t, f"of schema {v['schema'][:60]!r}, not {want}")] += v["count"]
            continue
        topics[t] = v["count"]
    return topics


def replay_archive(archive: str | Path | bytes, config: RunConfig | None = None, output: str | Path | None = None,
                   write_output: bool = True, review: bool = False, force: bool = False,
                   listeners: Sequence[Listener] = (), training_set: TrainingSet | None = None,
                   require_work: bool = False, blocks: bool = True,
                   on_block: Callable[[ReviewCollector | None, float], None] | None = None,
                   nav_review: bool = True) -> RunOutcome:
    """Replay an archive with a configuration; see the module docstring for what comes out.

    The results archive and its metrics files are claimed (replay.run.outputs) before the run:
    an existing one is refused unless `force`. `listeners` hear the run too, after the review
    collector and the results writer; `training_set` (another run's `RunResults.training_set`) is
    what `stack.training_source` "given" or "both" trains on. With `require_work`, a trial that
    holds no position of any kind is a UserError naming why, and writes nothing; any other trial
    runs what its inputs allow (metrics["skipped"] names the rest). `blocks=False` feeds the engine message by
    message (as `--rate` pacing does), the reference the block path is tested against. `on_block`, when given,
    is called after each block (each message when fed message by message) with the review collector (None
    without `review`) and the mission seconds the engine reached: `view` streams what was collected so far.
    An archive given as its bytes (`evaluate`) is replayed the same, with no output written. `nav_review=False`
    leaves out the vehicles' navigation reviews (metrics["navigation"] empty), which `evaluate` never reads.
    """
    config = config or RunConfig()
    in_memory = isinstance(archive, bytes)
    if in_memory and (write_output or output is not None):
        raise ValueError("an archive given as bytes is replayed with write_output=False and no output")
    sha = hashlib.sha256(archive).hexdigest() if isinstance(archive, bytes) else file_sha256(archive)
    label: str | Path = "<bytes>" if in_memory else archive  # type: ignore[assignment]
    version = package_version()
    id_input = sha
    if training_set is not None and config.stack.training_source != "own":
        # the detectors trained on the given set: another set is another run (the archive's purity rule)
        id_input = hashlib.sha256(f"{sha}\ntraining set {training_set.digest()}".encode()).hexdigest()
    rid = run_id(config, id_input, version)
    out_path = Path(output) if output is not None else (default_output(label, rid) if write_output else None)
    if out_path is not None:
        claim_outputs(results_paths(out_path), force)
    wall0 = time.monotonic()
    with ArchiveReader(archive) as reader:
        summary = reader.summary()
        if not summary.message_count or summary.start_ns is None:
            raise UserError(_nothing_to_run(label, "the archive holds no messages", [], reader))
        trial = trial_metadata(reader.metadata_json("trial"))
        readable = _readable_topics(summary, reader)
        positions = [t for t, v in summary.topics.items() if v["schema"] in POSITION_SCHEMAS]
        layout = plan_trial(trial, readable, config.stack.methods, positions)
        if require_work and not _holds_position(archive, layout):
            raise UserError(_nothing_to_run(label, "the trial holds no position of any kind (no GPS fix and no "
                                            "INS or autopilot position)", layout.notes, reader))
        t0_ns = summary.start_ns
        # an hour of mission or more: its freed blocks go back to the system (replay.run.heap)
        fix_mmap_threshold((summary.end_ns - t0_ns) / NS if summary.end_ns is not None else 0.0)
        topics = [t for t in readable if t == "/diagnostics" or t in layout.sources
                  or any(t == f"/{v}/{s}" for v in layout.roles for s in SENSORS)]
        window = config.engine.window_s
        start_ns = t0_ns + round(window[0] * NS) if window else None
        end_ns = t0_ns + round(window[1] * NS) + 1 if window else None
        heard: list[Listener] = []
        collector = None
        if review:
            collector = ReviewCollector(rid, trial or {}, t0_ns, layout,
                                        to_dict(config))
            heard.append(collector)
        writer = ArchiveWriter(out_path, replace=force) if out_path is not None else None
        try:
            if writer is not None:
                heard.append(ResultsWriter(writer, rid, t0_ns))
            engine = Engine(layout, config, t0_ns, [*heard, *listeners], training_set)
            # each vehicle's own navigation review is computed in the same pass, stretch by stretch (bounded memory)
            nav_columns = StreamCollector([v for v in layout.roles if layout.has(v, "dvl") or layout.has(v, "ins")],
                                          t0_ns)
            topics += [t for t in nav_columns.topics if t in readable and t not in topics]
            if config.engine.rate > 0 or not blocks:
                # message by message: --rate paces each one (and the block path's reference)
                for m in reader.messages(topics, start_ns, end_ns):
                    engine.push(m.topic, m.log_time_ns, m.message)
                    if nav_review:
                        nav_columns.add(m.topic, m.log_time_ns, m.message)
                    if on_block is not None:
                        on_block(collector, engine.last_s)
                    if config.engine.rate > 0:
                        pace(config.engine.rate, wall0, engine.last_s)
            else:
                # a time window at a time, INS, DVL and GPS as columns (replay.engine.blocks: the same results)
                columnar = [t for t in topics if summary.topics[t]["schema"] in COLUMN_FIELDS]
                for block in reader.blocks(topics, start_ns, end_ns, columnar):
                    engine.push_block(block)
                    if nav_review:
                        nav_columns.add_block(block)
                    if on_block is not None:
                        on_block(collector, engine.last_s)
            results = engine.finish()
            end_s = max(engine.last_s, 0.0)
            metrics = run_metrics(engine.scores(), results, rid, end_s)
            # the reviews are kept only for the views
            navigation: dict[str, NavigationReview] = {}
            metrics["navigation"] = {}
            for v in nav_columns.vehicles if nav_review else ():
                nav = nav_columns.review(v)
                metrics["navigation"][v] = review_metrics(nav)
                if collector is not None:
                    navigation[v] = nav
                del nav
            wall = time.monotonic() - wall0
            metrics["wall_s"] = wall
            if writer is not None:
                write_run_metadata(writer, config, rid, sha, version, archive, wall, metrics, t0_ns, engine)
                writer.close()
        except BaseException:
            if writer is not None:
                writer.abort()
            raise
        problems = list(reader.problems)
        refused = record_time_refusals(reader.metadata_json("recording"))
        warning = reader.warning()
    notes = list(engine.notes) + ([refused] if refused else []) + [f"archive: {p}" for p in problems]
    outcome = RunOutcome(rid, metrics, results, out_path, notes, wall, None, engine.messages, warning=warning)
    if collector is not None:
        outcome.review = collector.finish(metrics, navigation)
    if out_path is not None:
        save_metrics(metrics, out_path)
    return outcome


def record_time_refusals(recording: Any) -> str | None:
    """One note: the ranges and other values `record` refused as out of range (recording metadata), or None."""
    files = recording.get("files") if isinstance(recording, dict) else None
    counts = [(f.get("bad_ranges"), f.get("out_of_range")) for f in (files if isinstance(files, list) else [])
              if isinstance(f, dict)]
    ranges = sum(r for r, _ in counts if isinstance(r, int))
    values = sum(v for _, v in counts if isinstance(v, int))
    if not values:
        return None
    return (f"record time: {ranges} ranges refused (not above 0 m, or beyond max_range_m) and "
            f"{values - ranges} other values out of range; they are not in the archive")


def _holds_position(archive: str | Path | bytes, layout: TrialLayout) -> bool:
    """Whether a vehicle of the trial has a position: GPS fixes, another position source, or an INS state with a
    finite latitude and longitude (an IMU's or an autopilot's attitude-only states, as a tlog without
    GLOBAL_POSITION_INT gives, are no position). A reader of its own: the replay's damage counts stay its own."""
    vehicles = layout.positions()
    if layout.sources or any(layout.has(v, "gps") for v in vehicles):
        return True
    with ArchiveReader(archive) as reader:
        return any(math.isfinite(m.message.latitude) and math.isfinite(m.message.longitude)
                   for m in reader.messages([f"/{v}/ins" for v in vehicles]))


def _nothing_to_run(archive: Any, what: str, notes: list[str], reader: ArchiveReader) -> str:
    """One line: the archive, that nothing ran and why (the first notes, and the archive's damage)."""
    why = "; ".join(dict.fromkeys(notes[:3]))
    damage = reader.warning()
    return (f"{archive}: nothing to replay: {what}" + (f" ({why})" if why else "")
            + (f"; archive: {damage}" if damage else ""))


def write_run_metadata(writer: ArchiveWriter, config: RunConfig, rid: str, sha: str, version: str,
                        archive: Any, wall: float, metrics: dict[str, Any], t0_ns: int, engine: Engine) -> None:
    """The run's notes as events and its `run` metadata record (parameters, version, input hash, metrics)."""
    for note in engine.notes:
        writer.write(f"/replay/{rid}/events", S.Log(timestamp=S.timestamp(t0_ns), level=S.Log.WARNING, message=note,
                                                    name="engine"), t0_ns)
    writer.add_metadata("run", {
        "run_id": rid, "configuration": canonical_json(config), "package_version": version,
        "input_sha256": sha, "input_file": Path(archive).name, "input_path": str(Path(archive).resolve()),
        "wall_time_s": f"{wall:.3f}",
        "trial_start_ns": str(t0_ns), "metrics": json.dumps(metrics, sort_keys=True),
        "parameters": json.dumps(to_dict(config), sort_keys=True),
    })


def results_paths(output: Path) -> tuple[Path, Path, Path]:
    """The files a run with results archive `output` writes: the archive, <output>.metrics.csv and .json."""
    return output, output.with_suffix(".metrics.csv"), output.with_suffix(".metrics.json")


def save_metrics(metrics: dict[str, Any], output: Path) -> tuple[Path, Path]:
    """<output>.metrics.csv (one row per method) and <output>.metrics.json."""
    _, csv_path, json_path = results_paths(output)
    rows = metrics_table(metrics)
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["method"])
        w.writeheader()
        w.writerows(rows)
    json_path.write_text(json.dumps(metrics, indent=2, sort_keys=True))
    return csv_path, json_path


__all__ = ["RunOutcome", "format_table", "replay_archive", "results_paths", "save_metrics", "write_run_metadata"]
