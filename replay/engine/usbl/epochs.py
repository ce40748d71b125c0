"""LBL/USBL epochs from an archive: one ping heard by several buoys, positioned by KMCDF.

The recorder dates a USBL observation at the target's transmission
(reception minus the measured delay), so an abnormal delay shifts its time
by up to Rmax/c. Observations of one target within `usbl_group_s` of the
epoch's first one form that epoch (default 2.5 s: half the usual ping
interval); a node heard again starts a new epoch. Buoy
positions come from the buoys' GPS at the reception time, in local
east/north metres around a fixed origin.

Closed epochs are queued and positioned in batches (`batch_size` epochs, and
whatever is left at the final `flush`): one KMCDF call per group of epochs
with the same node count and parameters. Each epoch's result is the one it
would get alone; the callback just hears of it later, with the epoch's own
time and with what `at_close` said when the epoch closed (tracks keep only
recent fixes, so anything read from them must be read then).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from replay.engine.follower import VehicleTracks
from replay.events import UsblEpoch
from replay.stack.model import horizontal_offset_m
from replay.stack.positioning.kmcdf import KmcdfFix, KmcdfParams, kmcdf_epochs


@dataclass(frozen=True)
class _Closed:
    """A closed epoch waiting for its KMCDF fix."""

    t_s: float
    target: str
    nodes: tuple[str, ...]
    node_en: np.ndarray
    delays_s: np.ndarray
    phase_x: np.ndarray
    phase_y: np.ndarray
    params: KmcdfParams
    context: Any


class UsblEpochBuilder:
    """Groups UsblObservation messages into epochs and positions them with KMCDF, in batches.

    `on_epochs` receives each positioned batch, in closing order, with the
    value `at_close(target, t_s)` gave for each epoch when it closed.
    """

    def __init__(self, tracks: dict[str, VehicleTracks], origin: tuple[float, float], group_s: float,
                 params: KmcdfParams, max_gap_s: float,
                 on_epochs: Callable[[list[UsblEpoch], list[Any]], None],
                 at_close: Callable[[str, float], Any] = lambda target, t_s: None, batch_size: int = 64):
        self.tracks, self.origin, self.group_s = tracks, origin, group_s
        self.params, self.max_gap_s, self.on_epochs = params, max_gap_s, on_epochs
        self.at_close, self.batch_size = at_close, batch_size
        self.counts: Counter = Counter()
        self._open: dict[str, list[tuple[float, str, Any, float]]] = {}
        self._closed: list[_Closed] = []
        self._closed_earliest = math.inf   # earliest emission time in _closed: position_due runs per message
        self._earliest = math.inf     # first emission time over the open epochs: flush runs per message

    def add(self, t_s: float, msg: Any) -> None:
        """Add one observation (message time t_s); closes the target's previous epoch when it ended."""
        travel = msg.travel_time_s if math.isfinite(msg.travel_time_s) else msg.range_m / self.params.sound_speed_mps
        if not math.isfinite(travel) or not msg.target:
            self.counts["usbl_without_delay_or_target"] += 1
            return
        emitted = t_s
        group = self._open.setdefault(msg.target, [])
        if group and (emitted - group[0][0] > self.group_s or any(g[1] == msg.node for g in group)):
            self._close(msg.target)
            group = self._open.setdefault(msg.target, [])
        if not group:
            self._earliest = min(self._earliest, emitted)
        group.append((emitted, msg.node, msg, t_s))

    def flush(self, before_s: float = math.inf) -> None:
        """Close every epoch whose emission time is before `before_s`; position all queued ones at the end."""
        if self._earliest < before_s:
            for target in [t for t, g in self._open.items() if g and g[0][0] < before_s]:
                self._close(target)
        if before_s == math.inf:
            self.position_queued()

    def position_due(self, until_s: float) -> None:
        """Position the queued epochs now if one of them is at or before until_s (its fix is needed)."""
        if self._closed_earliest <= until_s:
            self.position_queued()

    def position_queued(self) -> None:
        """Position every closed epoch in the queue (one KMCDF call per node count and parameters)."""
        closed, self._closed = self._closed, []
        self._closed_earliest = math.inf
        if not closed:
            return
        groups: dict[tuple[int, KmcdfParams], list[int]] = {}
        for i, c in enumerate(closed):
            groups.setdefault((len(c.nodes), c.params), []).append(i)
        fixes: dict[int, KmcdfFix] = {}
        for (_, params), members in groups.items():
            nodes, delays, phase_x, phase_y = (np.stack([getattr(closed[i], f) for i in members])
                                               for f in ("node_en", "delays_s", "phase_x", "phase_y"))
            for i, fix in zip(members, kmcdf_epochs(nodes, delays, phase_x, phase_y, params)):
                fixes[i] = fix
        self.on_epochs([UsblEpoch(c.t_s, c.target, c.nodes, c.node_en, c.delays_s, c.phase_x, c.phase_y,
                                  fixes[i], c.params) for i, c in enumerate(closed)], [c.context for c in closed])

    def _close(self, target: str) -> None:
        group = self._open.pop(target, [])
        self._earliest = min((g[0][0] for g in self._open.values() if g), default=math.inf)
        by_node: dict[str, tuple[float, Any, float]] = {}
        for emitted, node, msg, t_s in group:
            by_node.setdefault(node, (emitted, msg, t_s))   # a node heard twice keeps its first
        rows = []
        for node, (_, msg, t_s) in by_node.items():
            known = self.tracks.get(node)
            pos = known.gps.at(t_s, self.max_gap_s) if known is not None else None
            if pos is None:
                self.counts["usbl_node_without_position"] += 1
                continue
            north, east = horizontal_offset_m(pos.lat_rad, pos.lon_rad, *self.origin)
            rows.append((node, float(east), float(north), msg))
        if len(rows) < 3:
            self.counts["usbl_epoch_below_3_nodes"] += 1
            return
        node_en = np.array([[r[1], r[2]] for r in rows])
        delays = np.array([r[3].travel_time_s for r in rows])
        px = np.array([r[3].phase_x_rad for r in rows])
        py = np.array([r[3].phase_y_rad for r in rows])
        params = self._params_for(rows)
        self._closed.append(_Closed(group[0][0], target, tuple(r[0] for r in rows), node_en, delays, px, py,
                                    params, self.at_close(target, group[0][0])))
        self._closed_earliest = min(self._closed_earliest, group[0][0])
        if len(self._closed) >= self.batch_size:
            self.position_queued()

    def _params_for(self, rows: list) -> KmcdfParams:
        """The epoch's sound speed, as the recorder applied it (range / travel time), when the log says."""
        speeds = [r[3].range_m / r[3].travel_time_s for r in rows
                  if math.isfinite(r[3].range_m) and math.isfinite(r[3].travel_time_s) and r[3].travel_time_s > 0]
        if not speeds:
            return self.params
        # statistics.median: np.median's value (middle, or the two middles' sum / 2) at a fraction of its cost
        return dataclasses.replace(self.params, sound_speed_mps=float(statistics.median(speeds)))
