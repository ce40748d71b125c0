"""A replay drawn while it runs: each stretch of the mission sent to the viewer as the engine produces it.

`StreamedRecording` hears the replay through the pipeline's `on_block` callback. Once the engine has passed
FIRST_S of mission time, and then at most every STRETCH_WALL_S of wall time, it takes the review collector's
rows added since the last stretch (a `ReviewData` of that stretch alone) and logs them with the views' own
functions, one `send_columns` per entity and stretch: tracks and trails on the map and the local plot,
range circles, ranges and residuals, paper A's features and the ANFIS outputs against T2, every method's
error, the new features, every detector's score against its threshold, and the event log. Those functions
give the same rows for a run cut in stretches as for the whole run (the trails carry their bins across
stretches, `replay.views.tracks.Trails`).

What needs the whole run waits for its end (`finish`): the whole-track lines, the truth marks (scaled to the
run's largest threshold), the t_a line, the detection lanes (ranked by the scoreboard), the why documents,
the CDFs, ANFIS, KMCDF, the vehicles' own navigation (computed at the end), the scoreboard, the colour key
and the summary. `finish` logs the whole run with `replay.views.recording.log_runs`, the bulk path itself,
less the rows the stretches already sent (`_Filter`), and sends the final blueprint; so the recording
holds the same entities and rows as the bulk one, but for the `/mission_span` entity, which also holds the
archive's last second (the axes span the mission from the first stretch on).

The first blueprint goes with the first stretch (built from it, its error axis from its errors): every
tab is there, its plots on axes that span the mission.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any, cast

import pandas as pd
import rerun as rr

from replay.review.collector import ReviewCollector
from replay.review.data import ReviewData
from replay.views.blueprint import build_blueprint
from replay.views.common import METHOD_STYLE, annotation_context, make_runs
from replay.views.features import log_detector_scores, log_features
from replay.views.positioning import log_events
from replay.views.recording import log_runs, prepare, recording_id
from replay.views.series import SPAN, error_ceiling, log_detections, log_errors, log_mission_span, log_ranges
from replay.views.tracks import Trails, log_range_circles, log_tracks

FIRST_S = 60.0
"""The first stretch is sent once the engine has passed this much mission time: the first minute, at once."""
STRETCH_WALL_S = 1.0
"""Later stretches are sent at most this often (wall seconds): a few large chunks, never one per block."""
TABLES = ("tracks", "ranges", "detections", "errors", "events")
"""The collector's tables the stretches draw (the others are drawn whole at the end)."""
# entities a stretch must not send: they depend on the whole run and are sent by `finish`
_LATER_STATIC = ("/track", "/features/note", "/scores/key")
_LATER_ROWS = ("/truth", "/marks/t_a")


class _Filter:
    """A RecordingStream seen through rules: `static_ok` and `rows_ok` say which static logs and which temporal
    rows (per entity path) pass; the paths that got temporal rows are added to `sent`."""

    def __init__(self, rec: rr.RecordingStream, static_ok: Callable[[str], bool], rows_ok: Callable[[str], bool],
                 sent: set[str] | None = None) -> None:
        self._rec, self._static_ok, self._rows_ok, self._sent = rec, static_ok, rows_ok, sent

    def log(self, path: str, *args: Any, static: bool = False, **kwargs: Any) -> None:
        if (self._static_ok if static else self._rows_ok)(path):
            if not static and self._sent is not None:
                self._sent.add(path)
            self._rec.log(path, *args, static=static, **kwargs)

    def send_columns(self, path: str, *args: Any, **kwargs: Any) -> None:
        if self._rows_ok(path):
            if self._sent is not None:
                self._sent.add(path)
            self._rec.send_columns(path, *args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._rec, name)


def _stretch_static(path: str) -> bool:
    return not path.endswith(_LATER_STATIC)


def _stretch_rows(path: str) -> bool:
    return not path.endswith(_LATER_ROWS) and path != SPAN


