"""A results archive back into ReviewData: the run is replayed from its input archive and configuration.

A run is a pure function of (archive, configuration), so re-running it gives
exactly what it showed; the input is found by the run's recorded path or name
(next to the results file, or in the current directory) and checked by sha256.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from formats.mcap_reader import ArchiveReader
from replay.engine.config import RunConfig
from replay.errors import UserError
from replay.review.data import ReviewData
from replay.run.config import config_from_parameters
from replay.run.pipeline import file_sha256, replay_archive


def run_metadata(results: str | Path) -> dict[str, Any] | None:
    """The `run` metadata of a results archive (JSON fields decoded), or None for a trial archive."""
    with ArchiveReader(results) as reader:
        return reader.metadata_json("run")


def _config_from(meta: dict[str, Any]) -> RunConfig:
    params = meta["parameters"] if isinstance(meta["parameters"], dict) else json.loads(meta["parameters"])
    return config_from_parameters(params)


def find_input(results: Path, meta: dict[str, Any], archive: str | Path | None = None) -> Path:
    """The run's input archive: the one given, its recorded path, or its name near the results; sha256-checked."""
    candidates = [Path(archive)] if archive else [
        Path(meta.get("input_path", "")), results.parent / meta.get("input_file", ""), Path(meta.get("input_file", ""))]
    for path in candidates:
        if path.is_file() and path.suffix == ".mcap" and file_sha256(path) == meta["input_sha256"]:
            return path
    raise UserError(f"{results}: cannot find the input archive {meta.get('input_file')!r} of run {meta['run_id']} "
                    f"(sha256 {meta['input_sha256'][:12]}...); give it with --archive")


def review_from_results(results: str | Path, archive: str | Path | None = None) -> ReviewData:
    """ReviewData of the run stored in a results archive."""
    results = Path(results)
    meta = run_metadata(results)
    if meta is None:
        raise UserError(f"{results}: not a replay results archive (no 'run' metadata record)")
    source = find_input(results, meta, archive)
    outcome = replay_archive(source, _config_from(meta), write_output=False, review=True)
    if outcome.run_id != meta["run_id"]:
        outcome.review.metrics["note"] = (f"re-run gives id {outcome.run_id}, stored {meta['run_id']} "
                                          "(another package version)")
    outcome.review.run_id = meta["run_id"]
    outcome.review.input_warning = f"{source}: {outcome.warning}" if outcome.warning else None
    return outcome.review
