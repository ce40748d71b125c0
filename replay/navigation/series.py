"""Depth, altitude, heading and speed of one vehicle over mission time, as arrays ready to plot.

Depth comes from a depth sensor where the archive has one, else from the
INS; altitude is the DVL's over the bottom, on locked samples only; speed is
the DVL's speed over ground (locked samples in the body or earth frame: a
horizontal norm needs no heading, but an instrument frame may be tilted)
and the INS's from its north/east velocity. Non-finite samples are left
out, so every series is plottable as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .columns import DvlColumns, InsColumns, SeriesColumns

__all__ = ["NavigationSeries", "Series", "navigation_series"]


@dataclass(frozen=True)
class Series:
    """One quantity over time: its name, unit, source, times (mission s) and values (finite only)."""

    name: str
    unit: str
    source: str
    t_s: np.ndarray
    values: np.ndarray

    @classmethod
    def of(cls, name: str, unit: str, source: str, t_s: np.ndarray, values: np.ndarray) -> Series:
        """A series keeping only rows with a finite time and value."""
        keep = np.isfinite(t_s) & np.isfinite(values)
        return cls(name, unit, source, t_s[keep], values[keep])

    def __len__(self) -> int:
        return int(self.t_s.size)


@dataclass(frozen=True)
class NavigationSeries:
    """The review's series: depth, DVL altitude, INS heading, DVL and INS speed."""

    depth: Series
    altitude: Series
    heading: Series
    speed_dvl: Series
    speed_ins: Series

    def all(self) -> tuple[Series, ...]:
        """Every series, in plotting order."""
        return (self.depth, self.altitude, self.heading, self.speed_dvl, self.speed_ins)


def navigation_series(dvl: DvlColumns, ins: InsColumns, depth: SeriesColumns | None = None) -> NavigationSeries:
    """The series of one vehicle from its columns (a depth sensor, when given and not empty, wins over the INS)."""
    if depth is not None and depth.t_s.size:
        depth_s = Series.of("depth", "m", "depth sensor", depth.t_s, depth.values)
    else:
        depth_s = Series.of("depth", "m", "ins", ins.t_s, ins.depth_m)
    # altitude where the DVL has bottom lock, or from a rangefinder (an altitude without velocity)
    lock = (dvl.valid & np.isfinite(dvl.vx_mps) & np.isfinite(dvl.vy_mps)) | dvl.ranging
    t_lock, use = dvl.t_s[lock], dvl.usable
    return NavigationSeries(
        depth=depth_s,
        altitude=Series.of("altitude", "m", "dvl", t_lock, dvl.altitude_m[lock]),
        heading=Series.of("heading", "deg", "ins", ins.t_s, np.mod(ins.heading_deg, 360.0)),
        speed_dvl=Series.of("speed over ground", "m/s", "dvl", dvl.t_s[use],
                            np.hypot(dvl.vx_mps[use], dvl.vy_mps[use])),
        speed_ins=Series.of("speed", "m/s", "ins", ins.t_s, np.hypot(ins.vn_mps, ins.ve_mps)),
    )
