"""A results archive back into ReviewData: the run is replayed from its input archive and configuration.

A run is a pure function of (archive, configuration), so re-running it gives
exactly what it showed; the input is found by the run's recorded path or name
(next to the results file, or in the current directory) and checked by sha256.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

from formats.mcap_reader import ArchiveReader
from replay.engine.config import RunConfig
from replay.errors import UserError
from replay.review.data import ReviewData
from replay.run.config import config_from_parameters
from replay.run.pipeline import file_sha256, replay_archive


def run_metadata(results: str | Path) -> dict[str, Any] | None:
    """The `run` metadata of a results archive, checked (see `checked_run_metadata`), or None for a trial archive."""
    with ArchiveReader(results) as reader:
        raw = reader.metadata("run")
    return None if raw is None else checked_run_metadata(raw, results)


# A results archive may come from anyone: its `run` record is checked before anything reads it. A record that
# cannot describe a run (a missing or malformed id, hash, metrics or parameters) is refused in one line; a single
# value of the wrong kind inside the metrics is left out and counted (meta["skipped_values"]).
_RUN_ID = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")
_SHA256 = re.compile(r"^[0-9a-f]{64}$")
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
_TEXT_MAX = 4096
_INT_MAX = 2**63 - 1
_COUNTS = ("epochs", "anomalous", "usbl_epochs")


def _decode(text: str) -> Any:
    try:
        return json.loads(text)
    except (ValueError, RecursionError):
        return text


def _text(value: Any) -> str | None:
    """A string fit for a report: bounded, no control characters (a line break in a name is not one)."""
    return value if isinstance(value, str) and len(value) <= _TEXT_MAX and not _CONTROL.search(value) else None


def _number(value: Any) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return abs(value) <= _INT_MAX if isinstance(value, int) else True


def _count(value: Any) -> bool:
    return _number(value) and isinstance(value, int) and value >= 0


class _Cleaner:
    """The metrics of a run with every value of the wrong kind left out, counted."""

    def __init__(self) -> None:
        self.skipped = 0

    def _drop(self) -> None:
        self.skipped += 1

    def figures(self, row: Any, strings: bool = False) -> dict[str, Any] | None:
        if not isinstance(row, dict):
            self._drop()
            return None
        out: dict[str, Any] = {}
        for k, v in row.items():
            if v is None or _number(v) or (strings and _text(v) is not None):
                out[k] = v
            else:
                self._drop()
        return out

    def table(self, value: Any, strings: bool = False) -> dict[str, dict[str, Any]]:
        if value is None:
            return {}
        if not isinstance(value, dict):
            self._drop()
            return {}
        out = {}
        for name, row in value.items():
            figures = self.figures(row, strings) if _text(name) is not None else None
            if figures is None:
                if _text(name) is None:
                    self._drop()
                continue
            out[name] = figures
        return out

    def texts(self, value: Any) -> list[str]:
        if value is None:
            return []
        items = value if isinstance(value, list) else []
        if not isinstance(value, list):
            self._drop()
        kept = [v for v in items if _text(v) is not None]
        self.skipped += len(items) - len(kept)
        return kept

    def metrics(self, m: dict[str, Any]) -> dict[str, Any]:
        out = dict(m)
        window = m.get("window")
        if window is not None and not (isinstance(window, list) and len(window) == 2
                                       and all(_number(w) and math.isfinite(w) for w in window)):
            self._drop()
            out["window"] = None
        for key in _COUNTS:
            if key in m and m[key] is not None and not _count(m[key]):
                self._drop()
                out[key] = None
        out["followers"] = self.texts(m.get("followers"))
        out["notes"] = self.texts(m.get("notes"))
        out["methods"] = self.table(m.get("methods"))
        skipped = m.get("skipped")
        out["skipped"] = {k: v for k, v in skipped.items() if _text(k) and _text(v)} if isinstance(skipped, dict) \
            else {}
        self.skipped += (len(skipped) if isinstance(skipped, dict) else skipped is not None) - len(out["skipped"])
        rejected = m.get("rejected")
        out["rejected"] = {}
        if rejected is not None and not isinstance(rejected, dict):
            self._drop()
        for follower, counts in (rejected.items() if isinstance(rejected, dict) else ()):
            table = self.figures(counts) if _text(follower) is not None else None
            if table is None:
                continue
            out["rejected"][follower] = {k: v for k, v in table.items() if _text(k) and _count(v)}
            self.skipped += len(table) - len(out["rejected"][follower])
        nav = m.get("navigation")
        out["navigation"] = {}
        if nav is not None and not isinstance(nav, dict):
            self._drop()
        for vehicle, entry in (nav.items() if isinstance(nav, dict) else ()):
            if _text(vehicle) is None or not isinstance(entry, dict):
                self._drop()
                continue
            out["navigation"][vehicle] = {**entry, "methods": self.table(entry.get("methods"), strings=True)}
        return out


def checked_run_metadata(raw: dict[str, str], where: Any) -> dict[str, Any]:
    """The `run` record of a results archive with its JSON fields decoded, every value checked: a record that
    cannot be a run's is a one-line UserError; a metric of the wrong kind is left out and counted in
    meta["skipped_values"]."""
    def refuse(key: str, what: str) -> UserError:
        return UserError(f"{where}: run metadata: {key} {what}")

    meta: dict[str, Any] = dict(raw)
    for key in ("run_id", "input_sha256", "input_file", "package_version", "metrics", "parameters"):
        if not isinstance(raw.get(key), str):
            raise refuse(key, "missing")
    if not _RUN_ID.match(raw["run_id"]):
        raise refuse("run_id", f"{raw['run_id'][:40]!r} is not a run id (1-64 letters, digits, '_', '-', '.')")
    if not _SHA256.match(raw["input_sha256"]):
        raise refuse("input_sha256", f"{raw['input_sha256'][:40]!r} is not a sha256 (64 lower-case hex digits)")
    for key in ("input_file", "input_path", "package_version"):
        if key in raw and _text(raw[key]) is None:
            raise refuse(key, "holds control characters or is too long")
    for key in ("metrics", "parameters"):
        meta[key] = _decode(raw[key])
        if not isinstance(meta[key], dict):
            raise refuse(key, "is not a JSON object")
    wall = _decode(raw["wall_time_s"]) if "wall_time_s" in raw else None
    meta["wall_time_s"] = wall if isinstance(wall, (int, float)) and _number(wall) and 0 <= wall < math.inf else None
    start = _decode(raw["trial_start_ns"]) if "trial_start_ns" in raw else None
    meta["trial_start_ns"] = start if _count(start) else None
    cleaner = _Cleaner()
    cleaner.skipped += ("wall_time_s" in raw and meta["wall_time_s"] is None) + (
        "trial_start_ns" in raw and meta["trial_start_ns"] is None)
    meta["metrics"] = cleaner.metrics(meta["metrics"])
    meta["skipped_values"] = cleaner.skipped
    return meta


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
