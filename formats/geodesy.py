"""Earth radii and local east/north metres <-> latitude/longitude, for every layer.

The radii are the first-order expansion in the flattening f that the
cooperative-localization model writes (seed A, eq. A.2):

    R_M = R_e (1 - 2f + 3f sin²L)    (meridian)
    R_N = R_e (1 + f sin²L)          (prime vertical)

with the WGS84 equatorial radius R_e and f = 1/298.257 as the paper gives it.
Against the exact WGS84 radii they differ by at most 1.2e-5 relative (order f²), far
below any sensor's noise; every layer uses these so the simulator, the
recorders and the estimator stack agree to the last bit.

A `LocalFrame` maps east/north metres about an origin to degrees with the
origin's radii: one fixed scaling, not a projection, so the map is exactly
invertible; over a few kilometres it differs from radii taken at each
point's own latitude by about 1e-5 (1 cm per km).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TypeVar

import numpy as np

RE_M: float = 6378137.0
"""Earth equatorial radius R_e (m, WGS84)."""
FLATTENING: float = 1.0 / 298.257
"""Earth flattening f as eq. A.2 writes it."""

# degrees per radian and back, as math.degrees/np.degrees and math.radians/np.radians multiply
_DEG_PER_RAD = 180.0 / math.pi
_RAD_PER_DEG = math.pi / 180.0

Coordinate = TypeVar("Coordinate", float, np.ndarray)


def earth_radii(lat_rad: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Meridian and prime-vertical radii R_M, R_N (m) at latitude L (rad), broadcast over arrays."""
    s2 = np.sin(lat_rad) ** 2
    r_m = RE_M * (1.0 - 2.0 * FLATTENING + 3.0 * FLATTENING * s2)
    r_n = RE_M * (1.0 + FLATTENING * s2)
    return r_m, r_n


def metric_scales(lat_rad: np.ndarray | float, depth_m: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Metres per radian (b, a) = (R_M + h, (R_N + h) cos L) along [latitude, longitude]."""
    r_m, r_n = earth_radii(lat_rad)
    return r_m + depth_m, (r_n + depth_m) * np.cos(lat_rad)


def metric_scales_scalar(lat_rad: float, depth_m: float) -> tuple[float, float]:
    """Scalar `metric_scales` with the math module (per-epoch hot paths): (R_M + h, (R_N + h) cos L)."""
    s2 = math.sin(lat_rad) ** 2
    return (RE_M * (1.0 - 2.0 * FLATTENING + 3.0 * FLATTENING * s2) + depth_m,
            (RE_M * (1.0 + FLATTENING * s2) + depth_m) * math.cos(lat_rad))


@lru_cache(maxsize=256)
def _origin_scales(lat0_deg: float) -> tuple[float, float]:
    """Metres per radian north and east at an origin's latitude (depth 0)."""
    r_m, r_n = earth_radii(math.radians(lat0_deg))
    return float(r_m), float(r_n) * math.cos(math.radians(lat0_deg))


def local_to_geodetic(east_m: Coordinate, north_m: Coordinate, lat0_deg: float, lon0_deg: float
                      ) -> tuple[Coordinate, Coordinate]:
    """Latitude and longitude in degrees (not wrapped) of east/north metres about an origin, its radii."""
    b, a = _origin_scales(lat0_deg)
    return lat0_deg + north_m / b * _DEG_PER_RAD, lon0_deg + east_m / a * _DEG_PER_RAD


def geodetic_to_local(lat_deg: Coordinate, lon_deg: Coordinate, lat0_deg: float, lon0_deg: float
                      ) -> tuple[Coordinate, Coordinate]:
    """East/north metres about an origin of latitude and longitude in degrees: `local_to_geodetic` inverted."""
    b, a = _origin_scales(lat0_deg)
    return (lon_deg - lon0_deg) * _RAD_PER_DEG * a, (lat_deg - lat0_deg) * _RAD_PER_DEG * b


@dataclass(frozen=True)
class LocalFrame:
    """East/north metres about an origin (degrees): `local_to_geodetic` and its inverse bound to the origin.

    Takes floats or numpy arrays alike: the same operations in the same
    order, so a scalar maps to the bits its array element maps to.
    """

    lat0_deg: float
    lon0_deg: float

    @property
    def scales(self) -> tuple[float, float]:
        """(b, a): metres per radian north and east at the origin."""
        return _origin_scales(self.lat0_deg)

    def to_geodetic(self, east_m: Coordinate, north_m: Coordinate) -> tuple[Coordinate, Coordinate]:
        """Latitude and longitude in degrees (not wrapped) for local east/north metres."""
        return local_to_geodetic(east_m, north_m, self.lat0_deg, self.lon0_deg)

    def to_local(self, lat_deg: Coordinate, lon_deg: Coordinate) -> tuple[Coordinate, Coordinate]:
        """Local east/north metres for latitude and longitude in degrees."""
        return geodetic_to_local(lat_deg, lon_deg, self.lat0_deg, self.lon0_deg)
