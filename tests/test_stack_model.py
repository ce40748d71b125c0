"""Cooperative-localization model: radii, dead reckoning, ranges, slant conversion, covariance units."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.geodesy import FLATTENING, RE_M, earth_radii, metric_scales, metric_scales_scalar
from replay.stack import model

LAT = math.radians(45.7)
LON = math.radians(126.6)


def offset(lat: float, lon: float, north_m: float, east_m: float) -> tuple[float, float]:
    """A point north_m / east_m away, scaled with radii at the mid latitude."""
    return model.offset_to_latlon(north_m, east_m, lat, lon)


def test_radii_at_equator_and_pole() -> None:
    r_m, r_n = earth_radii(np.array([0.0, math.pi / 2]))
    assert r_m[0] == RE_M * (1 - 2 * FLATTENING)
    assert r_n[0] == RE_M
    assert math.isclose(r_m[1], RE_M * (1 + FLATTENING), rel_tol=1e-15)
    assert math.isclose(r_n[1], RE_M * (1 + FLATTENING), rel_tol=1e-15)
    assert metric_scales_scalar(0.3, 12.0) == tuple(float(v) for v in metric_scales(0.3, 12.0))


def test_dead_reckoning_north_east_and_lateral() -> None:
    x = np.array([LAT, LON])
    b, a = metric_scales(LAT, 10.0)
    north = model.dead_reckon_step(x, 10.0, 1.0, 0.0, 0.0, 10.0)      # 10 m north
    assert math.isclose(north[0] - LAT, 10.0 / b, rel_tol=1e-9) and north[1] == LON
    east = model.dead_reckon_step(x, 5.0, 2.0, 0.0, math.pi / 2, 10.0)   # 10 m east
    assert abs(east[0] - LAT) < 1e-20 + 1e-15 and math.isclose(east[1] - LON, 10.0 / a, rel_tol=1e-9)
    side = model.dead_reckon_step(x, 10.0, 0.0, 1.0, 0.0, 10.0)         # starboard at heading 0 = east
    assert math.isclose(side[1] - LON, 10.0 / a, rel_tol=1e-9)


def test_dead_reckoning_broadcasts_over_points() -> None:
    pts = np.array([[LAT, LON], [LAT + 1e-5, LON - 1e-5], [LAT - 2e-5, LON]])
    many = model.dead_reckon_step(pts, 1.0, 1.5, 0.2, 0.7, 3.0)
    one = np.array([model.dead_reckon_step(p, 1.0, 1.5, 0.2, 0.7, 3.0) for p in pts])
    np.testing.assert_array_equal(many, one)


def test_horizontal_range_metres_and_symmetry() -> None:
    llat, llon = offset(LAT, LON, 300.0, 400.0)
    z = float(model.horizontal_range(np.array([LAT, LON]), 0.0, llat, llon, 0.0))
    assert abs(z - 500.0) < 1e-6
    back = float(model.horizontal_range(np.array([llat, llon]), 0.0, LAT, LON, 0.0))
    assert abs(back - z) < 1e-9


def test_literal_a4_is_off_by_hundreds_of_metres() -> None:
    """Why model.horizontal_range deviates from A.4 as printed (each vehicle's radii times its own angles)."""
    llat, llon = offset(LAT, LON, 300.0, 400.0)
    b, a = metric_scales(LAT, 5.0)
    bm, am = metric_scales(llat, 0.0)
    literal = math.hypot(b * LAT - bm * llat, a * LON - am * llon)
    ours = float(model.horizontal_range(np.array([LAT, LON]), 5.0, llat, llon, 0.0))
    assert abs(literal - 500.0) > 100.0
    assert abs(ours - 500.0) < 0.01


@settings(max_examples=200, deadline=None)
@given(st.floats(-5000, 5000), st.floats(-5000, 5000), st.floats(-1.4, 1.4))
def test_range_matches_metric_offsets(north: float, east: float, lat: float) -> None:
    llat, llon = offset(lat, 2.0, north, east)
    z = float(model.horizontal_range(np.array([lat, 2.0]), 0.0, llat, llon, 0.0))
    assert abs(z - math.hypot(north, east)) <= 1e-6 + 1e-9 * math.hypot(north, east)


def test_slant_to_horizontal() -> None:
    assert model.slant_to_horizontal(5.0, 4.0, 1.0) == (4.0, False)
    assert model.slant_to_horizontal(2.0, 10.0, 0.0) == (0.0, True)       # |Δh| > r: clamp, count
    assert model.slant_to_horizontal(3.0, 3.0, 0.0) == (0.0, True)
    assert model.slant_to_horizontal(float("nan"), 0.0, 0.0) == (0.0, True)


@settings(deadline=None)
@given(st.floats(allow_nan=True, allow_infinity=True), st.floats(-1e4, 1e4), st.floats(-1e4, 1e4))
def test_slant_to_horizontal_never_nan(r: float, h: float, hm: float) -> None:
    z, clamped = model.slant_to_horizontal(r, h, hm)
    assert not math.isnan(z) and z >= 0.0
    assert math.isfinite(z) or math.isinf(r)
    assert clamped == (not (r > abs(h - hm)))
    if not clamped and r < 1e100:
        assert abs(z - math.sqrt(max(r * r - (h - hm) ** 2, 0.0))) <= 1e-9 * r + 1e-6


def test_covariance_unit_round_trip() -> None:
    cov_m = np.array([[4.0, 1.5], [1.5, 9.0]])
    rad = model.cov_metres_to_radians(cov_m, LAT, 20.0)
    b, a = metric_scales(LAT, 20.0)
    assert math.isclose(rad[0, 0], 4.0 / b ** 2, rel_tol=1e-14)
    assert math.isclose(rad[0, 1], 1.5 / (a * b), rel_tol=1e-14)
    np.testing.assert_allclose(model.cov_radians_to_metres(rad, LAT, 20.0), cov_m, rtol=1e-14)
    batch = model.cov_metres_to_radians(np.stack([cov_m, 2 * cov_m]), np.array([LAT, 0.1]))
    assert batch.shape == (2, 2, 2)
    np.testing.assert_allclose(batch[1], model.cov_metres_to_radians(2 * cov_m, 0.1), rtol=1e-14)


def test_horizontal_distance_and_offset() -> None:
    llat, llon = offset(LAT, LON, -120.0, 50.0)
    dn, de = model.horizontal_offset_m(np.array(llat), np.array(llon), np.array(LAT), np.array(LON))
    assert abs(dn + 120.0) < 1e-6 and abs(de - 50.0) < 1e-6
    assert abs(model.horizontal_distance_m(llat, llon, LAT, LON) - 130.0) < 1e-6


@settings(max_examples=100, deadline=None)
@given(st.floats(-5000.0, 5000.0), st.floats(-5000.0, 5000.0), st.floats(-1.4, 1.4))
def test_offset_to_latlon_inverts_horizontal_offset(north: float, east: float, lat: float) -> None:
    plat, plon = model.offset_to_latlon(north, east, lat, 2.0)
    dn, de = model.horizontal_offset_m(np.array(plat), np.array(plon), np.array(lat), np.array(2.0))
    assert abs(dn - north) < 1e-6 and abs(de - east) < 1e-6
