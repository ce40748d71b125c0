"""CKF and adaptive CKF (seed A, eqs. A.6-A.20, A.28-A.35; patent step 2) as pure functions.

Two layers:

* general functions for any state and measurement dimension (``ckf_predict``,
  ``ckf_innovation``, ``ckf_update``), batched over leading axes; they are
  the reference the tests compare against a plain Kalman filter;
* the path the runner uses on every DR sample and range epoch
  (``dr_predict``, ``range_innovation``, ``range_update`` on a ``State2`` of
  plain floats), written out for a 2-state, 1-D measurement: a few
  microseconds per call where small-array numpy costs tens.

State order is ``[L, λ]`` (latitude, longitude) in radians; ranges, R, P_zz
and R* are in metres / m²; P_xz in rad·m.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from formats.geodesy import FLATTENING, RE_M, metric_scales_scalar
from replay.stack.filters.cubature import cubature_transform, symmetrize
from replay.stack.model import radian_scaling

MIN_PREDICTED_RANGE_M: float = 1.0
"""Below this predicted horizontal range the leader is 'on top of' the follower: the range
carries no direction and the cubature rule is meaningless, so the epoch is rejected."""
_SQRT2 = math.sqrt(2.0)
_RM0 = RE_M * (1.0 - 2.0 * FLATTENING)      # R_M = _RM0 + _RM2 sin²L,  R_N = R_e + _RN2 sin²L (A.2)
_RM2 = RE_M * 3.0 * FLATTENING
_RN2 = RE_M * FLATTENING
_FLOOR_REL = 1e-12


# ---------------------------------------------------------------- general CKF


@dataclass(frozen=True, slots=True)
class Innovation:
    """Measurement prediction of A.14-A.17: ẑ (m,), r = z - ẑ (m,), unadapted P_zz (m, m), P_xz (n, m)."""

    z_hat: np.ndarray
    residual: np.ndarray
    pzz: np.ndarray
    pxz: np.ndarray


def ckf_predict(
    x: np.ndarray, p: np.ndarray, f: Callable[[np.ndarray], np.ndarray], q: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Time update (A.7-A.11): propagate cubature points through f, centred covariance + Q."""
    mean, cov, _, _ = cubature_transform(x, p, f)
    return mean, symmetrize(cov + q)


def ckf_innovation(
    x: np.ndarray, p: np.ndarray, z: np.ndarray, h: Callable[[np.ndarray], np.ndarray], r: np.ndarray,
) -> Innovation:
    """Measurement prediction (A.12-A.17) with the innovation r = z - ẑ (A.28)."""
    z_hat, pzz, pxz, _ = cubature_transform(x, p, h)
    return Innovation(z_hat, np.asarray(z, dtype=float) - z_hat, symmetrize(pzz + r), pxz)


def adaptive_factor(residual: np.ndarray, pzz: np.ndarray) -> float:
    """η of A.30: 1 when tr(r rᵀ) <= tr(P_zz), else tr(P_zz) / tr(r rᵀ)."""
    rr = float(np.dot(residual, residual))
    tr = float(np.trace(pzz))
    return 1.0 if rr <= tr else tr / rr


