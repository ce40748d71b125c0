"""Sensor models of the lake trial: GPS, INS and DVL measurements from the truth tracks.

Every series is sampled on its own regular grid (seconds from the trial
start) and built with whole-array operations; noise comes from per-vehicle,
per-sensor generators (`trajectories.stream`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from formats.geodesy import LocalFrame

from .conditions import bottom_lock, compass_deviation
from .scenario import Conditions, DvlConfig, GpsConfig, InsConfig
from .trajectories import Track, gauss_markov, stream

# lake surface height above mean sea level and the local geoid separation
# (Harbin area; only written into GGA, never used by the stack)
LAKE_MSL_M = 116.0
GEOID_SEPARATION_M = -8.0


def grid(duration_s: float, rate_hz: float, first_s: float = 0.0) -> np.ndarray:
    """Sample times first, first + 1/rate, ... up to the duration (integer steps, no drift)."""
    n = int(math.floor((duration_s - first_s) * rate_hz + 1e-9)) + 1
    return first_s + np.arange(max(n, 0)) / rate_hz


def _at(track: Track, t: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.interp(t, track.t_s, values)


@dataclass(frozen=True)
class GpsSeries:
    """GPS fixes of one vehicle: time, position, and the receiver's quality figures."""

    t_s: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    altitude_m: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    sigma_m: float
    hdop: np.ndarray
    satellites: np.ndarray
    speed_mps: np.ndarray
    course_deg: np.ndarray


def simulate_gps(track: Track, cfg: GpsConfig, frame: LocalFrame, duration_s: float,
                 seed: int, rate_hz: float | None = None) -> GpsSeries:
    """Single-point fixes: truth plus Gauss-Markov errors of `horizontal_rms_m` RMS."""
    t = grid(duration_s, rate_hz or cfg.rate_hz)
    rng = stream(seed, "gps", track.name)
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    sigma = cfg.horizontal_rms_m / math.sqrt(2.0)
    east = _at(track, t, track.east_m) + gauss_markov(rng, len(t), dt, sigma, cfg.correlation_time_s)
    north = _at(track, t, track.north_m) + gauss_markov(rng, len(t), dt, sigma, cfg.correlation_time_s)
    alt = LAKE_MSL_M + 1.5 + gauss_markov(rng, len(t), dt, cfg.vertical_sigma_m, cfg.correlation_time_s)
    lat, lon = frame.to_geodetic(east, north)
    hdop = np.round(0.9 + 0.2 * np.abs(gauss_markov(rng, len(t), dt, 1.0, 120.0)), 1)
    sats = 9 + np.round(gauss_markov(rng, len(t), dt, 1.0, 300.0)).astype(int)
    # Doppler velocity: a few cm/s of noise, unlike differenced positions
    ve = _at(track, t, track.vel_east_mps) + rng.standard_normal(len(t)) * 0.03
    vn = _at(track, t, track.vel_north_mps) + rng.standard_normal(len(t)) * 0.03
    course = np.mod(np.degrees(np.arctan2(ve, vn)), 360.0)
    return GpsSeries(t, lat, lon, alt, east, north, sigma, hdop, np.clip(sats, 5, 12), np.hypot(ve, vn), course)


@dataclass(frozen=True)
class InsSeries:
    """INS solutions of one vehicle with the standard deviations the unit reports."""

    t_s: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    depth_m: np.ndarray
    roll_deg: np.ndarray
    pitch_deg: np.ndarray
    heading_deg: np.ndarray
    vel_north_mps: np.ndarray
    vel_east_mps: np.ndarray
    vel_down_mps: np.ndarray
    heading_std_deg: float
    position_std_m: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray


def heading_error(track: Track, cfg: InsConfig, leader: bool, seed: int,
                  conditions: Conditions | None = None) -> np.ndarray:
    """Heading error on the truth axis: white for a high-grade unit, bias + random walk (+ deviation) otherwise."""
    rng = stream(seed, "ins-heading", track.name)
    n = len(track.t_s)
    if leader:
        return rng.standard_normal(n) * cfg.leader_heading_sigma_deg
    dt = float(track.t_s[1] - track.t_s[0]) if n > 1 else 1.0
    walk = np.cumsum(rng.standard_normal(n)) * cfg.follower_heading_walk_deg_per_sqrt_s * math.sqrt(dt)
    err = cfg.follower_heading_bias_deg + walk - walk[0]
    if conditions is not None and conditions.compass_deviation_deg > 0:
        err = err + compass_deviation(conditions, track.heading_deg, track.name, seed)
    return err


