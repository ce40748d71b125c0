"""Export an archive: one topic to CSV or Parquet (one column per scalar field, the UTC time index and
`mission_s`, seconds from the trial start), or position tracks to GeoJSON or KML.

For geojson and kml every position track is written (a trial's GPS fixes, INS
and autopilot solutions, local positions on an origin and other vehicles' node
reports; a run's estimates and fixes per vehicle and method: see
`replay.run.track_export`) unless --topic names some:
one LineString (GeoJSON) or time-stamped gx:Track Placemark (KML) per track,
with UTC times and mission seconds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from formats.dataframe import with_mission_seconds
from formats.mcap_reader import ArchiveReader
from replay.errors import UserError, warn_damage
from replay.run.mission_time import trial_start_ns
from replay.run.outputs import claim_output
from replay.run.track_export import archive_tracks, tracks_bytes

TABLE_FORMATS = ("csv", "parquet")
TRACK_FORMATS = ("geojson", "kml")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of `auvreplay export`."""
    parser.add_argument("file", help="an archive or results file (.mcap)")
    parser.add_argument("--topic", action="append", default=[],
                        help="the topic to export, e.g. /follower/gps (csv, parquet: exactly one; "
                             "geojson, kml: any number of tracks, default all)")
    parser.add_argument("--format", choices=TABLE_FORMATS + TRACK_FORMATS, default="csv")
    parser.add_argument("-o", "--output", required=True, help="the file to write")
    parser.add_argument("--force", action="store_true", help="replace an existing output file")


def run(args: argparse.Namespace) -> int:
    """Write the topic or tracks; an unknown topic is bad input (exit 1) naming the topics there are."""
    if args.format in TRACK_FORMATS:

        out = claim_output(args.output, args.force)
        tracks = archive_tracks(args.file, args.topic or None)
        data = tracks_bytes(tracks, args.format, Path(args.file).stem)
        out.write_bytes(data)
        print(f"wrote {len(tracks)} tracks ({sum(len(t.time_ns) for t in tracks)} points) to {out}")
        return 0
    if len(args.topic) != 1:
        raise UserError(f"--format {args.format} exports one topic: give --topic once")

    topic = args.topic[0]
    with ArchiveReader(args.file) as reader:
        topics = reader.summary().topics
        if topic not in topics:
            raise UserError(f"{args.file}: no topic {topic}; topics: {', '.join(sorted(topics))}")
        out = claim_output(args.output, args.force)
        df = with_mission_seconds(reader.to_dataframe(topic), trial_start_ns(reader))
        warning = reader.warning()
    for col in df.columns:  # Parquet needs one type per column; timestamps stay typed
        if df[col].dtype == object:
            df[col] = df[col].astype(str)
    if args.format == "csv":
        df.to_csv(out)
    else:
        df.to_parquet(out)
    print(f"wrote {len(df)} rows of {topic} to {out}")
    warn_damage("export", warning)
    return 0
