"""A shareable report of one replay run: one self-contained HTML file (nothing fetched when it is opened).

The scoreboard (exactly the run's metrics.json), error CDFs and error over
time for every method, the detection timeline per leader and method beside
the truth labels, t_a and the anomaly intervals, what each detector caught per
anomaly kind, and the run's configuration, package version and input hash.
The run is re-run from its input archive (found as `view` finds it, or
--archive) for the error series; kinds come from the simulator's
anomalies.csv: the one given with --anomalies, else an anomalies.csv beside
the results or the input archive, else the bundled sample's when the input
was recorded from the bundled sample's manifest (the archive holds only
labels).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from formats.mcap_reader import ArchiveReader
from replay.errors import UserError, warn_damage
from replay.reproduce.anfis import sample_trial_dir
from replay.review.anomaly_kinds import load_intervals
from replay.review.report import build_report
from replay.run.outputs import claim_output
from replay.run.rebuild import find_input, review_from_results, run_metadata


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay report`."""
    parser.add_argument("results", help="a results archive (.mcap) from `auvreplay replay -o`")
    parser.add_argument("-o", "--output", help="the HTML file to write (default: <results>.report.html)")
    parser.add_argument("--archive", help="the run's input trial archive, if not found by itself")
    parser.add_argument("--anomalies", metavar="CSV",
                        help="the simulator's anomalies.csv (`auvreplay simulate` writes it): anomaly kinds")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")


def find_anomalies(results: Path, meta: dict[str, Any], archive: str | None) -> Path | None:
    """The simulator's anomalies.csv of the run's trial, when it can be found without being named (see above)."""
    try:
        source = find_input(results, meta, archive)
    except UserError:
        source = None
    for folder in (results.parent, source.parent if source is not None else None):
        if folder is not None and (folder / "anomalies.csv").is_file():
            return folder / "anomalies.csv"
    if source is None:
        return None
    sample = sample_trial_dir()
    with ArchiveReader(source) as reader:
        trial = reader.metadata_json("trial")
    manifest = trial.get("manifest") if isinstance(trial, dict) else None
    if isinstance(manifest, str) and (sample / "trial.toml").is_file() \
            and manifest == (sample / "trial.toml").read_text() and (sample / "anomalies.csv").is_file():
        return sample / "anomalies.csv"
    return None


def run(args: argparse.Namespace) -> int:
    """Build and write the report; a file that is no results archive is bad input (exit 1)."""
    results = Path(args.results)
    if not results.is_file():
        raise UserError(f"{results}: no such file")
    meta = run_metadata(results)
    if meta is None:
        raise UserError(f"{results}: not a replay results archive (no 'run' metadata record)")
    out = claim_output(args.output or results.with_suffix(".report.html"), args.force)
    review = review_from_results(results, args.archive)
    found = Path(args.anomalies) if args.anomalies else find_anomalies(results, meta, args.archive)
    intervals = load_intervals(found) if found is not None else None
    if found is not None and not args.anomalies:
        print(f"anomaly kinds from {found}")
    text = build_report(meta, review, intervals)
    out.write_text(text, encoding="utf-8")
    print(f"wrote {out} ({len(text.encode()) / 1e6:.2f} MB)")
    skipped = meta.get("skipped_values") or 0
    warn_damage("report", "; ".join(filter(None, [
        review.input_warning,
        f"{results}: {skipped} values of the run metadata were not of their kind: left out of the report"
        if skipped else None])) or None)
    return 0