def ckf_update(
    x: np.ndarray, p: np.ndarray, inn: Innovation, r: np.ndarray, eta: float = 1.0, gain: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Measurement update (A.18-A.20) with R* = R/η, P_zz* = P_zz - R + R* (A.31) and isolation (A.33-A.35).

    ``gain=False`` is γ = 1 of A.33: the epoch is a time update only. η = 1
    gives the plain CKF.
    """
    if not gain:
        return x, p
    pzz_star = inn.pzz - r + r / eta
    k = np.linalg.solve(pzz_star, inn.pxz.T).T
    return x + k @ inn.residual, symmetrize(p - k @ pzz_star @ k.T)


def features_of(inn: Innovation, r: np.ndarray, eta: float) -> tuple[float, float, float]:
    """Detector features (f1, f2, f3) = (|r|, rᵀ P_zz⁻¹ r on the unadapted P_zz (A.29), tr R*)."""
    res = inn.residual
    f2 = float(res @ np.linalg.solve(inn.pzz, res))
    return float(np.linalg.norm(res)), f2, float(np.trace(r)) / eta


# ------------------------------------------------------- range-only fast path


class State2(NamedTuple):
    """A follower's Gaussian as plain floats: mean [L, λ] (rad) and P = [[p11, p12], [p12, p22]] (rad²)."""

    lat: float
    lon: float
    p11: float
    p12: float
    p22: float

    @classmethod
    def from_arrays(cls, x: np.ndarray, p: np.ndarray) -> State2:
        """Build from a mean (2,) and a covariance (2, 2); the covariance is symmetrized."""
        return cls(float(x[0]), float(x[1]), float(p[0, 0]), 0.5 * float(p[0, 1] + p[1, 0]), float(p[1, 1]))

    @property
    def x(self) -> np.ndarray:
        """Mean [L, λ] as an array (2,)."""
        return np.array([self.lat, self.lon])

    @property
    def p(self) -> np.ndarray:
        """Covariance as an array (2, 2)."""
        return np.array([[self.p11, self.p12], [self.p12, self.p22]])


# State2(...) without the NamedTuple's Python-level __new__: dr_predict runs per method at every DR sample
_new_state2 = tuple.__new__


@dataclass(frozen=True, slots=True)
class RangeInnovation:
    """One range epoch's prediction: ẑ, r, unadapted P_zz (m²), P_xz (rad·m), η and R* (m²)."""

    z_hat: float
    residual: float
    pzz: float
    pxz_lat: float
    pxz_lon: float
    eta: float
    r_adapted: float

    @property
    def features(self) -> tuple[float, float, float]:
        """(f1, f2, f3) = (|r|, r² / P_zz unadapted (A.29), R* (A.31)) (docs/design.md section 8)."""
        return abs(self.residual), self.residual * self.residual / self.pzz, self.r_adapted


def _chol2(p11: float, p12: float, p22: float) -> tuple[float, float, float]:
    """Lower Cholesky factor (l11, l21, l22) of a 2x2 covariance, clamped so it never fails (A.7, A.12)."""
    floor = _FLOOR_REL * abs(p11 + p22) + 1e-300
    l11 = math.sqrt(p11 if p11 > floor else floor)
    l21 = p12 / l11
    d = p22 - l21 * l21
    return l11, l21, math.sqrt(d if d > floor else floor)


def _finite(*values: float) -> bool:
    """True when every value is a finite number (a NaN or inf anywhere makes the sum non-finite)."""
    return math.isfinite(sum(values))


def _range(lat: float, lon: float, depth: float, llat: float, llon: float, ldepth: float) -> float:
    """Scalar horizontal range with common mid-point radii (model.horizontal_range, A.4 amended)."""
    b, a = metric_scales_scalar(0.5 * (lat + llat), 0.5 * (depth + ldepth))
    dn = b * (lat - llat)
    de = a * (lon - llon)
    return math.sqrt(dn * dn + de * de)


def dr_predict(
    s: State2, dt_s: float, forward_mps: float, lateral_mps: float, heading_rad: float,
    depth_m: float, q_m_per_s: tuple[float, float],
) -> State2:
    """CKF time update (A.7-A.11) through the DR model A.1 for one filter, in scalar math.

    Equal to ``ckf_predict`` with ``model.dead_reckon_step`` and
    ``process_noise`` (the tests check it): the four points are x ± sqrt(2) S e_1
    and x ± sqrt(2) S e_2, so the DR increment, which depends on latitude
    only, is evaluated at three latitudes; covariances are centred sums of
    the points' offsets from x, which keeps every digit.
    """
    north, east = dr_displacement(dt_s, forward_mps, lateral_mps, heading_rad)
    return dr_predict_moved((s,), dt_s, north, east, depth_m, q_m_per_s)[0]


def dr_displacement(dt_s: float, forward_mps: float, lateral_mps: float, heading_rad: float) -> tuple[float, float]:
    """The DR displacement north, east (m) of one step (A.1), shared by every filter the step moves."""
    c, sn = math.cos(heading_rad), math.sin(heading_rad)
    return dt_s * (forward_mps * c - lateral_mps * sn), dt_s * (forward_mps * sn + lateral_mps * c)


def dr_predict_moved(
    states: tuple[State2, ...] | list[State2], dt_s: float, north: float, east: float, depth_m: float,
    q_m_per_s: tuple[float, float],
) -> list[State2]:
    """`dr_predict` of several filters moved by one DR displacement (`dr_displacement`), in one loop.

    The same operations in the same order as a call per filter: the results are equal bit for bit.
    """
    q11, q22 = q_m_per_s[0] ** 2 * dt_s, q_m_per_s[1] ** 2 * dt_s
    out = []
    for s in states:
        p11 = s.p11
        # the lower Cholesky factor, clamped (_chol2, inlined: this loop runs per filter at every DR sample)
        floor = _FLOOR_REL * abs(p11 + s.p22) + 1e-300
        l11 = math.sqrt(p11 if p11 > floor else floor)
        l21 = s.p12 / l11
        d = s.p22 - l21 * l21
        l22 = math.sqrt(d if d > floor else floor)
        a1, a21, a22 = _SQRT2 * l11, _SQRT2 * l21, _SQRT2 * l22
        # radii (A.2) at L and L ± a1, with sin/cos of L ± a1 by angle addition (hot path: 3 trig calls saved)
        lat = s.lat
        s0, c0 = math.sin(lat), math.cos(lat)
        sd, cd = math.sin(a1), math.cos(a1)
        sp, cp = s0 * cd + c0 * sd, c0 * cd - s0 * sd
        sm, cm = s0 * cd - c0 * sd, c0 * cd + s0 * sd
        s0, sp, sm = s0 * s0, sp * sp, sm * sm
        b0, bp, bm = _RM0 + _RM2 * s0 + depth_m, _RM0 + _RM2 * sp + depth_m, _RM0 + _RM2 * sm + depth_m
        a0 = (RE_M + _RN2 * s0 + depth_m) * c0
        ap = (RE_M + _RN2 * sp + depth_m) * cp
        am = (RE_M + _RN2 * sm + depth_m) * cm
        # offsets of the moved points (+e1, +e2, -e1, -e2) from the prior mean
        o1, o2, o3, o4 = a1 + north / bp, north / b0, north / bm - a1, north / b0
        w1, w2, w3, w4 = a21 + east / ap, a22 + east / a0, east / am - a21, east / a0 - a22
        m_lat = 0.25 * (o1 + o2 + o3 + o4)
        m_lon = 0.25 * (w1 + w2 + w3 + w4)
        o1, o2, o3, o4 = o1 - m_lat, o2 - m_lat, o3 - m_lat, o4 - m_lat
        w1, w2, w3, w4 = w1 - m_lon, w2 - m_lon, w3 - m_lon, w4 - m_lon
        out.append(_new_state2(State2, (
            lat + m_lat, s.lon + m_lon,
            0.25 * (o1 * o1 + o2 * o2 + o3 * o3 + o4 * o4) + q11 / (b0 * b0),
            0.25 * (o1 * w1 + o2 * w2 + o3 * w3 + o4 * w4),
            0.25 * (w1 * w1 + w2 * w2 + w3 * w3 + w4 * w4) + q22 / (a0 * a0))))
    return out


def range_innovation(
    s: State2, z: float, leader: tuple[float, float, float], depth_m: float, r_var: float,
) -> RangeInnovation | None:
    """Cubature range prediction (A.12-A.17), innovation (A.28) and adaptive factor (A.30-A.31).

    ``leader`` = (lat rad, lon rad, depth m). Returns None when an input is
    not finite, P is not positive, or the range at the mean h(x̂) is below
    MIN_PREDICTED_RANGE_M (the leader on top of the follower).
    """
    llat, llon, ldep = leader
    if not (_finite(z, llat, llon, ldep, depth_m, *s) and s.p11 > 0.0 and s.p22 > 0.0):
        return None
    lat, lon = s.lat, s.lon
    if _range(lat, lon, depth_m, llat, llon, ldep) < MIN_PREDICTED_RANGE_M:
        return None
    l11, l21, l22 = _chol2(s.p11, s.p12, s.p22)
    d1l, d1o, d2o = _SQRT2 * l11, _SQRT2 * l21, _SQRT2 * l22         # points of A.13
    z1 = _range(lat + d1l, lon + d1o, depth_m, llat, llon, ldep)
    z2 = _range(lat, lon + d2o, depth_m, llat, llon, ldep)
    z3 = _range(lat - d1l, lon - d1o, depth_m, llat, llon, ldep)
    z4 = _range(lat, lon - d2o, depth_m, llat, llon, ldep)
    z_hat = 0.25 * (z1 + z2 + z3 + z4)
    if not math.isfinite(z_hat):
        return None
    e1, e2, e3, e4 = z1 - z_hat, z2 - z_hat, z3 - z_hat, z4 - z_hat
    pzz = 0.25 * (e1 * e1 + e2 * e2 + e3 * e3 + e4 * e4) + r_var      # centred sum (A.16)
    pxz_lat = 0.25 * d1l * (e1 - e3)                                     # centred sum (A.17)
    pxz_lon = 0.25 * (d1o * (e1 - e3) + d2o * (e2 - e4))
    res = z - z_hat
    rr = res * res
    eta = 1.0 if rr <= pzz else pzz / rr
    if not (math.isfinite(rr) and eta > 0.0):     # absurd ranges: R* would overflow
        return None
    return RangeInnovation(z_hat, res, pzz, pxz_lat, pxz_lon, eta, r_var / eta)


def range_update(s: State2, inn: RangeInnovation, r_var: float, adaptive: bool, gain: bool = True) -> State2:
    """Gain, state and covariance update (A.18-A.20); ACKF uses P_zz* = P_zz - R + R* (A.31).

    ``gain=False`` isolates the epoch (γ = 1, A.33-A.35). A result that is not
    finite or not positive leaves the prior unchanged (never NaN).
    """
    if not gain:
        return s
    pzz = inn.pzz - r_var + inn.r_adapted if adaptive else inn.pzz
    k0, k1 = inn.pxz_lat / pzz, inn.pxz_lon / pzz
    # P - K P_zz Kᵀ with K = P_xz / P_zz equals P - P_xz P_xzᵀ / P_zz
    out = State2(s.lat + k0 * inn.residual, s.lon + k1 * inn.residual,
                 s.p11 - k0 * inn.pxz_lat, s.p12 - k0 * inn.pxz_lon, s.p22 - k1 * inn.pxz_lon)
    if not (_finite(*out) and out.p11 > 0.0 and out.p22 > 0.0):
        return s
    return out


def position_update(s: State2, lat: float, lon: float, r11: float, r12: float, r22: float) -> State2 | None:
    """Kalman update with a direct position fix z = [L, λ] (H = I), R = [[r11, r12], [r12, r22]] in rad².

    The measurement is linear in the state, so the cubature rule gives the
    plain Kalman update exactly: S = P + R, K = P S⁻¹, x += K (z - x),
    P -= K P. None when an input is not finite or S is not positive definite.
    """
    if not _finite(lat, lon, r11, r12, r22, *s):
        return None
    s11, s12, s22 = s.p11 + r11, s.p12 + r12, s.p22 + r22
    det = s11 * s22 - s12 * s12
    if not (s11 > 0.0 and s22 > 0.0 and det > 0.0):
        return None
    i11, i12, i22 = s22 / det, -s12 / det, s11 / det              # S⁻¹
    k11, k12 = s.p11 * i11 + s.p12 * i12, s.p11 * i12 + s.p12 * i22  # K = P S⁻¹
    k21, k22 = s.p12 * i11 + s.p22 * i12, s.p12 * i12 + s.p22 * i22
    d0, d1 = lat - s.lat, lon - s.lon
    out = State2(s.lat + k11 * d0 + k12 * d1, s.lon + k21 * d0 + k22 * d1,
                 s.p11 - (k11 * s.p11 + k12 * s.p12), s.p12 - (k11 * s.p12 + k12 * s.p22),
                 s.p22 - (k21 * s.p12 + k22 * s.p22))
    if not (_finite(*out) and out.p11 > 0.0 and out.p22 > 0.0):
        return None
    return out


def isolation_action(flagged: bool, streak: int, cap: int) -> tuple[str, int]:
    """Isolation with a cap (A.33-A.35, docs/design.md section 8): ('update'|'isolate'|'capped', new streak).

    A flagged epoch is isolated unless this leader's previous ``cap``
    consecutive epochs were all isolated; past the cap every flagged epoch is
    used with the ACKF's inflated R* ('capped') until an unflagged epoch
    resets the streak, so a filter biased by a missed slow drift re-acquires.
    """
    if not flagged:
        return "update", 0
    if streak < cap:
        return "isolate", streak + 1
    return "capped", streak + 1


# ----------------------------------------------------- batched time update


def process_noise(x: np.ndarray, dt_s: float, q_m_per_s: tuple[float, float], depth_m: float) -> np.ndarray:
    """Q for one dead-reckoning step in rad² at states (..., 2): diag(q²) m² per second × Δt."""
    d = radian_scaling(x[..., 0], depth_m)                          # (..., 2)
    q = np.zeros(np.shape(x)[:-1] + (2, 2))
    q[..., 0, 0] = q_m_per_s[0] ** 2 * dt_s * d[..., 0] ** 2
    q[..., 1, 1] = q_m_per_s[1] ** 2 * dt_s * d[..., 1] ** 2
    return q


class RangeCkf:
    """A single follower filter (CKF or ACKF) wiring the pure functions; state [L, λ] in radians."""

    def __init__(self, state: State2, r_var: float, q_m_per_s: tuple[float, float], adaptive: bool) -> None:
        """Start from a state (rad, rad²) with ranging variance r_var (m²) and DR noise q (m per √s)."""
        self.state = state
        self.r_var = r_var
        self.q_m_per_s = q_m_per_s
        self.adaptive = adaptive

    def predict(self, dt_s: float, forward_mps: float, lateral_mps: float, heading_rad: float,
                depth_m: float) -> None:
        """Dead-reckoning time update over dt_s seconds."""
        self.state = dr_predict(self.state, dt_s, forward_mps, lateral_mps, heading_rad, depth_m,
                                self.q_m_per_s)

    def update(self, z: float, leader: tuple[float, float, float], depth_m: float,
               gain: bool = True) -> RangeInnovation | None:
        """Range update; returns the innovation (features) or None if the epoch was rejected."""
        inn = range_innovation(self.state, z, leader, depth_m, self.r_var)
        if inn is not None:
            self.state = range_update(self.state, inn, self.r_var, self.adaptive, gain)
        return inn
