"""The live view of a capture: positions as they are decoded, estimates as the online engine makes them.

Entities are those of a replay run (`replay.views.tracks`, `positioning`) under
the run's prefix, so the live recording and the final one line up:
``P/map/<vehicle>/<source>/position`` GeoPoints on `time` for recorded GPS and
INS positions (logged as soon as they are decoded, without waiting for the
engine) and for every method's estimate, and ``P/events`` for the engine's
events. Rows are buffered and sent with `send_columns` at most every
`every_s` seconds; at the end the capture logs the complete replay views
(tracks, series, CDFs, ANFIS, KMCDF) with their blueprint into the same
recording (`finish`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

from formats.units import NS
from replay.events import Listener
from replay.review.data import ReviewData
from replay.views.common import class_id, mission_column, part
from replay.views.recording import log_runs, prepare

RAD = 180.0 / math.pi


def open_stream(run_id: str, spawn: bool = False, connect: str | None = None,
                rrd: str | None = None) -> rr.RecordingStream:
    """A recording for a live capture: spawned viewer, a viewer at a gRPC address, and/or an .rrd file."""
    rec = rr.RecordingStream("auvreplay", recording_id=f"auvreplay:live:{run_id}", send_properties=False)
    if rrd is not None:
        rec.save(rrd)
    if spawn:
        rec.spawn()
    if connect is not None:
        rec.connect_grpc(connect)
    rec.send_recording_name(f"live capture {run_id}")
    return rec


class LiveView(Listener):
    """Buffers positions and estimates; `flush` sends what came since the last one."""

    def __init__(self, rec: rr.RecordingStream, run_id: str, every_s: float = 0.1, measure: bool = False):
        self.rec, self.run_id, self.every_s = rec, run_id, every_s
        self.prefix = "/" + part(run_id)
        self.t0_ns: int | None = None
        self._rows: dict[tuple[str, str], list[tuple[int, float, float]]] = {}
        self._events: list[tuple[int, str, str]] = []
        self._received: list[int] = []
        self._next = 0.0
        self.measure = measure
        self.latencies_ms: list[float] = []  # receive -> sent to Rerun, with `measure`

    def attach(self, t0_ns: int) -> LiveView:
        """The trial start the engine's times count from (the online run calls this when it starts)."""
        self.t0_ns = t0_ns
        return self

    def recorded(self, topic: str, t_ns: int, msg: Any, received_ns: int | None = None) -> None:
        """A decoded archive message: GPS fixes and INS positions are shown at once."""
        kind = topic.rsplit("/", 1)[-1]
        if kind not in ("gps", "ins"):
            return
        lat, lon = float(msg.latitude), float(msg.longitude)
        if not (math.isfinite(lat) and math.isfinite(lon)):
            return
        vehicle = topic.split("/")[1]
        self._rows.setdefault((vehicle, kind), []).append((t_ns, lat, lon))
        if self.measure and received_ns is not None:
            self._received.append(received_ns)

    def estimates(self, follower: str, t_s: float, estimates: Mapping[str, tuple[float, ...]]) -> None:
        """Every method's estimate at t (lat, lon in radians)."""
        if self.t0_ns is None:
            return
        t = self.t0_ns + round(t_s * NS)
        for method, (lat, lon, *_) in estimates.items():
            self._rows.setdefault((follower, method), []).append((t, lat * RAD, lon * RAD))

    def event(self, t_s: float, level: str, text: str) -> None:
        """An engine event."""
        if self.t0_ns is not None:
            self._events.append((self.t0_ns + round(t_s * NS), level.upper(), text))

    def _times(self, t_ns: np.ndarray) -> list[rr.TimeColumn]:
        """UTC and mission seconds (from the trial start, once the engine said it) of receive-stamped rows."""
        cols = [rr.TimeColumn("time", timestamp=t_ns.astype("datetime64[ns]"))]
        if self.t0_ns is not None:
            cols.append(mission_column((t_ns - self.t0_ns) / NS))
        return cols

    def flush(self, force: bool = False) -> None:
        """Send the buffered rows, at most every `every_s` unless forced."""
        now = time.monotonic()
        if not force and now < self._next:
            return
        self._next = now + self.every_s
        for (vehicle, source), rows in self._rows.items():
            if not rows:
                continue
            arr = np.array(rows, dtype=np.float64)
            n = len(rows)
            self.rec.send_columns(
                f"{self.prefix}/map/{part(vehicle)}/{part(source)}/position",
                indexes=self._times(np.array([r[0] for r in rows], dtype=np.int64)),
                columns=rr.GeoPoints.columns(positions=arr[:, 1:3],
                                             class_ids=np.full(n, class_id(source), dtype=np.uint16),
                                             radii=np.full(n, rr.Radius.ui_points(5.0), dtype=np.float32)))
            rows.clear()
        if self._events:
            times = np.array([e[0] for e in self._events], dtype=np.int64)
            self.rec.send_columns(
                f"{self.prefix}/events", indexes=self._times(times),
                columns=rr.TextLog.columns(text=[e[2] for e in self._events], level=[e[1] for e in self._events]))
            self._events.clear()
        if self._received:
            sent = time.time_ns()
            self.latencies_ms.extend((sent - r) / 1e6 for r in self._received)
            self._received.clear()

    def finish(self, review: ReviewData | None) -> None:
        """Send what is left; then the complete replay views of the online run, with their blueprint."""
        self.flush(force=True)
        if review is not None:
            runs, axes, error_top, blueprint = prepare([review])
            self.rec.send_blueprint(blueprint)
            log_runs(self.rec, [review], runs, axes, error_top)
        self.rec.flush()
        self.rec.disconnect()
