"""Truth tracks of the lake trial's boats, in the local frame of `formats.geodesy.LocalFrame`.

Tracks are closed racetracks (straight legs and constant-rate turns) repeated
for as long as the trial lasts, with a slow heading and speed wander and a
small sideslip so they look like boats steered by people, not a plotter.
Everything is built with cumulative sums over the whole time axis.
`track_from_fixes` makes a truth track of recorded GPS fixes instead
(`simulate --tracks`, samples/recorded.py).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import lfilter

from formats.geodesy import LocalFrame


def stream(seed: int, *names: str) -> np.random.Generator:
    """An independent generator per purpose, so adding a vehicle never shifts another's noise."""
    return np.random.default_rng([seed, *(zlib.crc32(n.encode()) for n in names)])


def gauss_markov(rng: np.random.Generator, n: int, dt: float, sigma: float, tau: float) -> np.ndarray:
    """First-order Gauss-Markov samples, stationary from the first sample."""
    if n == 0 or sigma == 0:
        return np.zeros(n)
    phi = math.exp(-dt / tau)
    w = rng.standard_normal(n) * sigma * math.sqrt(1 - phi * phi)
    w[0] = rng.standard_normal() * sigma
    return lfilter([1.0], [1.0, -phi], w)


@dataclass(frozen=True)
class Leg:
    """A piece of a racetrack: duration, speed, and turn rate (deg/s, + = to starboard)."""

    duration_s: float
    speed_mps: float
    turn_dps: float = 0.0


@dataclass(frozen=True)
class TrackPlan:
    """A vehicle's closed track: start pose, transducer depth and the legs of one lap."""

    start_east_m: float
    start_north_m: float
    heading_deg: float
    depth_m: float
    legs: tuple[Leg, ...]


# transducer depths: a modem hung 1.5 m under a leader boat, 2.5 m under the follower
LEADER_DEPTH_M = 1.5
FOLLOWER_DEPTH_M = 2.5
# below this speed (m/s) a course over ground is noise: the heading of a track made of fixes is held instead
HEADING_HOLD_SPEED_MPS = 0.2


def default_plans(followers: int) -> dict[str, TrackPlan]:
    """Leaders north and east of a follower racetrack, over about 1.2 x 0.8 km."""
    plans = {
        "leader1": TrackPlan(-200.0, 250.0, 90.0, LEADER_DEPTH_M, (
            Leg(260, 2.3), Leg(60, 2.3, 3.0), Leg(260, 2.3), Leg(60, 2.3, 3.0))),
        "leader2": TrackPlan(686.0, -500.0, 0.0, LEADER_DEPTH_M, (
            Leg(300, 1.8), Leg(75, 1.8, -2.4), Leg(300, 1.8), Leg(75, 1.8, -2.4))),
    }
    for k in range(followers):
        name = "follower" if k == 0 else f"follower{k + 1}"
        # extra followers run the same racetrack 130 m further south
        plans[name] = TrackPlan(-420.0, -100.0 - 130.0 * k, 90.0, FOLLOWER_DEPTH_M, (
            Leg(420, 2.0), Leg(90, 2.0, 2.0), Leg(420, 2.0), Leg(90, 2.0, 2.0)))
    return plans


@dataclass(frozen=True)
class Track:
    """Truth of one vehicle on the truth time axis (seconds from the trial start)."""

    name: str
    t_s: np.ndarray
    east_m: np.ndarray
    north_m: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    depth_m: np.ndarray
    heading_deg: np.ndarray
    roll_deg: np.ndarray
    pitch_deg: np.ndarray
    surge_mps: np.ndarray
    sway_mps: np.ndarray
    vel_north_mps: np.ndarray
    vel_east_mps: np.ndarray
    vel_down_mps: np.ndarray


