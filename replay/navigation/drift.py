"""How far dead reckoning and the INS had drifted when GPS came back: errors at every fix and per dive.

The INS "just before the fix is applied" is its last solution strictly
before the fix time, at most `ins_max_age_s` old, carried to the fix time
with its own north/east velocity (or, where it gives none, the velocity of
its two last solutions): an aided INS may already hold the fix in a
solution stamped at the fix time, which would hide the drift.

A dive is a GPS gap longer than `dive_gap_s`: it begins at the last fix
before the gap and ends at the first fix after it. Its distance travelled
is the DR path length (DVL speed over ground), or the INS path length where
the DR is unknown; the drift in % is each error over that one distance, so
DR and INS are divided by the same figure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replay.stack.model import horizontal_distance_m, horizontal_offset_m

from .columns import FixColumns, InsColumns
from .dead_reckoning import DeadReckoning, offset_to_latlon

__all__ = ["Dives", "FixErrors", "dives", "fix_errors", "fix_table", "ins_before", "ins_error_at"]


def ins_before(ins: InsColumns, t_s: np.ndarray, max_age_s: float) -> tuple[np.ndarray, np.ndarray]:
    """INS latitude and longitude (deg) just before times `t_s` (module text); NaN where none is recent enough."""
    keep = np.isfinite(ins.lat_deg) & np.isfinite(ins.lon_deg)
    it = ins.t_s[keep]
    lat, lon = np.radians(ins.lat_deg[keep]), np.radians(ins.lon_deg[keep])
    vn, ve = ins.vn_mps[keep], ins.ve_mps[keep]
    out_lat, out_lon = np.full(t_s.shape, np.nan), np.full(t_s.shape, np.nan)
    k = np.searchsorted(it, t_s, side="left") - 1
    ok = (k >= 0) & (t_s - it[np.maximum(k, 0)] <= max_age_s) if it.size else np.zeros(t_s.shape, dtype=bool)
    if not ok.any():
        return out_lat, out_lon
    k = k[ok]
    dt = t_s[ok] - it[k]
    v_n, v_e = vn[k], ve[k]
    # no velocity of its own: the velocity between its two last solutions
    j = np.maximum(k - 1, 0)
    span = it[k] - it[j]
    dn, de = horizontal_offset_m(lat[k], lon[k], lat[j], lon[j])
    with np.errstate(invalid="ignore", divide="ignore"):
        fd_n, fd_e = np.where(span > 0, dn / span, np.nan), np.where(span > 0, de / span, np.nan)
    own = np.isfinite(v_n) & np.isfinite(v_e)
    v_n, v_e = np.where(own, v_n, fd_n), np.where(own, v_e, fd_e)
    la, lo = offset_to_latlon(v_n * dt, v_e * dt, lat[k], lon[k])
    out_lat[ok], out_lon[ok] = np.degrees(la), np.degrees(lo)
    return out_lat, out_lon


def _path_at(t_s: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray, at_s: np.ndarray) -> np.ndarray:
    """Path length (m) along a position track from its start to times `at_s`, linear between samples."""
    keep = np.isfinite(lat_deg) & np.isfinite(lon_deg)
    t, la, lo = t_s[keep], np.radians(lat_deg[keep]), np.radians(lon_deg[keep])
    if t.size < 2:
        return np.full(at_s.shape, np.nan)
    cum = np.concatenate([[0.0], np.cumsum(horizontal_distance_m(la[1:], lo[1:], la[:-1], lo[:-1]))])
    out = np.interp(at_s, t, cum)
    out[(at_s < t[0]) | (at_s > t[-1])] = np.nan
    return out


@dataclass(frozen=True)
class FixErrors:
    """Errors at every GPS fix (NaN at the first fix and where unknown).

    `since_prev_s` is the time since the previous fix (the span the DR ran
    open-loop); `dr_*` come from `DeadReckoning`; `ins_error_m` is the INS
    just before the fix against it; `ins_path_m` the INS path length since
    the previous fix; `dive_end` marks fixes that end a dive.
    """

    t_s: np.ndarray
    since_prev_s: np.ndarray
    dr_error_m: np.ndarray
    dr_path_m: np.ndarray
    dr_held_s: np.ndarray
    ins_error_m: np.ndarray
    ins_path_m: np.ndarray
    dive_end: np.ndarray


def fix_errors(fixes: FixColumns, dr: DeadReckoning, ins: InsColumns, dive_gap_s: float = 30.0,
               ins_max_age_s: float = 5.0) -> FixErrors:
    """DR and INS errors against every GPS fix, with the dive-ending fixes marked."""
    t = fixes.t_s
    path = _path_at(ins.t_s, ins.lat_deg, ins.lon_deg, t)
    return fix_table(t, dr.fix_error_m, dr.fix_path_m, dr.fix_held_s, ins_error_at(fixes, ins, ins_max_age_s),
                     path, dive_gap_s)


def ins_error_at(fixes: FixColumns, ins: InsColumns, ins_max_age_s: float) -> np.ndarray:
    """Distance (m) from the INS just before each fix (`ins_before`) to the fix; NaN where there is none."""
    ilat, ilon = ins_before(ins, fixes.t_s, ins_max_age_s)
    return horizontal_distance_m(np.radians(ilat), np.radians(ilon), np.radians(fixes.lat_deg),
                                 np.radians(fixes.lon_deg))


def fix_table(t: np.ndarray, dr_error_m: np.ndarray, dr_path_m: np.ndarray, dr_held_s: np.ndarray,
              ins_error_m: np.ndarray, ins_path_at_m: np.ndarray, dive_gap_s: float) -> FixErrors:
    """The fix-error table from per-fix figures (`ins_path_at_m`: the INS path length from its start to each fix)."""
    since = np.full(t.shape, np.nan)
    since[1:] = np.diff(t)
    ins_path = np.full(t.shape, np.nan)
    ins_path[1:] = np.diff(ins_path_at_m)
    dive_end = np.zeros(t.shape, dtype=bool)
    dive_end[1:] = since[1:] > dive_gap_s
    return FixErrors(t, since, dr_error_m, dr_path_m, dr_held_s, ins_error_m, ins_path, dive_end)


@dataclass(frozen=True)
class Dives:
    """One row per dive: start and end (mission s), duration, errors at its end, distance and drift in %.

    `distance_m` is the DR path length, or the INS one where the DR is
    unknown (`distance_from_dr` says which); `*_pct` = error / distance × 100.
    """

    start_s: np.ndarray
    end_s: np.ndarray
    duration_s: np.ndarray
    dr_error_m: np.ndarray
    ins_error_m: np.ndarray
    dr_held_s: np.ndarray
    distance_m: np.ndarray
    distance_from_dr: np.ndarray
    dr_pct: np.ndarray
    ins_pct: np.ndarray

    def __len__(self) -> int:
        return int(self.end_s.size)


def dives(errors: FixErrors) -> Dives:
    """The dives of a fix-error table: the rows that end a GPS gap longer than the dive threshold."""
    i = np.flatnonzero(errors.dive_end)
    dr_ok = np.isfinite(errors.dr_path_m[i])
    dist = np.where(dr_ok, errors.dr_path_m[i], errors.ins_path_m[i])
    with np.errstate(invalid="ignore", divide="ignore"):
        dr_pct = np.where(dist > 0, 100.0 * errors.dr_error_m[i] / dist, np.nan)
        ins_pct = np.where(dist > 0, 100.0 * errors.ins_error_m[i] / dist, np.nan)
    end = errors.t_s[i]
    return Dives(end - errors.since_prev_s[i], end, errors.since_prev_s[i], errors.dr_error_m[i],
                 errors.ins_error_m[i], errors.dr_held_s[i], dist, dr_ok, dr_pct, ins_pct)
