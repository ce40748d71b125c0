"""The position covariance of a GNSS fix (ENU, m²): GST sigmas, else HDOP times the UERE, else unknown.

One rule for every NMEA path (per line, columnar, and the reference in
tests/): GST of the same epoch gives diag(lon σ², lat σ², alt σ²),
DIAGONAL_KNOWN; else GGA's HDOP with a fix gives a horizontal σ = HDOP × UERE
split equally on east and north (σ_E² = σ_N² = (HDOP·UERE)²/2) and a
vertical σ = 2·HDOP·UERE (VDOP is not in GGA; about twice HDOP is typical),
APPROXIMATED; else None and UNKNOWN. UERE depends on the fix quality
(`UERE_M`) unless the log's manifest entry sets ``uere_m``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from formats import schemas as S

# User-equivalent range error (m, 1 sigma) by GGA fix quality, for HDOP-based covariance
UERE_M: dict[int, float] = {1: 4.0, 2: 1.0, 3: 4.0, 4: 0.05, 5: 0.5, 6: 10.0, 7: 4.0, 8: 4.0, 9: 2.0}
DEFAULT_UERE_M = 4.0

Covariance = tuple[tuple[float, ...] | None, int]  # (row-major 3x3 ENU matrix or None, covariance type)
UNKNOWN: Covariance = (None, S.COVARIANCE_UNKNOWN)


def uere_m(quality: int, options: Mapping[str, Any]) -> float:
    """The UERE (m) for a fix quality: the manifest's ``uere_m``, else `UERE_M`'s, else the default."""
    value = options.get("uere_m", UERE_M.get(quality, DEFAULT_UERE_M))
    return float(value)


def sigma_covariance(lat_std_m: float, lon_std_m: float, alt_std_m: float) -> Covariance:
    """diag(σ_E², σ_N², σ_U²), DIAGONAL_KNOWN, from 1-sigma errors (GST, NovAtel BESTPOS)."""
    e, n, u = lon_std_m, lat_std_m, alt_std_m
    return (e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, u * u), S.COVARIANCE_DIAGONAL_KNOWN


def hdop_covariance(hdop: float, uere: float) -> Covariance:
    """diag(h²/2, h²/2, 4h²) with h = HDOP × UERE, APPROXIMATED."""
    h = hdop * uere
    return (h * h / 2, 0.0, 0.0, 0.0, h * h / 2, 0.0, 0.0, 0.0, 4 * h * h), S.COVARIANCE_APPROXIMATED


def fix_covariance(lat_std_m: float, lon_std_m: float, alt_std_m: float, hdop: float, quality: int,
                   options: Mapping[str, Any]) -> Covariance:
    """An epoch's covariance: its GST sigmas (NaN when it has none), else its GGA HDOP, else UNKNOWN."""
    if not (math.isnan(lat_std_m) or math.isnan(lon_std_m)):
        return sigma_covariance(lat_std_m, lon_std_m, alt_std_m)
    if not math.isnan(hdop) and quality > 0:
        return hdop_covariance(hdop, uere_m(quality, options))
    return UNKNOWN


def fix_covariance_columns(lat_std_m: np.ndarray, lon_std_m: np.ndarray, alt_std_m: np.ndarray, hdop: np.ndarray,
                           quality: np.ndarray, options: Mapping[str, Any]
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`fix_covariance` of each row: the (n, 9) matrices (NaN rows where UNKNOWN), their types, and whether each
    has one (not UNKNOWN); the same arithmetic in the same order, so the same doubles."""
    n = len(hdop)
    sigma = ~(np.isnan(lat_std_m) | np.isnan(lon_std_m))
    approximated = ~sigma & ~np.isnan(hdop) & (quality > 0)
    out = np.full((n, 9), np.nan)
    kinds = np.full(n, S.COVARIANCE_UNKNOWN, dtype=np.int64)
    with np.errstate(over="ignore", invalid="ignore"):  # a float product overflows to inf, as Python's
        e, north, u = lon_std_m[sigma], lat_std_m[sigma], alt_std_m[sigma]
        out[sigma] = 0.0
        out[sigma, 0], out[sigma, 4], out[sigma, 8] = e * e, north * north, u * u
        kinds[sigma] = S.COVARIANCE_DIAGONAL_KNOWN
        if approximated.any():
            q = quality[approximated]
            ueres = {k: uere_m(k, options) for k in np.unique(q).tolist()}
            h = hdop[approximated] * np.array([ueres[k] for k in q.tolist()], dtype=np.float64)
            out[approximated] = 0.0
            out[approximated, 0] = out[approximated, 4] = h * h / 2
            out[approximated, 8] = 4 * h * h
            kinds[approximated] = S.COVARIANCE_APPROXIMATED
    return out, kinds, sigma | approximated
