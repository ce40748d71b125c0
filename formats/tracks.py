"""A named track of timed WGS84 positions: what the GeoJSON and KML writers take."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Track:
    """One vehicle's path from one source: UTC ns times, degrees, and seconds from the trial start.

    `properties` are written beside the geometry as they are (strings and numbers).
    """

    name: str
    time_ns: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    mission_s: np.ndarray
    properties: dict[str, Any] = field(default_factory=dict)

    def finite(self) -> Track:
        """The track without points whose latitude or longitude is not a finite number in range."""
        ok = (np.isfinite(self.lat_deg) & np.isfinite(self.lon_deg) & (np.abs(self.lat_deg) <= 90)
              & (np.abs(self.lon_deg) <= 180))
        return Track(self.name, self.time_ns[ok], self.lat_deg[ok], self.lon_deg[ok], self.mission_s[ok],
                     self.properties)


def iso_utc(time_ns: np.ndarray) -> list[str]:
    """ISO 8601 UTC times to the millisecond ('2016-10-12T02:00:01.000Z'), as GeoJSON and KML readers expect."""
    ms = np.asarray(time_ns, dtype="int64") // 1_000_000
    return [f"{s}Z" for s in np.datetime_as_string(ms.astype("datetime64[ms]"), unit="ms")]
