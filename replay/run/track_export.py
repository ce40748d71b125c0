"""Every position track of an archive (GPS fixes of a trial, estimates and fixes of a replay run) as Tracks.

A trial archive's tracks are its `foxglove.LocationFix` topics `/<vehicle>/<sensor>`;
a results archive's are `/replay/<run>/<vehicle>/<method>`. Each Track carries
its vehicle, source (sensor or method) and topic, and mission seconds from
the trial start (replay.run.mission_time).
"""

from __future__ import annotations

import os
from collections import defaultdict

import numpy as np

from formats.geojson import feature_collection
from formats.kml import kml_document
from formats.mcap_reader import ArchiveReader
from formats.tracks import Track
from replay.errors import UserError
from replay.review.palette import method_kml
from replay.run.mission_time import mission_seconds, trial_start_ns

LOCATION_FIX = "foxglove.LocationFix"
FORMATS = ("geojson", "kml")


def _names(topic: str) -> tuple[str, str, str]:
    """(run, vehicle, source) of a track topic; run is '' for a trial archive's own topics."""
    parts = topic.strip("/").split("/")
    if len(parts) >= 4 and parts[0] == "replay":
        return parts[1], parts[2], "/".join(parts[3:])
    return "", parts[0], "/".join(parts[1:]) or parts[0]


def archive_tracks(path: str | os.PathLike[str], topics: list[str] | None = None) -> list[Track]:
    """The tracks of an archive (all its LocationFix topics, or the given ones), in topic order."""
    with ArchiveReader(path) as reader:
        schemas = {t: v.get("schema") for t, v in reader.summary().topics.items()}
        chosen = sorted(t for t, s in schemas.items() if s == LOCATION_FIX) if topics is None else topics
        for t in chosen:
            if schemas.get(t) != LOCATION_FIX:
                raise UserError(f"{path}: {t} is not a position track (LocationFix); tracks: "
                                f"{', '.join(sorted(k for k, s in schemas.items() if s == LOCATION_FIX)) or 'none'}")
        start = trial_start_ns(reader)
        cols: dict[str, tuple[list[int], list[float], list[float]]] = defaultdict(lambda: ([], [], []))
        for m in reader.messages(chosen):
            c = cols[m.topic]
            c[0].append(m.log_time_ns)
            c[1].append(m.message.latitude)
            c[2].append(m.message.longitude)
    tracks = []
    for topic in chosen:
        t_ns, lat, lon = (np.asarray(v) for v in cols[topic])
        run, vehicle, source = _names(topic)
        props = {"vehicle": vehicle, "source": source, "topic": topic, **({"run": run} if run else {})}
        tracks.append(Track(f"{vehicle} {source}", t_ns.astype("int64"), lat.astype(float), lon.astype(float),
                            mission_seconds(t_ns, start), props))
    return tracks


def tracks_bytes(tracks: list[Track], fmt: str, name: str) -> bytes:
    """The tracks as GeoJSON or KML (a Folder per vehicle, one colour per method)."""
    if fmt == "geojson":
        return feature_collection(tracks)
    if fmt == "kml":
        groups: dict[str, list[tuple[Track, str]]] = defaultdict(list)
        for t in tracks:
            groups[str(t.properties.get("vehicle", ""))].append((t, method_kml(str(t.properties.get("source")))))
        return kml_document(name, sorted(groups.items()))
    raise UserError(f"unknown track format {fmt!r}; expected one of {', '.join(FORMATS)}")
