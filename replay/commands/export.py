"""Export one topic of an archive to CSV or Parquet (one column per scalar field, UTC time index)."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay export`."""
    parser.add_argument("file", help="an archive or results file (.mcap)")
    parser.add_argument("--topic", required=True, help="the topic to export, e.g. /follower/gps")
    parser.add_argument("--format", choices=["csv", "parquet"], default="csv")
    parser.add_argument("-o", "--output", required=True, help="the file to write")


def run(args: argparse.Namespace) -> int:
    """Write the topic; an unknown topic is bad input (exit 1) naming the topics there are."""
    from formats.mcap_reader import ArchiveReader
    from replay.errors import UserError

    with ArchiveReader(args.file) as reader:
        topics = reader.summary().topics
        if args.topic not in topics:
            raise UserError(f"{args.file}: no topic {args.topic}; topics: {', '.join(sorted(topics))}")
        df = reader.to_dataframe(args.topic)
    df = df.copy()
    for col in df.columns:  # Parquet needs one type per column; timestamps stay typed
        if df[col].dtype == object:
            df[col] = df[col].astype(str)
    if args.format == "csv":
        df.to_csv(args.output)
    else:
        df.to_parquet(args.output)
    print(f"wrote {len(df)} rows of {args.topic} to {args.output}")
    return 0
