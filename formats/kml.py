"""Tracks as KML 2.2 for Google Earth: a Folder per group, a Placemark per track with a time-stamped gx:Track.

A gx:Track (Google's KML extension) holds one `when` per `gx:coord`, so
Google Earth's time slider plays the tracks; the Placemark's TimeSpan gives
the track's first and last time. Coordinates are "longitude latitude altitude"
(altitude 0: clamped to the ground or sea surface). Colours are KML's aabbggrr.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from xml.sax.saxutils import escape as _escape

from formats.tracks import Track, iso_utc

KML_NS = "http://www.opengis.net/kml/2.2"
GX_NS = "http://www.google.com/kml/ext/2.2"
# characters XML 1.0 cannot hold at all (names come from archives, which are other people's files)
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


def escape(text: str) -> str:
    """Text for an XML element: markup escaped, characters XML cannot hold dropped."""
    return _escape(_NOT_XML.sub("", text))


def _placemark(track: Track, color_abgr: str) -> list[str]:
    t = track.finite()
    if len(t.time_ns) == 0:
        return []
    times = iso_utc(t.time_ns)
    desc = "; ".join(f"{k}: {v}" for k, v in track.properties.items())
    desc += f"; mission_s {t.mission_s[0]:.3f} to {t.mission_s[-1]:.3f}"
    out = ["<Placemark>", f"<name>{escape(t.name)}</name>", f"<description>{escape(desc)}</description>",
           f"<TimeSpan><begin>{times[0]}</begin><end>{times[-1]}</end></TimeSpan>",
           f"<Style><LineStyle><color>{color_abgr}</color><width>2</width></LineStyle></Style>",
           "<gx:Track><altitudeMode>clampToGround</altitudeMode>"]
    out += [f"<when>{w}</when>" for w in times]
    out += [f"<gx:coord>{lon:.7f} {lat:.7f} 0</gx:coord>" for lon, lat in zip(t.lon_deg, t.lat_deg)]
    out += ["</gx:Track>", "</Placemark>"]
    return out


def kml_document(name: str, groups: Iterable[tuple[str, Iterable[tuple[Track, str]]]]) -> bytes:
    """A KML document named `name`: one Folder per (group name, [(track, aabbggrr colour)])."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', f'<kml xmlns="{KML_NS}" xmlns:gx="{GX_NS}">',
             "<Document>", f"<name>{escape(name)}</name>"]
    for group, tracks in groups:
        lines += ["<Folder>", f"<name>{escape(group)}</name>"]
        for track, color in tracks:
            lines += _placemark(track, color)
        lines.append("</Folder>")
    lines += ["</Document>", "</kml>"]
    return ("\n".join(lines) + "\n").encode()