def _leg_profile(plan: TrackPlan, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speed and turn rate at every time, the lap repeated."""
    ends = np.cumsum([leg.duration_s for leg in plan.legs])
    phase = np.mod(t, ends[-1])
    idx = np.minimum(np.searchsorted(ends, phase, side="right"), len(ends) - 1)
    speed = np.array([leg.speed_mps for leg in plan.legs])[idx]
    turn = np.array([leg.turn_dps for leg in plan.legs])[idx]
    return speed, turn


def make_track(name: str, plan: TrackPlan, t: np.ndarray, frame: LocalFrame, seed: int) -> Track:
    """A boat's truth track: the plan plus wander, integrated over the time axis."""
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    rng = stream(seed, "track", name)
    n = len(t)
    speed, turn = _leg_profile(plan, t)
    surge = speed + gauss_markov(rng, n, dt, 0.05, 60.0)
    sway = gauss_markov(rng, n, dt, 0.05, 30.0)
    wander = gauss_markov(rng, n, dt, 2.0, 30.0)
    heading = plan.heading_deg + np.concatenate(([0.0], np.cumsum(turn[:-1]) * dt)) + wander
    h = np.radians(heading)
    vn = surge * np.cos(h) - sway * np.sin(h)
    ve = surge * np.sin(h) + sway * np.cos(h)
    north = plan.start_north_m + np.concatenate(([0.0], np.cumsum(vn[:-1]) * dt))
    east = plan.start_east_m + np.concatenate(([0.0], np.cumsum(ve[:-1]) * dt))
    lat, lon = frame.to_geodetic(east, north)
    roll = gauss_markov(rng, n, dt, 1.5, 2.0)
    pitch = gauss_markov(rng, n, dt, 0.8, 2.0)
    return Track(name, t, east, north, lat, lon, np.full(n, plan.depth_m), np.mod(heading, 360.0),
                 roll, pitch, surge, sway, vn, ve, np.zeros(n))


def _held_heading(course_deg: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """The course where the vehicle moves; elsewhere the last course it moved on (the first one before it moves)."""
    if not moving.any():
        return np.zeros(len(course_deg))
    idx = np.where(moving, np.arange(len(course_deg)), -1)
    idx = np.maximum.accumulate(idx)
    idx[idx < 0] = int(np.argmax(moving))
    return course_deg[idx]


def _smoothed(x: np.ndarray, sigma: float) -> np.ndarray:
    """x smoothed by a Gaussian of `sigma` samples, the ends extended by point reflection (x0 - (x_k - x0)).

    A vehicle under way keeps its velocity at the ends of a track, where a
    constant extension would slow it down and put a DR off by metres.
    """
    if sigma < 0.1 or len(x) < 2:          # under a tenth of a sample the kernel is one sample wide
        return x
    pad = min(int(4 * sigma) + 1, len(x) - 1)
    ext = np.concatenate((2 * x[0] - x[pad:0:-1], x, 2 * x[-1] - x[-2:-pad - 2:-1]))
    return gaussian_filter1d(ext, sigma, mode="nearest")[pad:pad + len(x)]


def track_from_fixes(name: str, fix_t_s: np.ndarray, fix_east_m: np.ndarray, fix_north_m: np.ndarray,
                     t: np.ndarray, frame: LocalFrame, depth_m: float, seed: int, smoothing_s: float) -> Track:
    """A truth track through recorded fixes (seconds, local metres; times increasing) on the time axis `t`.

    Positions are the fixes interpolated linearly, so the track passes through
    every fix. Velocity is the derivative of the positions smoothed by a
    Gaussian of `smoothing_s` seconds; the heading is its course (held where the
    vehicle is slower than HEADING_HOLD_SPEED_MPS), so surge is its speed and
    sway 0 but where the heading is held: a DR of the track's heading, surge
    and sway follows the smoothed path, within
    the fixes' noise of the track itself. Roll and pitch wander as `make_track`'s.
    """
    n = len(t)
    dt = float(t[1] - t[0]) if n > 1 else 1.0
    east = np.interp(t, fix_t_s, fix_east_m)
    north = np.interp(t, fix_t_s, fix_north_m)
    ve = np.gradient(_smoothed(east, smoothing_s / dt), dt) if n > 1 else np.zeros(n)
    vn = np.gradient(_smoothed(north, smoothing_s / dt), dt) if n > 1 else np.zeros(n)
    speed = np.hypot(ve, vn)
    heading = _held_heading(np.mod(np.degrees(np.arctan2(ve, vn)), 360.0), speed > HEADING_HOLD_SPEED_MPS)
    h = np.radians(heading)
    surge = vn * np.cos(h) + ve * np.sin(h)
    sway = ve * np.cos(h) - vn * np.sin(h)
    rng = stream(seed, "track", name)
    roll = gauss_markov(rng, n, dt, 1.5, 2.0)
    pitch = gauss_markov(rng, n, dt, 0.8, 2.0)
    lat, lon = frame.to_geodetic(east, north)
    return Track(name, t, east, north, lat, lon, np.full(n, depth_m), heading, roll, pitch, surge, sway, vn, ve,
                 np.zeros(n))


def interp_track(track: Track, t: np.ndarray) -> dict[str, np.ndarray]:
    """East, north, depth and heading of a track at arbitrary times (heading unwrapped first)."""
    head = np.degrees(np.unwrap(np.radians(track.heading_deg)))
    return {
        "east_m": np.interp(t, track.t_s, track.east_m),
        "north_m": np.interp(t, track.t_s, track.north_m),
        "depth_m": np.interp(t, track.t_s, track.depth_m),
        "heading_deg": np.mod(np.interp(t, track.t_s, head), 360.0),
    }