def simulate_ins(track: Track, cfg: InsConfig, frame: LocalFrame, duration_s: float,
                 leader: bool, seed: int, conditions: Conditions | None = None) -> InsSeries:
    """INS output: GPS-aided high-grade on leaders, a drifting low-grade solution on followers."""
    t = grid(duration_s, cfg.rate_hz)
    rng = stream(seed, "ins", track.name)
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    n = len(t)
    vn, ve = _at(track, t, track.vel_north_mps), _at(track, t, track.vel_east_mps)
    if leader:
        s, tau = cfg.leader_position_sigma_m, cfg.leader_position_correlation_s
        de, dn = gauss_markov(rng, n, dt, s, tau), gauss_markov(rng, n, dt, s, tau)
        dve = dvn = np.zeros(n)
        pos_std = np.full(n, s)
    else:
        s, tau = cfg.follower_velocity_error_mps, cfg.follower_velocity_correlation_s
        dve, dvn = gauss_markov(rng, n, dt, s, tau), gauss_markov(rng, n, dt, s, tau)
        de = np.concatenate(([0.0], np.cumsum(dve[:-1]) * dt))
        dn = np.concatenate(([0.0], np.cumsum(dvn[:-1]) * dt))
        pos_std = 1.0 + s * t
    east, north = _at(track, t, track.east_m) + de, _at(track, t, track.north_m) + dn
    lat, lon = frame.to_geodetic(east, north)
    unwrapped = np.degrees(np.unwrap(np.radians(track.heading_deg)))
    head_err = heading_error(track, cfg, leader, seed, conditions)
    heading = np.mod(np.interp(t, track.t_s, unwrapped + head_err), 360.0)
    att = cfg.attitude_sigma_deg
    roll = _at(track, t, track.roll_deg) + rng.standard_normal(n) * att
    pitch = _at(track, t, track.pitch_deg) + rng.standard_normal(n) * att
    # the unit reports the size of its heading error: a drawn bias may be negative, a std never is
    head_std = cfg.leader_heading_sigma_deg if leader else abs(cfg.follower_heading_bias_deg)
    return InsSeries(t, lat, lon, _at(track, t, track.depth_m), roll, pitch, heading, vn + dvn,
                     ve + dve, np.zeros(n), head_std, pos_std, east, north)


@dataclass(frozen=True)
class DvlSeries:
    """Bottom-track velocities in the body frame (x forward, y starboard, z down); NaN without bottom lock."""

    t_s: np.ndarray
    forward_mps: np.ndarray
    starboard_mps: np.ndarray
    down_mps: np.ndarray
    error_mps: np.ndarray
    beam_range_m: np.ndarray
    altitude_m: np.ndarray
    heading_deg: np.ndarray
    roll_deg: np.ndarray
    pitch_deg: np.ndarray
    valid: np.ndarray                   # bottom lock: False where a condition took it (velocities, beams NaN)


def lake_depth(cfg: DvlConfig, east_m: np.ndarray, north_m: np.ndarray) -> np.ndarray:
    """A smooth lake bottom: depth below the surface in metres."""
    return cfg.lake_depth_m + cfg.lake_depth_variation_m * np.sin(east_m / 300.0) * np.cos(north_m / 250.0)


def simulate_dvl(track: Track, cfg: DvlConfig, duration_s: float, rate_hz: float,
                 seed: int, heading_deg: np.ndarray | None = None, conditions: Conditions | None = None) -> DvlSeries:
    """DVL bottom track: truth body velocities plus `sigma_mps` noise, four beam ranges.

    `heading_deg` (the vehicle's INS heading on the truth axis) is what a PD0
    ensemble carries in its variable leader; truth when not given. Pings
    without bottom lock (`conditions`' lock loss) have NaN velocities and beams.
    """
    t = grid(duration_s, rate_hz)
    rng = stream(seed, "dvl", track.name)
    n = len(t)
    noise = rng.standard_normal((4, n)) * cfg.sigma_mps
    altitude = lake_depth(cfg, _at(track, t, track.east_m), _at(track, t, track.north_m)) - _at(
        track, t, track.depth_m)
    roll, pitch = _at(track, t, track.roll_deg), _at(track, t, track.pitch_deg)
    tilt = np.radians(np.stack([roll, -roll, pitch, -pitch]))
    beam_angle = math.radians(cfg.beam_angle_deg)
    beams = altitude / np.cos(beam_angle + tilt) + rng.standard_normal((4, n)) * 0.05
    head = heading_deg if heading_deg is not None else track.heading_deg
    unwrapped = np.degrees(np.unwrap(np.radians(head)))
    lock = bottom_lock(conditions, t, track.name, duration_s, seed) if conditions is not None \
        else np.ones(n, dtype=bool)
    lost = np.where(lock, 0.0, np.nan)                  # NaN where lock is lost, 0 (adds nothing) elsewhere
    return DvlSeries(
        t, _at(track, t, track.surge_mps) + noise[0] + lost, _at(track, t, track.sway_mps) + noise[1] + lost,
        noise[2] + lost, noise[3] * 0.5 + lost, beams.T + lost[:, None], altitude,
        np.mod(np.interp(t, track.t_s, unwrapped), 360.0), roll, pitch, lock,
    )