class StreamedRecording:
    """Stretches of one run sent as the replay produces them (`on_block`), and the rest at its end (`finish`).

    `rec` is the recording stream, its sinks set (the viewer, the .rrd); `end_s` the mission's last second as
    the archive says (the span of every time axis); `focus` as `view --focus`.
    """

    def __init__(self, rec: rr.RecordingStream, end_s: float | None, focus: Sequence[str] | None = None,
                 first_s: float = FIRST_S, every_wall_s: float = STRETCH_WALL_S) -> None:
        self.rec, self.end_s, self.focus = rec, end_s, focus
        self.first_s, self.every_wall_s = first_s, every_wall_s
        self.collector: ReviewCollector | None = None
        self.stretches = 0
        self.first_sent_at: float | None = None        # time.monotonic() of the first stretch sent
        self._taken = dict.fromkeys(TABLES, 0)
        self._trails: Trails = {}
        self._sent: set[str] = set()
        self._last = 0.0

    def on_block(self, collector: ReviewCollector | None, t_s: float) -> None:
        """The pipeline's callback after each block: send a stretch when one is due."""
        if collector is None:
            return
        self.collector = collector
        if self.stretches == 0 and t_s < self.first_s:
            return
        if self.stretches and time.monotonic() - self._last < self.every_wall_s:
            return
        self.send_stretch()

    def _stretch(self) -> ReviewData | None:
        """The rows collected since the last stretch, as a ReviewData of that stretch; None when there are none."""
        c = self.collector
        if c is None:
            return None
        origin = getattr(c, "_origin", None)
        data = ReviewData(c.run_id, str(c.trial.get("name", "")), c.t0_ns,
                          origin[0] * 57.29577951308232 if origin else float("nan"),
                          origin[1] * 57.29577951308232 if origin else float("nan"), dict(c.layout.roles))
        fresh = False
        for name in TABLES:
            rows = c.rows[name]
            if len(rows) > self._taken[name]:
                setattr(data, name, pd.DataFrame(rows[self._taken[name]:]))
                self._taken[name] = len(rows)
                fresh = True
        return data if fresh else None

    def send_stretch(self) -> None:
        """Log the rows collected since the last stretch (the first stretch: the name, span and blueprint too)."""
        data = self._stretch()
        if data is None:
            return
        run = make_runs([data])[0]
        rec = cast(rr.RecordingStream, _Filter(self.rec, _stretch_static, _stretch_rows, self._sent))
        if self.stretches == 0:
            self.rec.send_recording_name(f"{data.trial} {data.run_id}")
            self.rec.send_recording_start_time_nanos(int(data.trial_start_ns))
            self.rec.send_blueprint(build_blueprint([run], error_ceiling([data.errors]), 0, self.focus))
            if self.end_s is not None:
                log_mission_span(self.rec, [run], self.end_s)
            self.first_sent_at = time.monotonic()
        # every name the palette knows: the class ids' colours hold before the run's own names are known
        self.rec.log(run.prefix, annotation_context(run, [n for n, _ in METHOD_STYLE]), static=True)
        log_tracks(rec, run, self._trails)
        log_range_circles(rec, run)
        log_ranges(rec, run)
        log_detections(rec, run)
        log_errors(rec, run, 1.0)
        log_features(rec, run)
        log_detector_scores(rec, run)
        log_events(rec, run)
        self.stretches += 1
        self._last = time.monotonic()

    def finish(self, review: ReviewData) -> None:
        """The last stretch (rows collected since, the dead-reckoning tracks and notes among them), then the whole
        run less the rows already sent, and the final blueprint."""
        if self.collector is not None:
            self.send_stretch()
        runs, axes, error_top, blueprint = prepare([review], 0, self.focus)
        sent = self._sent
        if self.end_s is None:
            sent = sent - {SPAN}
        rec = cast(rr.RecordingStream, _Filter(self.rec, lambda _: True, lambda p: p not in sent))
        log_runs(rec, [review], runs, axes, error_top, self.focus)
        self.rec.send_blueprint(blueprint)


def stream_recording(application_id: str, reviews_id: str) -> rr.RecordingStream:
    """A recording stream with the id the bulk path gives one run (`recording_id`), its sinks not yet set."""
    return rr.RecordingStream(application_id, recording_id=reviews_id, send_properties=False)


__all__ = ["FIRST_S", "STRETCH_WALL_S", "StreamedRecording", "recording_id", "stream_recording"]
