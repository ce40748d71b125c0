"""The navigation review of one vehicle: dead reckoning, drift at GPS fixes, bottom lock, series, scores.

`review_vehicle` takes an open archive (or columns built by the caller) and
returns a `NavigationReview`; `scores` turns it into scoreboard rows with
the same error keys as the cooperative methods' metrics, so both rank side
by side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from formats.mcap_reader import ArchiveReader
from replay.errors import UserError

from .bottom_lock import BottomLock, bottom_lock
from .columns import VehicleColumns, read_columns
from .dead_reckoning import DeadReckoning, dead_reckon
from .drift import Dives, FixErrors, dives, fix_errors
from .series import NavigationSeries, navigation_series

__all__ = ["DR_METHOD", "INS_METHOD", "NavigationConfig", "NavigationReview", "NavigationScore", "SensorCounts",
           "notes", "review_metrics", "review_vehicle", "scores"]

DR_METHOD = "dead_reckoning (DVL)"
INS_METHOD = "ins"


@dataclass(frozen=True)
class NavigationConfig:
    """The review's settings (seconds).

    `dvl_hold_s`: how long a DVL velocity is carried over lost bottom lock or
    silence before the DR becomes unknown; `heading_max_gap_s`: widest
    spacing of heading samples interpolated across; `ins_max_age_s`: oldest
    INS solution taken as "just before" a fix; `dive_gap_s`: a GPS gap longer
    than this is a dive; `lock_min_gap_s`: shortest bottom-lock gap listed;
    `lock_bin_s`: bin of the availability series.
    """

    dvl_hold_s: float = 5.0
    heading_max_gap_s: float = 5.0
    ins_max_age_s: float = 5.0
    dive_gap_s: float = 30.0
    lock_min_gap_s: float = 5.0
    lock_bin_s: float = 60.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise UserError(f"navigation review: {name} must be a finite number >= 0, not {value!r}")


@dataclass(frozen=True)
class SensorCounts:
    """What the notes and the scoreboard need to know of the samples: DVL samples measuring velocity, those of
    them without bottom lock or a usable frame, altitude-only (rangefinder) samples, and whether the INS ever
    gave a latitude."""

    dvl_velocity: int
    dvl_unusable: int
    dvl_ranging: int
    ins_positions: bool

    @classmethod
    def of(cls, cols: VehicleColumns) -> SensorCounts:
        """The counts of whole-mission columns."""
        velocity = cols.dvl.velocities()
        return cls(int(velocity.t_s.size), int((~velocity.usable).sum()), int(cols.dvl.ranging.sum()),
                   bool(np.isfinite(cols.ins.lat_deg).any()))


@dataclass(frozen=True)
class NavigationReview:
    """Everything the review computed for one vehicle; times in mission seconds from `start_ns` (UTC ns).

    `notes` says in plain lines what a reviewer should know about the
    figures (dives found, DR unknown or carried, rows dropped). `columns`
    holds the samples when the review was computed on whole-mission columns;
    the streamed review (`stream.NavigationStream`) keeps none, its DR track
    one point a second (no DR position at the fixes) and its series at most a
    bounded number of points.
    """

    vehicle: str
    start_ns: int
    config: NavigationConfig
    columns: VehicleColumns | None
    counts: SensorCounts
    dead_reckoning: DeadReckoning
    fix_errors: FixErrors
    dives: Dives
    bottom_lock: BottomLock
    series: NavigationSeries
    notes: tuple[str, ...] = field(default=())


def notes(counts: SensorCounts, dropped: dict[str, int], errors: FixErrors, dv: Dives,
          config: NavigationConfig) -> tuple[str, ...]:
    """What a reviewer should know about the figures, in plain lines (the review's `notes`)."""
    out: list[str] = []
    n_fix = errors.t_s.size
    if n_fix < 2:
        out.append(f"{n_fix} GPS fix(es): no error at a fix can be measured")
    out.append(f"{len(dv)} dive(s) (GPS gaps longer than {config.dive_gap_s:g} s)")
    if counts.dvl_ranging:
        out.append(f"{counts.dvl_ranging} altitude-only samples (a rangefinder): altitude, not bottom lock")
    if counts.dvl_velocity:
        unusable = counts.dvl_unusable
        if unusable:
            out.append(f"{unusable} of {counts.dvl_velocity} DVL samples without bottom lock or a usable frame")
        measured = np.isfinite(errors.dr_error_m[1:])
        unknown = int((~measured).sum())
        if unknown:
            out.append(f"DR unknown at {unknown} of {max(n_fix - 1, 0)} fixes (no DVL velocity for longer than "
                       f"{config.dvl_hold_s:g} s, or no heading)")
        held = errors.dr_held_s[1:][measured]
        if held.size and float(held.sum()) > 0:
            out.append(f"DR carried the last DVL velocity for {float(held.sum()):.0f} s over "
                       f"{int((held > 0).sum())} fix interval(s) (at most {config.dvl_hold_s:g} s each time)")
    else:
        out.append("no DVL: no dead reckoning")
    out.extend(f"{n} row(s) dropped: {why}" for why, n in sorted(dropped.items()))
    return tuple(out)


def review_vehicle(source: ArchiveReader | VehicleColumns, vehicle: str,
                   config: NavigationConfig | None = None, start_ns: int | None = None) -> NavigationReview:
    """Review one vehicle's navigation from an open archive (its `/<v>/gps|dvl|ins|depth` topics) or columns.

    Mission seconds count from `start_ns` (default: the archive's first message, as the engine's).
    Raises `UserError` when the archive holds none of the vehicle's navigation topics.
    """
    config = config or NavigationConfig()
    if isinstance(source, ArchiveReader):
        topics = set(source.summary().topics)
        if not any(f"/{vehicle}/{t}" in topics for t in ("gps", "dvl", "ins")):
            raise UserError(f"{source.path}: no /{vehicle}/gps, /{vehicle}/dvl or /{vehicle}/ins to review")
        start = start_ns if start_ns is not None else source.summary().start_ns
        if start is None:
            raise UserError(f"{source.path}: the archive holds no messages")
        cols = read_columns(source, vehicle, int(start))
        damage = source.warning()
    else:
        cols, damage = source, None
    velocity = cols.dvl.velocities()      # a rangefinder's altitude-only samples are not lost bottom lock
    dr = dead_reckon(cols.fixes, velocity, cols.ins, config.dvl_hold_s, config.heading_max_gap_s)
    errors = fix_errors(cols.fixes, dr, cols.ins, config.dive_gap_s, config.ins_max_age_s)
    dv = dives(errors)
    counts = SensorCounts.of(cols)
    return NavigationReview(
        vehicle=vehicle,
        start_ns=cols.start_ns,
        config=config,
        columns=cols,
        counts=counts,
        dead_reckoning=dr,
        fix_errors=errors,
        dives=dv,
        bottom_lock=bottom_lock(velocity, config.lock_min_gap_s, config.lock_bin_s),
        series=navigation_series(cols.dvl, cols.ins, cols.depth),
        notes=notes(counts, cols.dropped, errors, dv, config) + ((f"archive: {damage}",) if damage else ()),
    )


@dataclass(frozen=True)
class NavigationScore:
    """One scoreboard row: method name, vehicle and figures keyed as the cooperative methods' metrics.

    figures: ``error_p50_m``, ``error_p90_m``, ``error_max_m`` (at the fixes
    scored), ``final_drift_pct`` (the last dive's error in % of its distance;
    NaN without dives), ``worst_fix_s`` (mission seconds of the largest
    error), ``fixes`` (how many were scored) and ``scored_at`` ("dive ends"
    when the trial has dives, else "every fix").
    """

    method: str
    vehicle: str
    figures: dict[str, Any]


def _figures(t_s: np.ndarray, error_m: np.ndarray, last_pct: float, scored_at: str) -> dict[str, Any]:
    ok = np.isfinite(error_m)
    e, t = error_m[ok], t_s[ok]
    if e.size == 0:
        return {"error_p50_m": math.nan, "error_p90_m": math.nan, "error_max_m": math.nan,
                "final_drift_pct": last_pct, "worst_fix_s": math.nan, "fixes": 0, "scored_at": scored_at}
    worst = int(np.argmax(e))
    return {"error_p50_m": float(np.percentile(e, 50)), "error_p90_m": float(np.percentile(e, 90)),
            "error_max_m": float(e[worst]), "final_drift_pct": last_pct, "worst_fix_s": float(t[worst]),
            "fixes": int(e.size), "scored_at": scored_at}


def scores(review: NavigationReview) -> list[NavigationScore]:
    """Scoreboard rows for the DR (when the vehicle has a DVL) and the INS (when it has INS positions).

    Errors are scored at the fixes that end a dive when there are any, else
    at every fix after the first: a fix a second after the last one says
    little about drift, so dives are preferred wherever the trial has them.
    """
    fe, dv = review.fix_errors, review.dives
    rows = fe.dive_end if len(dv) else np.arange(fe.t_s.size) > 0
    scored_at = "dive ends" if len(dv) else "every fix"
    last = -1 if len(dv) else None
    out: list[NavigationScore] = []
    if review.counts.dvl_velocity:
        pct = float(dv.dr_pct[last]) if last is not None else math.nan
        out.append(NavigationScore(DR_METHOD, review.vehicle, _figures(fe.t_s[rows], fe.dr_error_m[rows], pct,
                                                                        scored_at)))
    if review.counts.ins_positions:
        pct = float(dv.ins_pct[last]) if last is not None else math.nan
        out.append(NavigationScore(INS_METHOD, review.vehicle, _figures(fe.t_s[rows], fe.ins_error_m[rows], pct,
                                                                         scored_at)))
    return out


def _json_number(v: Any) -> Any:
    """A figure as JSON takes it: None for NaN, plain Python numbers."""
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(float(v)) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def review_metrics(review: NavigationReview) -> dict[str, Any]:
    """The review as metrics.json holds it: scoreboard rows, dives, bottom lock and notes, in mission seconds."""
    dv, lock = review.dives, review.bottom_lock
    return {
        "methods": {s.method: {k: _json_number(v) for k, v in s.figures.items()} for s in scores(review)},
        "dives": [{k: _json_number(getattr(dv, k)[i]) for k in ("start_s", "end_s", "duration_s", "dr_error_m",
                                                                 "ins_error_m", "distance_m", "dr_pct", "ins_pct")}
                  for i in range(len(dv))],
        "bottom_lock": {"samples": lock.samples, "sample_share": _json_number(lock.sample_share),
                        "time_share": _json_number(lock.time_share),
                        "gaps": [[_json_number(a), _json_number(b)] for a, b in
                                 zip(lock.gap_start_s, lock.gap_end_s, strict=True)]},
        "notes": list(review.notes),
    }
