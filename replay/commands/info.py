"""Show what is inside an archive: topics, time span, vehicles, attachments, diagnostics."""

from __future__ import annotations

import argparse
import json
from typing import Any

from formats.mcap_reader import ArchiveReader
from formats.nmea.counts import describe as describe_counts
from recorders.clock import iso_utc as iso
from replay.errors import warn_damage


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay info`."""
    parser.add_argument("file", help="an MCAP archive")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def describe(path: str) -> dict[str, Any]:
    """The `info --json` object for an archive (docs/design.md section 6).

    Metadata comes from other people's machines: a value of the wrong shape
    is left out and counted in the warning, never trusted.
    """

    with ArchiveReader(path) as reader:
        summary = reader.summary()
        trial = _mapping(reader.metadata_json("trial"))
        recording = _mapping(reader.metadata_json("recording"))
        runs = [n for n in summary.metadata_names if n == "run"]
        files, dropped = _files(recording.get("files"))
        vehicles = [v for v in _list(trial.get("vehicles")) if isinstance(v, (dict, str))]
        if dropped:
            reader.damage.bad_record("recording metadata entry", f"{dropped} log entries not of the recorded shape")
        problems = list(reader.problems)
        warning = reader.warning()
    return {
        "file": str(path),
        "topics": {t: {"count": v["count"], "schema": v["schema"]} for t, v in sorted(summary.topics.items())},
        "messages": summary.message_count,
        "attachments": [{"name": a.name, "size": a.size, "media_type": a.media_type} for a in summary.attachments],
        "start": iso(summary.start_ns),
        "end": iso(summary.end_ns),
        "trial": trial.get("name") if isinstance(trial.get("name"), str) else None,
        "vehicles": vehicles,
        "diagnostics": {
            f["path"]: {k: f.get(k) for k in ("vehicle", "sensor", "format", "parsed", "skipped", "bad_checksum",
                                               "out_of_order", "duplicates", "start", "end", "ignored",
                                               "ignored_reasons", "parts", "notes", "sentences")}
            for f in files
        },
        "metadata": summary.metadata_names,
        "runs": len(runs),
        "recovered": bool(problems),
        "problems": problems,
        "warning": warning,
    }


def _mapping(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def _files(value: Any) -> tuple[list[dict[str, Any]], int]:
    """The recording's per-log entries that have a path, and how many others were dropped."""
    entries = _list(value)
    good = [f for f in entries if isinstance(f, dict) and isinstance(f.get("path"), str)]
    return good, len(entries) - len(good) + (1 if value is not None and not isinstance(value, list) else 0)


def _counts_shape(value: Any) -> bool:
    """Whether a log's `sentences` entry is {address: {outcome: count}} (metadata from someone else's file)."""
    return isinstance(value, dict) and bool(value) and all(
        isinstance(per, dict) and all(isinstance(n, int) for n in per.values()) for per in value.values())


def _count(value: Any) -> str:
    return str(value) if isinstance(value, int) else "?"


def _print_text(info: dict[str, Any]) -> None:
    print(f"file:        {info['file']}")
    if info["trial"]:
        print(f"trial:       {info['trial']}")
    print(f"span:        {info['start']} .. {info['end']}")
    print(f"messages:    {info['messages']}")
    for v in info["vehicles"]:
        print(f"vehicle:     {v.get('name')} ({v.get('role')})" if isinstance(v, dict) else f"vehicle:     {v}")
    print("topics:")
    width = max((len(t) for t in info["topics"]), default=10)
    for topic, t in info["topics"].items():
        print(f"  {topic:<{width}}  {t['count']:>8}  {t['schema']}")
    if info["attachments"]:
        print("attachments:")
        for a in info["attachments"]:
            print(f"  {a['name']}  ({a['size']} bytes)")
    if info["diagnostics"]:
        print("logs:                                parsed  skipped  bad checksum  ignored")
        for path, d in info["diagnostics"].items():
            print(f"  {path:<34} {_count(d['parsed']):>7}  {_count(d['skipped']):>7}  {_count(d['bad_checksum']):>12}"
                  f"  {_count(d['ignored'] or 0):>7}")
        for path, d in info["diagnostics"].items():
            if _counts_shape(d.get("sentences")):
                print(f"  {path}: {describe_counts(d['sentences'])}")
    warn_damage("info", info["warning"])


def run(args: argparse.Namespace) -> int:
    """Print the archive description; exit 0 (a recovered damaged file still exits 0)."""
    info = describe(args.file)
    if args.json:
        print(json.dumps(info, indent=2))
        warn_damage("info", info["warning"])
    else:
        _print_text(info)
    return 0
