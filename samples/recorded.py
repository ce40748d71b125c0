"""The vehicles' motion from a recorded trial's GPS tracks: what `auvreplay simulate --tracks ARCHIVE` moves along.

Tracks: any MCAP archive's `foxglove.LocationFix` topics `/<vehicle>/<source>`
give one track per vehicle (its `/<vehicle>/gps`, else its LocationFix topic
with the most fixes). Buoys are left out (role `buoy` in the archive's trial
metadata, or a vehicle with a `/<vehicle>/usbl` topic), as are a results
archive's `/replay/...` topics, fixes that are not finite and repeated times.

Roles: with two or more tracks the follower is `[tracks] follower` (by
default the vehicle named `follower`, else the first of role follower in the
archive's trial metadata, else the first track in the metadata's vehicle order,
then topic order) and the others are leader1, leader2, ... in that order. With
one track its vehicle is the follower and its track is replayed for
`[tracks] leaders` leaders: leader k is the same track k * `leader_offset_s`
seconds ahead in time.

Span: a track covers its stretches whose gaps between fixes are at most
`max_gap_s` (bridged by linear interpolation); the trial is the longest span
every track (every time-shifted copy too) covers, cut to `[trial] duration_s`,
starting on that span's first whole UTC second. The trial's date, start time and
origin (the mean fix, to 1e-6 degrees) come from the archive.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from formats.geodesy import LocalFrame
from formats.mcap_reader import ArchiveReader
from formats.records import FormatError
from formats.units import NS

from .scenario import Scenario, ScenarioError
from .trajectories import FOLLOWER_DEPTH_M, LEADER_DEPTH_M, Track, track_from_fixes

LOCATION_FIX = "foxglove.LocationFix"


class TrackError(ScenarioError):
    """An archive whose GPS tracks cannot give a trial's motion (not MCAP, no track, one point, no common span)."""


@dataclass(frozen=True)
class SourceTrack:
    """One vehicle's GPS fixes as recorded: UTC ns (increasing, distinct) and degrees."""

    vehicle: str
    topic: str
    t_ns: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray


@dataclass(frozen=True)
class RecordedMotion:
    """The scenario with the archive's date, start, length and origin; each simulated vehicle's truth track; notes."""

    scenario: Scenario
    tracks: dict[str, Track]
    notes: tuple[str, ...]


def _gps_topics(topics: dict[str, dict], buoys: set[str]) -> dict[str, str]:
    """Vehicle -> its LocationFix topic: /<v>/gps, else the one with the most messages."""
    best: dict[str, tuple[bool, int, str]] = {}
    for topic, info in sorted(topics.items()):
        parts = topic.strip("/").split("/")
        if info.get("schema") != LOCATION_FIX or len(parts) < 2 or parts[0] == "replay" or parts[0] in buoys:
            continue
        key = (parts[1:] == ["gps"], int(info.get("count", 0)), topic)
        if parts[0] not in best or key[:2] > best[parts[0]][:2]:
            best[parts[0]] = key
    return {v: k[2] for v, k in best.items()}


def _source(vehicle: str, topic: str, t: list[int], lat: list[float], lon: list[float]) -> SourceTrack:
    t_ns, la, lo = np.asarray(t, dtype=np.int64), np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
    ok = np.isfinite(la) & np.isfinite(lo) & (np.abs(la) <= 90) & (np.abs(lo) <= 180)
    t_ns, la, lo = t_ns[ok], la[ok], lo[ok]
    order = np.argsort(t_ns, kind="stable")
    t_ns, la, lo = t_ns[order], la[order], lo[order]
    first = np.concatenate(([True], np.diff(t_ns) > 0)) if len(t_ns) else np.zeros(0, dtype=bool)
    return SourceTrack(vehicle, topic, t_ns[first], la[first], lo[first])


