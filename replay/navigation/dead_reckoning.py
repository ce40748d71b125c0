"""Dead reckoning of one vehicle from DVL velocity and heading, restarted at each GPS fix (vectorized).

The velocity model is piecewise constant on the DVL's own time grid: the
velocity of sample k holds on [t_k, t_k+1). A body-frame velocity (x
forward, y starboard) is turned to north/east by the heading interpolated
at t_k (wrap-aware, between heading samples at most `heading_max_gap_s`
apart); an earth-frame one is taken as north/east.

Bottom lock lost (a sample not valid, not finite, or in a frame we cannot
put on the earth) or the DVL silent: the last usable velocity is carried
for at most `hold_s` seconds after the sample that measured it (a body-frame
one still turned by the current heading, since an AUV keeps going where it
points). Past that the displacement is unknown, and the DR is NaN until the
next restart: a position that grows on a guessed velocity would be scored
as if it were measured. The seconds integrated on a carried velocity are
reported (`held_s`) so a reviewer sees which errors lean on it.

Restarts: the track is anchored at every GPS fix. While the vehicle is at
the surface (fixes every second or so) the DR follows GPS; when fixes stop
(a dive) the DR runs from the last fix before the gap, so its error at the
first fix after the gap is exactly the error accumulated during the dive.

Integration is a cumulative sum: P(t) = F_k + v_k (t - t_k) with F the
running integral at the grid times, and the DR from an anchor at t_a is
P(t) - P(t_a), converted to latitude and longitude with the radii at the
mid latitude of anchor and point (the inverse of `model.horizontal_offset_m`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replay.stack.model import horizontal_distance_m, metric_scales

from .columns import BODY_FRD, EARTH_NED, DvlColumns, FixColumns, InsColumns

__all__ = ["DeadReckoning", "VelocityModel", "dead_reckon", "heading_at", "heading_between", "offset_to_latlon",
           "velocity_model"]

_CHANNELS = 4  # north, east, speed (path length) and "carried" (seconds on a held velocity)


def heading_at(t_s: np.ndarray, heading_t_s: np.ndarray, heading_deg: np.ndarray,
               max_gap_s: float) -> np.ndarray:
    """Heading (rad, [0, 2π)) at times `t_s`, interpolated along the shorter arc; NaN where unknown.

    Known at t when heading samples lie on both sides of t (or at t) at most
    `max_gap_s` apart. Non-finite heading samples are left out.
    """
    t_s = np.asarray(t_s, dtype=np.float64)
    keep = np.isfinite(heading_t_s) & np.isfinite(heading_deg)
    ht, hd = heading_t_s[keep], heading_deg[keep]
    return heading_between(t_s, ht, np.unwrap(np.radians(hd)) if ht.size else hd, max_gap_s)


def heading_between(t_s: np.ndarray, ht: np.ndarray, unwrapped: np.ndarray, max_gap_s: float) -> np.ndarray:
    """Heading (rad, [0, 2π)) at `t_s` from finite heading samples already unwrapped (`heading_at`'s rule)."""
    out = np.full(t_s.shape, np.nan)
    if ht.size == 0:
        return out
    after = np.searchsorted(ht, t_s, side="left")          # first sample at or after t
    before = np.searchsorted(ht, t_s, side="right") - 1    # last sample at or before t
    ok = (before >= 0) & (after < ht.size)
    span = np.full(t_s.shape, np.inf)
    span[ok] = ht[np.minimum(after[ok], ht.size - 1)] - ht[before[ok]]
    ok &= span <= max_gap_s
    out[ok] = np.mod(np.interp(t_s[ok], ht, unwrapped), 2.0 * np.pi)
    return out


def offset_to_latlon(north_m: np.ndarray, east_m: np.ndarray, ref_lat_rad: np.ndarray,
                     ref_lon_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and longitude (rad) of north/east offsets from references: inverse of `horizontal_offset_m`.

    Vector form of `model.offset_to_latlon` (same fixed-point steps on the mid-latitude radii).
    """
    lat = np.asarray(ref_lat_rad, dtype=np.float64)
    for _ in range(4):  # the radii at the mid latitude barely move: a few steps reach 1e-12 m
        b, _a = metric_scales(0.5 * (lat + ref_lat_rad), 0.0)
        lat = ref_lat_rad + north_m / b
    _b, a = metric_scales(0.5 * (lat + ref_lat_rad), 0.0)
    return lat, ref_lon_rad + east_m / a


@dataclass(frozen=True)
class VelocityModel:
    """The piecewise-constant velocity on the DVL grid and its running integrals.

    Per grid interval k (from t_k to t_k+1, the last one open-ended):
    `vel` (north, east, speed, carried) with NaN where unknown, `trust_end_s`
    (the last instant the velocity may be carried), `broken` (the interval
    has an unknown part); `integral` holds ∫ of each channel from t_0 to t_k,
    `broken_before` the count of broken intervals before k.
    """

    t_s: np.ndarray
    vel: np.ndarray            # (n, 4)
    trust_end_s: np.ndarray
    broken: np.ndarray
    integral: np.ndarray       # (n, 4)
    broken_before: np.ndarray
    heading_rad: np.ndarray    # at t_k, NaN where unknown

    def integrate(self, t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
        """∫ of each channel from `t_from` to `t_to` (arrays, t_to >= t_from), shape (..., 4); NaN where unknown."""
        t_from = np.asarray(t_from, dtype=np.float64)
        t_to = np.asarray(t_to, dtype=np.float64)
        out = np.full(t_from.shape + (_CHANNELS,), np.nan)
        n = self.t_s.size
        if n == 0:
            return out
        ka = np.searchsorted(self.t_s, t_from, side="right") - 1
        # the interval that ends at t_to: a position at a grid time needs no velocity after it
        kb = np.maximum(np.searchsorted(self.t_s, t_to, side="left") - 1, ka)
        ok = (ka >= 0) & (kb >= ka) & (t_to >= t_from)
        kac, kbc = np.clip(ka, 0, n - 1), np.clip(kb, 0, n - 1)
        ok &= self.broken_before[kbc] == self.broken_before[kac]
        ok &= np.isfinite(self.vel[kbc, 0]) & (t_to <= self.trust_end_s[kbc])
        ok &= t_from <= self.trust_end_s[kac]
        a, b = kac[ok], kbc[ok]
        p_to = self.integral[b] + self.vel[b] * (t_to[ok] - self.t_s[b])[:, None]
        p_from = self.integral[a] + self.vel[a] * (t_from[ok] - self.t_s[a])[:, None]
        out[ok] = p_to - p_from
        return out



def ned_velocity(x: np.ndarray, y: np.ndarray, frame: np.ndarray, heading_rad: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray]:
    """North and east velocity (m/s) of DVL samples: a body-frame (FRD) sample turned by the heading, an
    earth-frame (NED) one as it is, any other frame NaN."""
    c, s = np.cos(heading_rad), np.sin(heading_rad)
    body = frame == BODY_FRD
    vn = np.where(body, x * c - y * s, np.where(frame == EARTH_NED, x, np.nan))
    ve = np.where(body, x * s + y * c, np.where(frame == EARTH_NED, y, np.nan))
    return vn, ve

def velocity_model(dvl: DvlColumns, ins: InsColumns, hold_s: float, heading_max_gap_s: float) -> VelocityModel:
    """The DVL velocity on its own grid in north/east, with carrying and its limits (see the module text)."""
    t = dvl.t_s
    n = t.size
    usable = dvl.usable
    idx = np.where(usable, np.arange(n), -1)
    last = np.maximum.accumulate(idx) if n else idx   # last usable sample at or before k
    has = last >= 0
    src = np.where(has, last, 0)
    heading = heading_at(t, ins.t_s, ins.heading_deg, heading_max_gap_s)
    x, y, frame = dvl.vx_mps[src], dvl.vy_mps[src], dvl.frame[src]
    vn, ve = ned_velocity(x, y, frame, heading)
    vn[~has], ve[~has] = np.nan, np.nan
    speed = np.hypot(vn, ve)
    carried = np.where(np.isfinite(vn), (~usable).astype(np.float64), np.nan)
    vel = np.stack([vn, ve, speed, carried], axis=-1) if n else np.empty((0, _CHANNELS))
    trust_end = np.where(has, t[src] + hold_s, -np.inf)
    t_next = np.append(t[1:], np.inf)
    broken = ~np.isfinite(vn) | (t_next > trust_end)
    dt = np.diff(t)
    steps = np.where(broken[:-1, None], 0.0, vel[:-1] * dt[:, None]) if n else np.empty((0, _CHANNELS))
    integral = np.concatenate([np.zeros((min(n, 1), _CHANNELS)), np.cumsum(steps, axis=0)])
    broken_before = np.concatenate([np.zeros(min(n, 1), dtype=np.int64), np.cumsum(broken[:-1], dtype=np.int64)])
    return VelocityModel(t, vel, trust_end, broken, integral, broken_before, heading)


@dataclass(frozen=True)
class DeadReckoning:
    """Dead reckoning restarted at every GPS fix.

    The track: at each DVL time, the DR from the last fix at or before it
    (`lat_deg`, `lon_deg`, NaN where unknown). At each fix i > 0, the DR run
    from fix i-1 to fix i before the restart (`fix_lat_deg`, `fix_lon_deg`),
    its error against fix i (`fix_error_m`), its path length (`fix_path_m`)
    and the seconds of it on a carried velocity (`fix_held_s`); NaN at fix 0.
    """

    t_s: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    fix_t_s: np.ndarray
    fix_lat_deg: np.ndarray
    fix_lon_deg: np.ndarray
    fix_error_m: np.ndarray
    fix_path_m: np.ndarray
    fix_held_s: np.ndarray
    hold_s: float


def dead_reckon(fixes: FixColumns, dvl: DvlColumns, ins: InsColumns, hold_s: float = 5.0,
                heading_max_gap_s: float = 5.0) -> DeadReckoning:
    """Dead reckoning from DVL velocity and INS heading, restarted at each GPS fix (module text for the rules)."""
    model = velocity_model(dvl, ins, hold_s, heading_max_gap_s)
    ft, flat, flon = fixes.t_s, np.radians(fixes.lat_deg), np.radians(fixes.lon_deg)
    # the track: anchored at the last fix at or before each DVL time
    anchor = np.searchsorted(ft, model.t_s, side="right") - 1
    lat = np.full(model.t_s.shape, np.nan)
    lon = np.full(model.t_s.shape, np.nan)
    on = anchor >= 0
    if on.any():
        a = anchor[on]
        d = model.integrate(ft[a], model.t_s[on])
        la, lo = offset_to_latlon(d[:, 0], d[:, 1], flat[a], flon[a])
        lat[on], lon[on] = np.degrees(la), np.degrees(lo)
    # at each fix, the run from the previous one before the restart
    m = ft.size
    fix_lat, fix_lon = np.full(m, np.nan), np.full(m, np.nan)
    err, path, held = np.full(m, np.nan), np.full(m, np.nan), np.full(m, np.nan)
    if m > 1:
        d = model.integrate(ft[:-1], ft[1:])
        la, lo = offset_to_latlon(d[:, 0], d[:, 1], flat[:-1], flon[:-1])
        fix_lat[1:], fix_lon[1:] = np.degrees(la), np.degrees(lo)
        err[1:] = horizontal_distance_m(la, lo, flat[1:], flon[1:])
        path[1:], held[1:] = d[:, 2], d[:, 3]
    return DeadReckoning(model.t_s, lat, lon, ft, fix_lat, fix_lon, err, path, held, hold_s)
