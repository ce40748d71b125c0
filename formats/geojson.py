"""Tracks as a GeoJSON FeatureCollection (RFC 7946): one LineString Feature per track, times beside it.

Coordinates are [longitude, latitude] in WGS84 degrees (RFC 7946 section 3.1.1),
rounded to 1e-7 degree (about a centimetre). Each point's time goes in the
Feature's properties as `coordTimes` (ISO 8601 UTC, the convention GPX/KML
converters and Mapbox tools read) and `mission_s` (seconds from the trial start).
A track of one point is a Point.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import Any

from formats.tracks import Track, iso_utc

DIGITS = 7


def feature(track: Track) -> dict[str, Any] | None:
    """The GeoJSON Feature of a track (its non-finite points dropped), or None when no point is left."""
    t = track.finite()
    if len(t.time_ns) == 0:
        return None
    coords = [[round(float(lon), DIGITS), round(float(lat), DIGITS)] for lon, lat in zip(t.lon_deg, t.lat_deg)]
    times = iso_utc(t.time_ns)
    geometry = {"type": "LineString", "coordinates": coords} if len(coords) > 1 else \
        {"type": "Point", "coordinates": coords[0]}
    props = {"name": t.name, **t.properties, "start_utc": times[0], "end_utc": times[-1],
             "coordTimes": times, "mission_s": [round(float(s), 3) for s in t.mission_s]}
    return {"type": "Feature", "geometry": geometry, "properties": props}


def feature_collection(tracks: Iterable[Track]) -> bytes:
    """UTF-8 GeoJSON of every track that has a finite point."""
    features = [f for f in (feature(t) for t in tracks) if f is not None]
    return json.dumps({"type": "FeatureCollection", "features": features}, separators=(",", ":")).encode()
