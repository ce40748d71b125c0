"""Cooperative-localization model (seed A, eqs. A.1-A.5): dead reckoning, ranges, unit conversions.

The earth radii and metres-per-radian scales (A.2, A.3) are `formats.geodesy`'s.

State order everywhere in the stack: ``X = [L, λ]`` = [latitude, longitude] in
radians (docs/design.md section 7). Covariances are given by users in metres
(north, east) and converted to radians with the local radii.

All functions broadcast over leading axes, so the same code propagates one
state, the 2n cubature points of one filter, or the points of every method
at once.
"""

from __future__ import annotations

import math

import numpy as np

from formats.geodesy import metric_scales, metric_scales_scalar


def dead_reckon_step(
    state: np.ndarray, dt_s: float, forward_mps: float, lateral_mps: float,
    heading_rad: float, depth_m: float,
) -> np.ndarray:
    """One dead-reckoning step X_k = f(X_{k-1}, v, ω, θ) of A.1 on states (..., 2) = [L, λ].

    The radii and cos L are evaluated at the previous latitude L_{k-1}: A.1
    writes them at L_k, which is not known before the step (explicit Euler;
    the difference is ~1e-13 relative per metre moved).
    """
    lat = state[..., 0]
    b, a = metric_scales(lat, depth_m)
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    north = forward_mps * c - lateral_mps * s
    east = forward_mps * s + lateral_mps * c
    out = np.empty_like(state)
    out[..., 0] = lat + dt_s * north / b
    out[..., 1] = state[..., 1] + dt_s * east / a
    return out


def horizontal_range(
    state: np.ndarray, depth_m: float | np.ndarray,
    leader_lat_rad: float | np.ndarray, leader_lon_rad: float | np.ndarray,
    leader_depth_m: float | np.ndarray,
) -> np.ndarray:
    """Horizontal range Z = h(X^m, X) between follower states (..., 2) and a leader (A.4, amended).

    Deviation from A.4: the seed multiplies each vehicle's own radii by its
    absolute angles, (b L - b^m L^m); evaluated literally the tiny difference
    of radii times a whole latitude or longitude leaves hundreds of metres
    (971 m at 126.6° E in a prototype). We use common radii at the mid-point
    latitude and mean depth of the two vehicles times the angle differences
    (docs/design.md section 7):  b̄ = R_M(L̄) + h̄,  ā = (R_N(L̄) + h̄) cos L̄,
    Z = sqrt((b̄ ΔL)² + (ā Δλ)²).
    """
    lat = state[..., 0]
    mid = 0.5 * (lat + leader_lat_rad)
    b, a = metric_scales(mid, 0.5 * (depth_m + leader_depth_m))
    dn = b * (lat - leader_lat_rad)
    de = a * (state[..., 1] - leader_lon_rad)
    return np.sqrt(dn * dn + de * de)


def slant_to_horizontal(slant_m: float, depth_m: float, leader_depth_m: float) -> tuple[float, bool]:
    """Horizontal range sqrt(r² - Δh²) from a slant range (A.4); (0, True) when clamped, never NaN."""
    dz = abs(depth_m - leader_depth_m)
    r = abs(slant_m)
    if not (r > dz and slant_m > 0.0):  # also catches NaN from non-finite inputs
        return 0.0, True
    q = dz / r                          # r·sqrt(1 - q²) cannot overflow where r² - Δh² would
    return r * math.sqrt((1.0 - q) * (1.0 + q)), False


def radian_scaling(lat_rad: np.ndarray | float, depth_m: np.ndarray | float) -> np.ndarray:
    """Diagonal of D with X_rad = D X_m for [north, east] metres -> [L, λ] radians, shape (..., 2)."""
    b, a = metric_scales(lat_rad, depth_m)
    return np.stack(np.broadcast_arrays(1.0 / b, 1.0 / a), axis=-1)


def cov_metres_to_radians(cov_m2: np.ndarray, lat_rad: np.ndarray | float, depth_m: float = 0.0) -> np.ndarray:
    """Convert north-east covariances (..., 2, 2) in m² to [L, λ] covariances in rad² (D C D)."""
    d = radian_scaling(lat_rad, depth_m)
    return cov_m2 * d[..., :, None] * d[..., None, :]


def cov_radians_to_metres(cov_rad2: np.ndarray, lat_rad: np.ndarray | float,
                          depth_m: np.ndarray | float = 0.0) -> np.ndarray:
    """Convert [L, λ] covariances (..., 2, 2) in rad² back to north-east m² (D⁻¹ C D⁻¹)."""
    d = radian_scaling(lat_rad, depth_m)
    return cov_rad2 / (d[..., :, None] * d[..., None, :])


def horizontal_offset_m(
    lat_rad: np.ndarray | float, lon_rad: np.ndarray | float, ref_lat_rad: np.ndarray | float,
    ref_lon_rad: np.ndarray | float,
) -> tuple[np.ndarray, np.ndarray]:
    """North and east offsets (m) of points from reference points, radii at the mid latitude."""
    b, a = metric_scales(0.5 * (lat_rad + ref_lat_rad), 0.0)
    return b * (lat_rad - ref_lat_rad), a * (lon_rad - ref_lon_rad)


def horizontal_distance_scalar(lat_rad: float, lon_rad: float, ref_lat_rad: float, ref_lon_rad: float) -> float:
    """Scalar ``horizontal_distance_m`` with the math module, for per-fix loops (numpy scalars cost ~10x)."""
    b, a = metric_scales_scalar(0.5 * (lat_rad + ref_lat_rad), 0.0)
    return math.hypot(b * (lat_rad - ref_lat_rad), a * (lon_rad - ref_lon_rad))


def offset_to_latlon(north_m: float, east_m: float, ref_lat_rad: float, ref_lon_rad: float) -> tuple[float, float]:
    """Latitude and longitude (rad) of a north/east offset from a reference: the inverse of horizontal_offset_m."""
    lat = ref_lat_rad
    for _ in range(4):     # the radii at the mid latitude barely move: a few fixed-point steps reach 1e-12 m
        b, a = metric_scales_scalar(0.5 * (lat + ref_lat_rad), 0.0)
        lat = ref_lat_rad + north_m / b
    _, a = metric_scales_scalar(0.5 * (lat + ref_lat_rad), 0.0)
    return lat, ref_lon_rad + east_m / a


def horizontal_distance_m(
    lat_rad: np.ndarray, lon_rad: np.ndarray, ref_lat_rad: np.ndarray, ref_lon_rad: np.ndarray,
) -> np.ndarray:
    """Horizontal distance (m) between points and reference points (same common-radii form as A.4)."""
    dn, de = horizontal_offset_m(lat_rad, lon_rad, ref_lat_rad, ref_lon_rad)
    return np.hypot(dn, de)
