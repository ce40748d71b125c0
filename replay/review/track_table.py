"""The review's tracks table while a run collects it: one list per column, of plain floats and strings.

A run's tens of thousands of track rows as one tuple each kept the garbage collector busy (every few hundred
new containers start a collection, and older ones are walked again); floats and strings in lists are no
containers of their own. Degrees, standard deviations and the east/north of the rows after the origin are
computed over the column when a frame is taken, with the operations one row at a time used (the same bits).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import repeat

import numpy as np
import pandas as pd

from replay.review.columns import column
from replay.stack.model import horizontal_offset_m

RAD = 180.0 / math.pi

TRACK_COLUMNS = ("t_s", "vehicle", "source", "lat_deg", "lon_deg", "east_m", "north_m", "std_east_m", "std_north_m")
"""The tracks table's columns, in order."""

class TrackTable:
    """Track rows (time, vehicle, source, latitude and longitude in rad, the estimate's east and north variances,
    east/north) as columns; rows added while an origin is known get their east/north about it."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.vehicle: list[str] = []
        self.source: list[str] = []
        self.lat: list[float] = []
        self.lon: list[float] = []
        self.var_e: list[float] = []      # NaN: no standard deviation (all but the filters' estimates)
        self.var_n: list[float] = []
        self.east: list[float] = []       # NaN until resolved, and for ever on rows from before the origin
        self.north: list[float] = []
        self.origin: tuple[float, float] | None = None
        self._pending: tuple[list[int], list[float], list[float]] = ([], [], [])   # rows, their lat and lon (rad)
        self._resolved: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []      # rows, their east and north

    def __len__(self) -> int:
        return len(self.t)

    def set_origin(self, lat_rad: float, lon_rad: float) -> None:
        """A new origin for the rows from now on (those before keep the one they were added under)."""
        self.resolve()
        self.origin = (lat_rad, lon_rad)

    def add(self, t_s: float, vehicle: str, source: str, lat: float, lon: float) -> None:
        """One row without standard deviations."""
        self.add_many([t_s], vehicle, [source], [lat], [lon])

    def add_many(self, ts: Sequence[float], vehicle: str, sources: Sequence[str], lat: Sequence[float],
                 lon: Sequence[float], var_e: Sequence[float] | None = None,
                 var_n: Sequence[float] | None = None) -> None:
        """Rows of one vehicle: times, sources, latitudes and longitudes (rad), and variances when they have some."""
        k, first = len(ts), len(self.t)
        if self.origin is not None:
            rows, lats, lons = self._pending
            rows.extend(range(first, first + k))
            lats.extend(lat)
            lons.extend(lon)
        self.t.extend(ts)
        self.vehicle.extend(repeat(vehicle, k))
        self.source.extend(sources)
        self.lat.extend(lat)
        self.lon.extend(lon)
        nan = repeat(math.nan, k)
        self.var_e.extend(nan if var_e is None else var_e)
        self.var_n.extend(repeat(math.nan, k) if var_n is None else var_n)
        self.east.extend(repeat(math.nan, k))
        self.north.extend(repeat(math.nan, k))

    def add_placed(self, t_s: float, vehicle: str, source: str, lat: float, lon: float, east: float,
                   north: float) -> None:
        """One row whose east/north are known (a positioning fix, its latitude and longitude made from them)."""
        self.t.append(t_s)
        self.vehicle.append(vehicle)
        self.source.append(source)
        self.lat.append(lat)
        self.lon.append(lon)
        self.var_e.append(math.nan)
        self.var_n.append(math.nan)
        self.east.append(east)
        self.north.append(north)

    def resolve(self) -> None:
        """East/north of the rows waiting for theirs: horizontal_offset_m over the column, element for element
        what it gives one point at a time."""
        rows, lats, lons = self._pending
        if not rows or self.origin is None:
            return
        n, e = horizontal_offset_m(np.array(lats), np.array(lons), *self.origin)
        self._resolved.append((np.array(rows), np.asarray(e, dtype=float), np.asarray(n, dtype=float)))
        self._pending = ([], [], [])

    def frame(self, start: int = 0) -> pd.DataFrame | None:
        """The rows from `start` on as a frame of TRACK_COLUMNS; None when there are none."""
        if start >= len(self.t):
            return None
        self.resolve()
        lat, lon = np.array(self.lat[start:], dtype=float), np.array(self.lon[start:], dtype=float)
        east, north = np.array(self.east[start:], dtype=float), np.array(self.north[start:], dtype=float)
        for rows, e, n in self._resolved:
            keep = rows >= start
            east[rows[keep] - start] = e[keep]
            north[rows[keep] - start] = n[keep]
        # sqrt(max(v, 0)) as one row took it: a NaN stays NaN, -0.0 stays -0.0
        var_e, var_n = np.array(self.var_e[start:], dtype=float), np.array(self.var_n[start:], dtype=float)
        std_e = np.sqrt(np.where(var_e < 0.0, 0.0, var_e))
        std_n = np.sqrt(np.where(var_n < 0.0, 0.0, var_n))
        return pd.DataFrame(dict(zip(TRACK_COLUMNS, (
            column(self.t[start:]), column(self.vehicle[start:]), column(self.source[start:]), lat * RAD, lon * RAD,
            east, north,
            std_e, std_n), strict=True)))
