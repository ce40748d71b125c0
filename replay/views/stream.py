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

import os
import socket
import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import rerun as rr

from replay.review.collector import ReviewCollector
from replay.review.data import ReviewData
from replay.views.blueprint import build_blueprint
from replay.views.common import METHOD_STYLE, annotation_context, make_runs
from replay.views.features import log_detector_scores, log_features
from replay.views.positioning import log_events
from replay.views.recording import log_runs, prepare, recording_id, rerun_executable
from replay.views.series import SPAN, error_ceiling, log_detections, log_errors, log_mission_span, log_ranges
from replay.views.tracks import Trails, log_range_circles, log_tracks
from replay.views.web import WEB_BIND, free_port

FIRST_S = 60.0
"""The first stretch is sent once the engine has passed this much mission time: the first minute, at once."""
STRETCH_WALL_S = 1.0
"""Later stretches are sent at most this often (wall seconds): a few large chunks, never one per block."""
TABLES = ("tracks", "ranges", "detections", "errors", "events")
"""The collector's tables the stretches draw (the others are drawn whole at the end)."""
# entities a stretch must not send: they depend on the whole run and are sent by `finish`
_LATER_STATIC = ("/track", "/features/note", "/scores/key")
_LATER_ROWS = ("/truth", "/marks/t_a")
WAITING = ("**Scoreboard**: drawn when the replay ends (it ranks the whole run). The tracks, series, errors, "
           "features, scores and events are drawn as the replay goes; the lanes, why documents, CDFs, ANFIS, KMCDF "
           "and each vehicle's navigation at the end.")


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

    `open_stream` makes the recording stream, its sinks set (the viewer, the .rrd), given the recording id (the
    bulk path's, `recording_id`: known once the replay has its run id); `end_s` is the mission's last second
    as the archive says (the span of every time axis); `focus` as `view --focus`.
    """

    def __init__(self, open_stream: Callable[[str], rr.RecordingStream], end_s: float | None,
                 focus: Sequence[str] | None = None, first_s: float = FIRST_S,
                 every_wall_s: float = STRETCH_WALL_S, active_tab: int | str = 0) -> None:
        self.open_stream, self.end_s, self.focus, self.active_tab = open_stream, end_s, focus, active_tab
        self.rec: rr.RecordingStream | None = None
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
            frame = c.table(name, self._taken[name])
            if frame is not None:
                setattr(data, name, frame)
                self._taken[name] = c.count(name)
                fresh = True
        return data if fresh else None

    def send_stretch(self) -> None:
        """Log the rows collected since the last stretch (the first stretch: the name, span and blueprint too)."""
        data = self._stretch()
        if data is None:
            return
        run = make_runs([data])[0]
        out = self.rec = self.rec or self.open_stream(recording_id([data]))
        rec = cast(rr.RecordingStream, _Filter(out, _stretch_static, _stretch_rows, self._sent))
        if self.stretches == 0:
            out.send_recording_name(f"{data.trial} {data.run_id}")
            out.send_recording_start_time_nanos(int(data.trial_start_ns))
            out.send_blueprint(build_blueprint([run], error_ceiling([data.errors]), self.active_tab, self.focus))
            if self.end_s is not None:
                log_mission_span(out, [run], self.end_s)
            # static, as the scoreboard it stands for: the end's scoreboard replaces it
            out.log(run.path("scoreboard"), rr.TextDocument(WAITING, media_type="text/markdown"), static=True)
            self.first_sent_at = time.monotonic()
        # every name the palette knows: the class ids' colours hold before the run's own names are known
        out.log(run.prefix, annotation_context(run, [n for n, _ in METHOD_STYLE]), static=True)
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
        runs, axes, error_top, blueprint = prepare([review], self.active_tab, self.focus)
        out = self.rec = self.rec or self.open_stream(recording_id([review]))
        sent = self._sent
        rec = cast(rr.RecordingStream, _Filter(out, lambda _: True, lambda p: p not in sent))
        log_runs(rec, [review], runs, axes, error_top, self.focus)
        out.send_blueprint(blueprint)


VIEWER_START_S = 20.0
"""How long a viewer we start may take to listen before the replay streams anyway (the sink buffers)."""


@dataclass
class LiveViewer:
    """Where the stretches go: a viewer's gRPC URL, and the viewer process we started (None for --connect)."""

    url: str
    process: subprocess.Popen[bytes] | None = None

    def wait(self) -> int:
        """Wait for the viewer we started to be closed; its exit code (0 for a viewer of someone else's)."""
        return self.process.wait() if self.process is not None else 0


def _listening(port: int, proc: subprocess.Popen[bytes], timeout_s: float = VIEWER_START_S) -> None:
    """Return once something listens on 127.0.0.1:`port`, the process exits, or `timeout_s` passes."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and proc.poll() is None:
        with socket.socket() as s:
            if s.connect_ex((WEB_BIND, port)) == 0:
                return
        time.sleep(0.05)


@contextmanager
def live_viewer(web: bool = False, connect: str | None = None) -> Iterator[LiveViewer]:
    """A viewer to stream to: the gRPC URL given (`connect`), or Rerun's native viewer, or with `web` its web
    viewer, started here on 127.0.0.1 (free ports) and left running for the reviewer when the block ends
    normally (`LiveViewer.wait`); ended if the block fails."""
    if connect:
        yield LiveViewer(connect)
        return
    port = free_port()
    cmd = [rerun_executable(), "--port", str(port), "--expect-data-soon"]
    if web:
        cmd += ["--web-viewer", "--bind", WEB_BIND, "--web-viewer-port", str(free_port())]
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL)
    try:
        _listening(port, proc)
        yield LiveViewer(f"rerun+http://{WEB_BIND}:{port}/proxy", proc)
    except BaseException:
        proc.terminate()
        proc.wait()
        raise


def open_stream(rid: str, path: str | os.PathLike[str], viewer_url: str | None = None,
                application_id: str = "auvreplay") -> rr.RecordingStream:
    """A recording stream with id `rid` into the file `path` and, when given, the viewer at `viewer_url`."""
    rec = rr.RecordingStream(application_id, recording_id=rid, send_properties=False)
    sinks: list[Any] = [rr.FileSink(str(path))]
    if viewer_url:
        sinks.append(rr.GrpcSink(viewer_url))
    rec.set_sinks(*sinks)
    return rec


@dataclass
class Streamed:
    """What a streamed replay gave: its outcome (review data, warning), the recording saved, and when the
    first stretch was sent (seconds from the start, None if none was)."""

    outcome: Any
    path: Path
    first_s: float | None
    stretches: int


def stream_replay(archive: str | Path, out: str | Path, viewer_url: str | None,
                  config: Any = None, focus: Sequence[str] | None = None, first_s: float = FIRST_S,
                  every_wall_s: float = STRETCH_WALL_S, active_tab: int | str = 0) -> Streamed:
    """Replay a trial archive in memory while its stretches go to the viewer at `viewer_url` (None: only to the
    file) and to `out` (.rrd, written under a temporary name and renamed when complete)."""
    from formats.mcap_reader import ArchiveReader
    from replay.run.config import load_config
    from replay.run.pipeline import replay_archive

    start = time.monotonic()
    with ArchiveReader(archive) as reader:
        summary = reader.summary()
    end_s = (summary.end_ns - summary.start_ns) / 1e9 if summary.start_ns is not None and summary.end_ns else None
    path = Path(out)
    tmp = path.with_name(path.name + ".partial")
    streamer = StreamedRecording(lambda rid: open_stream(rid, tmp, viewer_url), end_s, focus, first_s,
                                 every_wall_s, active_tab)
    try:
        outcome = replay_archive(archive, config or load_config(), write_output=False, review=True,
                                 require_work=True, on_block=streamer.on_block)
        streamer.finish(outcome.review)
        if streamer.rec is not None:
            streamer.rec.flush()
    finally:
        if streamer.rec is not None:
            streamer.rec.disconnect()
    os.replace(tmp, path)
    first = streamer.first_sent_at - start if streamer.first_sent_at is not None else None
    return Streamed(outcome, path, first, streamer.stretches)
