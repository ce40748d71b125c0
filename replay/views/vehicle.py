"""A vehicle's own navigation on screen: depth, altitude, heading, speed, drift at the GPS fixes, bottom lock.

Entities under a run prefix P, per vehicle V with a navigation review (`replay.navigation`):
- ``P/vehicle/V/depth|altitude|heading|speed/<source>``: the series over mission time;
- ``P/vehicle/V/error/<source>``: the error against each GPS fix of the dead reckoning restarted at the
  fixes and of the INS (markers: one per fix);
- ``P/vehicle/V/lock``: the share of DVL samples with bottom lock per bin (a step line);
- ``P/vehicle/V/summary``: the vehicle's scoreboard rows, its dives, its bottom-lock gaps and the notes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from replay.navigation.review import DR_METHOD, INS_METHOD, NavigationReview, review_metrics
from replay.review.scoreboard import NAV_HEADINGS, format_value
from replay.views.common import Run

# (key, title of its plot, unit): the panels of a vehicle, in screen order
PANELS: tuple[tuple[str, str], ...] = (
    ("depth", "Depth and altitude (m)"),
    ("heading", "Heading (deg true)"),
    ("speed", "Speed (m/s): DVL over ground, INS"),
    ("lock", "Bottom lock: share of DVL samples per bin"),
)
SOURCE_RGB = {"depth": (90, 160, 255), "altitude": (200, 160, 0), "heading": (160, 120, 220),
              "dvl": (60, 200, 120), "ins": (176, 150, 110), "lock": (60, 200, 120),
              # the two errors side by side need two hues far apart (the palette's DR and INS are both browns)
              "dr_error": (255, 140, 30), "ins_error": (100, 180, 255)}
SUMMARY_COLUMNS = ("error_p50_m", "error_p90_m", "error_max_m", "final_drift_pct", "worst_fix_s")
MAX_ROWS = 12     # dives and gaps listed in the summary; the rest counted


def _series(rec: rr.RecordingStream, run: Run, path: str, t_s: np.ndarray, v: np.ndarray, name: str,
            rgb: tuple[int, int, int], markers: bool = False, step: bool = False) -> None:
    """One series where it is finite, as a line (or markers), in bulk."""
    ok = np.isfinite(t_s) & np.isfinite(v)
    if not ok.any():
        return
    style = (rr.SeriesPoints(names=name, colors=[rgb], marker_sizes=3.0) if markers else
             rr.SeriesLines(names=name, colors=[rgb], widths=1.2, interpolation_mode="StepAfter" if step else None))
    rec.log(path, style, static=True)
    rec.send_columns(path, indexes=run.times(t_s[ok]), columns=rr.Scalars.columns(scalars=v[ok]))


def summary_markdown(nav: NavigationReview, figures: dict[str, Any] | None = None) -> str:
    """The vehicle's ranked sources, its dives, its bottom-lock gaps and the notes, in mission seconds.

    `figures` is the review as the run's metrics hold it (metrics.json's `navigation`); computed when not given.
    """
    m = figures if figures is not None else review_metrics(nav)
    rows = m["methods"]
    first: dict[str, Any] = next(iter(rows.values()), {})
    lines = [f"**{nav.vehicle}: own navigation against GPS**, at {first.get('fixes', 0)} fixes "
             f"({first.get('scored_at', 'none')})", "",
             "| source | " + " | ".join(NAV_HEADINGS[c] for c in SUMMARY_COLUMNS) + " |",
             "|---|" + "---:|" * len(SUMMARY_COLUMNS)]
    lines += [f"| {name} | " + " | ".join(format_value(row.get(c)) for c in SUMMARY_COLUMNS) + " |"
              for name, row in rows.items()]
    dives = m["dives"]
    lines += ["", f"**Dives** (GPS gaps longer than {nav.config.dive_gap_s:g} s): {len(dives)}"]
    if dives:
        lines += ["", "| start (s) | end (s) | length (s) | DR error (m) | INS error (m) | distance (m) | DR % "
                      "| INS % |", "|---:|---:|---:|---:|---:|---:|---:|---:|"]
        lines += ["| " + " | ".join(format_value(d[k]) for k in ("start_s", "end_s", "duration_s", "dr_error_m",
                                                                   "ins_error_m", "distance_m", "dr_pct", "ins_pct"))
                  + " |" for d in dives[:MAX_ROWS]]
        lines += [f"... and {len(dives) - MAX_ROWS} more"] if len(dives) > MAX_ROWS else []
    lock = m["bottom_lock"]
    if lock["samples"]:
        gaps = lock["gaps"]
        lines += ["", f"**Bottom lock**: {format_value(lock['sample_share'])} of {lock['samples']} DVL samples, "
                      f"{format_value(lock['time_share'])} of the time; {len(gaps)} gap(s) of "
                      f"{nav.config.lock_min_gap_s:g} s or more"]
        lines += [f"- {format_value(a)} s to {format_value(b)} s" for a, b in gaps[:MAX_ROWS]]
        lines += [f"- ... and {len(gaps) - MAX_ROWS} more"] if len(gaps) > MAX_ROWS else []
    lines += ["", "**Notes**", ""] + [f"- {n}" for n in m["notes"]]
    return "\n".join(lines)


def log_vehicles(rec: rr.RecordingStream, run: Run) -> None:
    """Every navigation review of a run: its series, errors at fixes, bottom lock and summary."""
    for vehicle, nav in run.review.navigation.items():
        def path(*parts: str, v: str = vehicle) -> str:
            return run.path("vehicle", v, *parts)
        s = nav.series
        _series(rec, run, path("depth", "depth"), s.depth.t_s, s.depth.values, run.name(f"depth ({s.depth.source})"),
                SOURCE_RGB["depth"])
        _series(rec, run, path("depth", "altitude"), s.altitude.t_s, s.altitude.values, run.name("altitude (DVL)"),
                SOURCE_RGB["altitude"])
        _series(rec, run, path("heading", "heading"), s.heading.t_s, s.heading.values,
                run.name(f"heading ({s.heading.source})"), SOURCE_RGB["heading"], markers=True)
        _series(rec, run, path("speed", "dvl"), s.speed_dvl.t_s, s.speed_dvl.values, run.name("DVL"),
                SOURCE_RGB["dvl"])
        _series(rec, run, path("speed", "ins"), s.speed_ins.t_s, s.speed_ins.values, run.name("INS"),
                SOURCE_RGB["ins"])
        lock = nav.bottom_lock
        _series(rec, run, path("lock", "share"), lock.bin_start_s, lock.bin_share, run.name("bottom lock"),
                SOURCE_RGB["lock"], step=True)
        fe = nav.fix_errors
        _series(rec, run, path("error", "dead_reckoning"), fe.t_s, fe.dr_error_m, run.name(DR_METHOD),
                SOURCE_RGB["dr_error"], markers=True)
        _series(rec, run, path("error", "ins"), fe.t_s, fe.ins_error_m, run.name(INS_METHOD),
                SOURCE_RGB["ins_error"], markers=True)
        figures = run.review.metrics.get("navigation", {}).get(vehicle)
        rec.log(path("summary"), rr.TextDocument(summary_markdown(nav, figures), media_type="text/markdown"),
                static=True)