def read_gps_tracks(path: str | os.PathLike[str]) -> tuple[list[SourceTrack], dict[str, str]]:
    """Every vehicle's GPS track of an archive (metadata vehicle order, then topic order) and the roles it records.

    TrackError when the file is not an MCAP archive.
    """
    try:
        reader = ArchiveReader(path)
    except FormatError as exc:
        raise TrackError(str(exc)) from None
    with reader:
        meta = reader.metadata_json("trial") or {}
        vehicles = meta.get("vehicles") if isinstance(meta, dict) else None
        roles = {str(v["name"]): str(v.get("role") or "") for v in (vehicles if isinstance(vehicles, list) else [])
                 if isinstance(v, dict) and "name" in v}
        topics = reader.summary().topics
        usbl = {t.strip("/").split("/")[0] for t in topics if t.strip("/").split("/")[1:2] == ["usbl"]}
        buoys = {v for v, r in roles.items() if r == "buoy"} | usbl
        chosen = _gps_topics(topics, buoys)
        cols: dict[str, tuple[list[int], list[float], list[float]]] = {t: ([], [], []) for t in chosen.values()}
        for m in reader.messages(list(cols)):
            c = cols[m.topic]
            c[0].append(m.log_time_ns)
            c[1].append(float(m.message.latitude))
            c[2].append(float(m.message.longitude))
    order = {name: i for i, name in enumerate(roles)}
    names = sorted(chosen, key=lambda v: (order.get(v, len(order)), chosen[v]))
    return [_source(v, chosen[v], *cols[chosen[v]]) for v in names], roles


def pick_follower(sources: list[SourceTrack], roles: dict[str, str], wanted: str) -> SourceTrack:
    """The follower's track: `wanted`, else the vehicle named follower, else the first follower, else the first."""
    by_name = {s.vehicle: s for s in sources}
    if wanted:
        if wanted not in by_name:
            raise TrackError(f"no GPS track of vehicle {wanted!r} to follow; tracks: {', '.join(by_name)}")
        return by_name[wanted]
    if "follower" in by_name:
        return by_name["follower"]
    return next((s for s in sources if roles.get(s.vehicle) == "follower"), sources[0])


Spans = list[tuple[float, float]]


def covered(t_s: np.ndarray, max_gap_s: float) -> Spans:
    """The stretches [first, last] of increasing times whose gaps are all at most `max_gap_s` (single fixes: none)."""
    if len(t_s) < 2:
        return []
    breaks = np.flatnonzero(np.diff(t_s) > max_gap_s)
    starts, ends = np.concatenate(([0], breaks + 1)), np.concatenate((breaks, [len(t_s) - 1]))
    return [(float(t_s[a]), float(t_s[b])) for a, b in zip(starts, ends) if t_s[b] > t_s[a]]


def intersect(a: Spans, b: Spans) -> Spans:
    """The intersection of two sorted lists of disjoint closed spans."""
    out, i, j = [], 0, 0
    while i < len(a) and j < len(b):
        lo, hi = max(a[i][0], b[j][0]), min(a[i][1], b[j][1])
        if hi > lo:
            out.append((lo, hi))
        if a[i][1] < b[j][1]:
            i += 1
        else:
            j += 1
    return out


def _roles(sources: list[SourceTrack], follower: SourceTrack, scenario: Scenario
           ) -> tuple[list[tuple[str, SourceTrack, float]], str]:
    """(simulated name, source, seconds ahead) per vehicle, leaders first, and the line that says who is who."""
    others = [s for s in sources if s is not follower]
    if others:
        cast = [(f"leader{k + 1}", s, 0.0) for k, s in enumerate(others)] + [("follower", follower, 0.0)]
        return cast, "tracks: " + ", ".join(f"{n} = {s.vehicle}" for n, s, _ in cast)
    tr = scenario.tracks
    cast = [(f"leader{k}", follower, k * tr.leader_offset_s) for k in range(1, tr.leaders + 1)]
    ahead = ", ".join(f"{n} +{dt:g} s" for n, _, dt in cast)
    return cast + [("follower", follower, 0.0)], (
        f"one vehicle with a GPS track ({follower.vehicle}): it is the follower, and each leader is its own track "
        f"ahead in time ({ahead})")


