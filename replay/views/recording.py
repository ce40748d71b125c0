"""Rerun views of replay runs: one recording (one run, or two compared) with its blueprint, saved as .rrd.

`build_recording` turns `ReviewData` into a Rerun recording with the columnar API
(`send_columns`: one call per entity and series, no Python loop per sample);
`save_rrd` writes it atomically with the blueprint inside; `open_viewer` opens a
file in Rerun's native viewer, or in the web viewer bound to 127.0.0.1 only, the file served to it
over HTTP on 127.0.0.1 (`replay.views.web`: the page shows its loading progress at once).

Timelines: every mission row is on both `time` (UTC timestamps, trial_start_ns + t_s) and
`mission_s` (seconds from the trial start, the one time base of the events, `compare` and
`export`); `anfis_epoch` (sequence) for ANFIS training. Entity layout per run under
``/<run_id>``: ``scoreboard``, ``map``, ``local``, ``series``, ``features``, ``scores``, ``why``, ``cdf``,
``anfis``, ``kmcdf``, ``events``, ``info`` (see the other modules of ``replay.views``); ``/colour_key``
and ``/lanes`` once per recording. This package's modules are
the only ones that import `rerun` (with `replay.views.kmcdf`).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from replay.review.data import ReviewData
from replay.views.anfis import log_anfis
from replay.views.blueprint import build_blueprint
from replay.views.cdf import Growth, error_axis, log_cdf_frame, log_cdf_legend, log_cdfs
from replay.views.common import Run, annotation_context, make_runs, no_cycle_collection, run_names
from replay.views.features import log_detector_scores, log_features, log_why
from replay.views.focus import hidden_methods
from replay.views.lanes import detector_order, log_lanes
from replay.views.positioning import log_events, log_kmcdf
from replay.views.scores import log_scores
from replay.views.series import error_ceiling, log_detections, log_errors, log_mission_span, log_ranges
from replay.views.tracks import log_colour_key, log_local_scale, log_range_circles, log_tracks
from replay.views.vehicle import log_vehicles
from replay.views.web import WEB_BIND, free_port, serve_file, viewer_url, web_viewer_command


def recording_id(reviews: list[ReviewData]) -> str:
    """A deterministic recording id from the run ids (no random default)."""
    return "auvreplay:" + "+".join(r.run_id or f"run{i}" for i, r in enumerate(reviews))


def _summary(run: Run) -> str:
    rv = run.review
    vehicles = ", ".join(f"{k} ({v})" for k, v in rv.vehicles.items())
    lines = [f"# {rv.trial}: run {rv.run_id}", "", f"vehicles: {vehicles}", "",
             f"methods: {', '.join(rv.methods)}", ""]
    if rv.metrics:
        lines += ["```json", json.dumps(rv.metrics, indent=1, default=str)[:20000], "```"]
    return "\n".join(lines)


def log_review(rec: rr.RecordingStream, run: Run, axes: dict, error_top: float,
               lane_order: list[str] | None = None) -> Growth:
    """Every view's entities for one run (`lane_order`: its detection lanes' order, replay.views.lanes); its
    p50s as the CDFs grow (for the legend, shared by the runs)."""
    rec.log(run.prefix, annotation_context(run, run_names(run.review)), static=True)
    rec.log(run.path("info"), rr.TextDocument(_summary(run), media_type="text/markdown"), static=True)
    log_tracks(rec, run)
    log_range_circles(rec, run)
    log_ranges(rec, run)
    log_detections(rec, run)
    log_lanes(rec, run, lane_order)
    log_features(rec, run)
    log_detector_scores(rec, run)
    log_why(rec, run)
    log_errors(rec, run, error_top)
    growth = log_cdfs(rec, run, axes)
    log_anfis(rec, run)
    log_kmcdf(rec, run)
    log_vehicles(rec, run)
    log_events(rec, run)
    return growth


def prepare(reviews: list[ReviewData], active_tab: int | str = 0,
            focus: Sequence[str] | None = None) -> tuple[list[Run], dict, float, rrb.Blueprint]:
    """The runs of one or two reviews, their error axes and ceiling, and the workstation blueprint (`focus`:
    the methods shown at first, replay.views.focus)."""
    if not 1 <= len(reviews) <= 2:
        raise ValueError(f"a recording takes one run or two to compare, got {len(reviews)}")
    runs = make_runs(reviews)
    error_top = error_ceiling([r.errors for r in reviews])
    return runs, error_axis(runs), error_top, build_blueprint(runs, error_top, active_tab, focus)


def log_runs(rec: rr.RecordingStream, reviews: list[ReviewData], runs: list[Run], axes: dict,
             error_top: float, focus: Sequence[str] | None = None) -> None:
    """Everything of the runs into a recording: its name and start, scores, colour key, CDF frame, every view."""
    rec.send_recording_name(" vs ".join(f"{r.trial} {run.label or r.run_id}" for r, run in zip(reviews, runs,
                                                                                             strict=True)))
    rec.send_recording_start_time_nanos(int(reviews[0].trial_start_ns))
    log_scores(rec, runs)
    log_colour_key(rec, runs, focus)
    log_local_scale(rec, runs)
    log_mission_span(rec, runs)
    log_cdf_frame(rec, runs, axes)
    order = detector_order(runs[0])       # both runs of a comparison rank their lanes alike: neighbours
    growth = [log_review(rec, run, axes, error_top, order) for run in runs]
    log_cdf_legend(rec, runs, growth, frozenset(m for r in runs for m in hidden_methods(r, focus)))


def build_recording(reviews: list[ReviewData], application_id: str = "auvreplay",
                    path: str | os.PathLike[str] | None = None, active_tab: int | str = 0,
                    focus: Sequence[str] | None = None) -> rr.RecordingStream:
    """A recording of one or two runs with the blueprint; streamed to `path` (.rrd) when given, else buffered."""
    with no_cycle_collection():
        runs, axes, error_top, blueprint = prepare(reviews, active_tab, focus)
        rec = rr.RecordingStream(application_id, recording_id=recording_id(reviews), send_properties=False)
        if path is not None:
            rec.save(str(path), default_blueprint=blueprint)
        else:
            rec.send_blueprint(blueprint)
        log_runs(rec, reviews, runs, axes, error_top, focus)
    return rec


def save_rrd(reviews: list[ReviewData], path: str | os.PathLike[str], application_id: str = "auvreplay",
             active_tab: int | str = 0, focus: Sequence[str] | None = None) -> Path:
    """Write the recording with its blueprint to `path`: a temporary name first, renamed when complete."""
    out = Path(path)
    tmp = out.with_name(out.name + ".partial")
    rec = build_recording(reviews, application_id, tmp, active_tab, focus)
    rec.flush()
    rec.disconnect()
    os.replace(tmp, out)
    return out


def rerun_executable() -> str:
    """The `rerun` CLI installed with rerun-sdk (beside this interpreter first, then PATH)."""
    local = Path(sys.executable).parent / "rerun"
    if local.exists():
        return str(local)
    found = shutil.which("rerun")
    if found is None:
        raise FileNotFoundError("the rerun command (installed with rerun-sdk) was not found")
    return found


def viewer_command(path: str | os.PathLike[str], web: bool = False) -> list[str]:
    """The command that opens an .rrd or .mcap file: native viewer, or web viewer on 127.0.0.1 only (streamed
    through Rerun's gRPC proxy; `open_viewer` serves the file by URL instead)."""
    cmd = [rerun_executable(), str(path)]
    if web:
        cmd += ["--web-viewer", "--bind", WEB_BIND]
    return cmd


def open_viewer(path: str | os.PathLike[str], web: bool = False) -> int:
    """Open a file in Rerun and wait for the viewer (or the web server) to exit; its exit code.

    The web viewer gets the file by URL from a server of our own on 127.0.0.1 (`replay.views.web`).
    """
    if not Path(path).exists():
        raise FileNotFoundError(f"{path}: no such file")
    if not web:
        return subprocess.run(viewer_command(path), check=False).returncode
    port = free_port()
    with serve_file(path, port) as served:
        print(f"serving {path} on {WEB_BIND} to the web viewer: {viewer_url(served.url, port)}", flush=True)
        return subprocess.run(web_viewer_command(rerun_executable(), served.url, port), check=False).returncode
