"""Every position track of an archive (every position source of a trial, a run's estimates and fixes).

A trial archive's tracks are its topics `/<vehicle>/<source>` whose schema carries
latitude and longitude: `foxglove.LocationFix` (GPS fixes, `/<v>/gps`) and
`auvreplay.InsState` (navigation solutions: `/<v>/ins`, a second INS such as
`/<v>/ins/sbg`, local x/y placed on an origin as `/<v>/ins/local`, other
vehicles' `/<name>/node_report`). A topic with no finite position (an IMU's
attitude-only InsStates) is no track. A results archive's tracks are
`/replay/<run>/<vehicle>/<method>`. Each Track is named "<vehicle> <source>",
carries its vehicle, source (sensor path or method) and topic, and mission
seconds from the trial start (replay.run.mission_time); non-finite points are
dropped.
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
INS_STATE = "auvreplay.InsState"
# the schemas whose messages carry `latitude` and `longitude` in degrees
POSITION_SCHEMAS = (LOCATION_FIX, INS_STATE)
FORMATS = ("geojson", "kml")


def _names(topic: str) -> tuple[str, str, str]:
    """(run, vehicle, source) of a track topic; run is '' for a trial archive's own topics."""
    parts = topic.strip("/").split("/")
    if len(parts) >= 4 and parts[0] == "replay":
        return parts[1], parts[2], "/".join(parts[3:])
    return "", parts[0], "/".join(parts[1:]) or parts[0]


def archive_tracks(path: str | os.PathLike[str], topics: list[str] | None = None) -> list[Track]:
    """The position tracks of an archive (every one, or the given topics), in topic order.

    Reads only the topics of position schemas (or the chosen ones); a topic without one finite position is
    no track. A topic given that is no position schema, or holds no position, is a UserError.
    """
    with ArchiveReader(path) as reader:
        schemas = {t: v.get("schema") for t, v in reader.summary().topics.items()}
        candidates = sorted(t for t, s in schemas.items() if s in POSITION_SCHEMAS)
        chosen = candidates if topics is None else topics
        for t in chosen:
            if schemas.get(t) not in POSITION_SCHEMAS:
                raise UserError(f"{path}: {t} is not a position track (LocationFix or InsState); tracks: "
                                f"{', '.join(candidates) or 'none'}")
        start = trial_start_ns(reader)
        cols: dict[str, tuple[list[int], list[float], list[float]]] = {t: ([], [], []) for t in chosen}
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
        track = Track(f"{vehicle} {source}", t_ns.astype("int64"), lat.astype(float), lon.astype(float),
                      mission_seconds(t_ns, start), props).finite()
        if not len(track.time_ns):  # an IMU's attitude-only InsStates, or fixes that are all NaN
            if topics is not None:
                raise UserError(f"{path}: {topic} holds no position (none of its {len(cols[topic][0])} messages has a "
                                f"finite latitude and longitude)")
            continue
        tracks.append(track)
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