def _common_span(cast: list[tuple[str, SourceTrack, float]], max_gap_s: float, archive: str
                 ) -> tuple[int, float, bool]:
    """(UTC ns of its first whole second, seconds to its end to 0.1 s, whether a gap cut it) of the longest span
    every track of the cast covers, each shifted by the seconds it runs ahead."""
    t0 = min(int(s.t_ns[0]) for _, s, _ in cast)
    spans: Spans = [(-math.inf, math.inf)]
    hull: Spans = [(-math.inf, math.inf)]
    for _, s, ahead in cast:
        t_s = (s.t_ns - t0) / NS - ahead
        spans = intersect(spans, covered(t_s, max_gap_s))
        hull = intersect(hull, [(float(t_s[0]), float(t_s[-1]))])
    if not spans:
        raise TrackError(f"{archive}: no span that every track covers with gaps of at most {max_gap_s:g} s")
    lo, hi = max(spans, key=lambda ab: (ab[1] - ab[0], -ab[0]))
    start_ns = -(-(t0 + math.ceil(lo * NS)) // NS) * NS
    span_s = math.floor((t0 + hi * NS - start_ns) / NS * 10) / 10
    if span_s <= 0:
        raise TrackError(f"{archive}: the tracks' longest common span ({hi - lo:.1f} s) holds no whole second")
    return start_ns, span_s, bool(hull) and hi - lo < hull[0][1] - hull[0][0] - 1e-6


def _utc(t_ns: int) -> datetime:
    return datetime.fromtimestamp(t_ns // NS, UTC)


def recorded_motion(scenario: Scenario, seed: int) -> RecordedMotion:
    """The truth tracks of `scenario.tracks.archive` (module text) and the scenario dated and placed on them."""
    tr = scenario.tracks
    sources, roles = read_gps_tracks(tr.archive)
    if not sources:
        raise TrackError(f"{tr.archive}: no GPS track (no {LOCATION_FIX} topic of a vehicle with a finite fix)")
    moving = [s for s in sources if len(s.t_ns) >= 2]
    if not moving:
        raise TrackError(f"{tr.archive}: every GPS track has one point ({', '.join(s.vehicle for s in sources)}): "
                         "no motion to follow")
    cast, who = _roles(moving, pick_follower(moving, roles, tr.follower), scenario)
    start_ns, span_s, gapped = _common_span(cast, tr.max_gap_s, tr.archive)
    duration = min(span_s, scenario.trial.duration_s)
    notes = [who]
    if gapped:
        notes.append(f"GPS gaps over {tr.max_gap_s:g} s: the trial is cut to the longest span every track covers, "
                     f"{span_s:g} s from {_utc(start_ns).isoformat()}")
    if duration < span_s:
        notes.append(f"the trial is cut to its duration, {duration:g} of the {span_s:g} s the tracks cover")
    if duration <= scenario.trial.training_window_s:
        notes.append(f"the trial lasts {duration:g} s, no longer than its {scenario.trial.training_window_s:g} s "
                     "training window: the detectors will not train")
    inside = [((s.t_ns - start_ns) / NS - ahead, s) for _, s, ahead in cast]
    lat = np.concatenate([s.lat_deg[(t >= 0) & (t <= duration)] for t, s in inside])
    lon = np.concatenate([s.lon_deg[(t >= 0) & (t <= duration)] for t, s in inside])
    when = _utc(start_ns)
    trial = replace(scenario.trial, date=when.date().isoformat(), start_time_utc=when.time().isoformat("seconds"),
                    duration_s=float(duration), followers=1, origin_lat_deg=round(float(np.mean(lat)), 6),
                    origin_lon_deg=round(float(np.mean(lon)), 6))
    frame = LocalFrame(trial.origin_lat_deg, trial.origin_lon_deg)
    step = 1.0 / trial.truth_rate_hz
    t = np.arange(int(round(duration / step)) + 1) * step
    tracks = {}
    for (name, s, _), (t_s, _) in zip(cast, inside):
        east, north = frame.to_local(s.lat_deg, s.lon_deg)
        depth = FOLLOWER_DEPTH_M if name == "follower" else LEADER_DEPTH_M
        tracks[name] = track_from_fixes(name, t_s, east, north, t, frame, depth, seed, tr.smoothing_s)
    archive = str(Path(tr.archive).resolve())
    out = replace(scenario, trial=trial, tracks=replace(tr, archive=archive))
    return RecordedMotion(out, tracks, tuple(notes))
