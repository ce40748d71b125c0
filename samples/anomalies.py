"""Ranging anomalies: drawing the natural ones, applying all of them, and the labels.

Kinds (seed A section 1 and 4.1, seed P background): `stale` — the modem
keeps reporting its last range; `drift` — a slowly growing error; `outlier` —
one wild range; `dropout` — no reply; `multipath` — a persistent positive bias on a link for a
time (a condition, samples/conditions.py). Labels follow docs/design.md section 9
(seed A eqs. 26-27): an epoch is anomalous when |Z_gps - Z| > T1, Z_gps from
the vehicles' GPS fixes, Z the measured range made horizontal.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from formats.geodesy import metric_scales

from .scenario import AnomalyEvent, NaturalAnomalies
from .trajectories import stream

KIND_CODES = {"": 0, "stale": 1, "drift": 2, "outlier": 3, "multipath": 4}
T1_M = 9.0


@dataclass(frozen=True)
class Interval:
    """A labelled anomaly interval for anomalies.csv (times in seconds from the start)."""

    vehicle: str
    leader: str
    kind: str
    start_s: float
    end_s: float
    origin: str
    magnitude_m: float = 0.0


def _stale_starts(rng: np.random.Generator, per_hour: float, duration_s: float) -> np.ndarray:
    """One start per period of 3600/per_hour s, uniform inside it (jittered, not Poisson).

    Jittered placement keeps the count of segments fixed per trial length, so
    the share of anomalous epochs varies little from seed to seed.
    """
    if per_hour <= 0:
        return np.zeros(0)
    period = 3600.0 / per_hour
    count = int(duration_s // period)
    return (np.arange(count) + rng.random(count)) * period


def natural_events(nat: NaturalAnomalies, follower: str, t_epochs: np.ndarray, duration_s: float,
                   seed: int, scripted: Sequence[AnomalyEvent] = ()) -> list[AnomalyEvent]:
    """Random stale segments, outliers and dropouts of one follower-leader link.

    Drawn stale segments that would overlap a scripted event are dropped, so
    that the scripted anomalies keep the shape the source describes.
    """
    rng = stream(seed, "natural", follower, nat.leader)
    starts = _stale_starts(rng, nat.stale_per_hour, duration_s)
    ends = np.minimum(starts + rng.uniform(nat.stale_min_s, nat.stale_max_s, len(starts)), duration_s)
    clear = [not any(s <= e.end_s and e.start_s <= f for e in scripted) for s, f in zip(starts, ends)]
    events = [AnomalyEvent(nat.leader, "stale", round(float(s), 1), round(float(f), 1), 0.0, follower)
              for s, f, ok in zip(starts, ends, clear) if ok]
    n = len(t_epochs)
    hit = rng.random(n) < nat.outlier_prob
    size = rng.uniform(nat.outlier_min_m, nat.outlier_max_m, n) * np.where(rng.random(n) < 0.5, -1.0, 1.0)
    drop = rng.random(n) < nat.dropout_prob
    events += [AnomalyEvent(nat.leader, "outlier", float(t), float(t), round(float(m), 2), follower)
               for t, m in zip(t_epochs[hit], size[hit])]
    events += [AnomalyEvent(nat.leader, "dropout", float(t), float(t), 0.0, follower) for t in t_epochs[drop]]
    return events


def _inside(t: np.ndarray, ev: AnomalyEvent) -> np.ndarray:
    return (t >= ev.start_s - 1e-9) & (t <= ev.end_s + 1e-9)


def apply_events(t: np.ndarray, noisy_m: np.ndarray,
                 events: list[AnomalyEvent]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured ranges of ONE link after its events: (measured, replied mask, kind codes).

    Order: dropouts remove epochs; drift, outliers and multipath add to the noisy range;
    stale segments then freeze the last reported value (the modem repeats
    what it last had, whatever that was).
    """
    measured = noisy_m.copy()
    kinds = np.zeros(len(t), dtype=np.int8)
    replied = np.ones(len(t), dtype=bool)
    for ev in (e for e in events if e.kind == "dropout"):
        replied &= ~_inside(t, ev)
    for ev in (e for e in events if e.kind in ("drift", "outlier", "multipath")):
        m = _inside(t, ev) & replied
        span = max(ev.end_s - ev.start_s, 1e-9)
        ramp = (t[m] - ev.start_s) / span if ev.kind == "drift" else 1.0
        measured[m] = np.maximum(measured[m] + ev.magnitude_m * ramp, 1.0)
        kinds[m] = KIND_CODES[ev.kind]
    for ev in sorted((e for e in events if e.kind == "stale"), key=lambda e: e.start_s):
        m = _inside(t, ev) & replied
        if not m.any():
            continue
        before = np.flatnonzero(replied & (t < ev.start_s - 1e-9))
        # with no earlier reply, the first reply inside is the one repeated
        measured[m] = measured[before[-1] if len(before) else np.flatnonzero(m)[0]]
        kinds[m] = KIND_CODES["stale"]
    return measured, replied, kinds


def horizontal_range(slant_m: np.ndarray, depth_a_m: np.ndarray, depth_b_m: np.ndarray) -> np.ndarray:
    """Slant to horizontal range, clamped at 0 (docs/design.md section 7)."""
    return np.sqrt(np.maximum(slant_m**2 - (depth_a_m - depth_b_m) ** 2, 0.0))


def gps_range(lat_a: np.ndarray, lon_a: np.ndarray, lat_b: np.ndarray, lon_b: np.ndarray,
              depth_a: np.ndarray, depth_b: np.ndarray) -> np.ndarray:
    """Horizontal range between two fixes with common mid-point radii (docs/design.md section 7, A.4)."""
    la, lb = np.radians(lat_a), np.radians(lat_b)
    mid = 0.5 * (la + lb)
    h = 0.5 * (depth_a + depth_b)
    b, a = metric_scales(mid, h)
    return np.hypot(b * (la - lb), a * np.radians(lon_a - lon_b))


def label(z_gps_m: np.ndarray, z_m: np.ndarray, t1_m: float = T1_M) -> np.ndarray:
    """1 where |Z_gps - Z| > T1 (seed A eq. 27)."""
    return (np.abs(z_gps_m - z_m) > t1_m).astype(np.int8)


def intervals_for(events: list[AnomalyEvent], origin: str) -> list[Interval]:
    """Labelled intervals of a list of events (vehicle = the follower that measured)."""
    return [Interval(e.follower, e.leader, e.kind, e.start_s, e.end_s, origin, e.magnitude_m) for e in events]
