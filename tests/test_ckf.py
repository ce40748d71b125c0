"""Cubature rule, CKF against a plain Kalman filter, ACKF, fast range path, NEES/NIS consistency."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from formats.geodesy import metric_scales_scalar
from replay.stack import model
from replay.stack.filters import ckf, cubature
from replay.stack.filters.ckf import State2

LAT = math.radians(45.7)
LON = math.radians(126.6)
B0, A0 = metric_scales_scalar(LAT, 0.0)


def to_rad(north: float, east: float) -> tuple[float, float]:
    """Local metres around (LAT, LON) to radians with fixed radii."""
    return LAT + north / B0, LON + east / A0


def random_gaussian(seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A seeded mean and well-conditioned covariance."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    return rng.normal(size=n), a @ a.T + 0.1 * np.eye(n)


# ------------------------------------------------------------------ cubature


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 4))
def test_cubature_exact_up_to_degree_three(seed: int, n: int) -> None:
    mu, p = random_gaussian(seed, n)
    pts = cubature.cubature_points(mu, cubature.robust_cholesky(p))
    assert pts.shape == (2 * n, n)
    e = lambda values: values.mean(axis=0)                       # noqa: E731 - equal weights 1/2n
    np.testing.assert_allclose(e(pts), mu, atol=1e-12)
    second = np.einsum("ki,kj->kij", pts, pts)
    np.testing.assert_allclose(e(second), p + np.outer(mu, mu), atol=1e-10)
    third = np.einsum("ki,kj,kl->kijl", pts, pts, pts)
    exact = (np.einsum("i,j,l->ijl", mu, mu, mu) + np.einsum("i,jl->ijl", mu, p)
             + np.einsum("j,il->ijl", mu, p) + np.einsum("l,ij->ijl", mu, p))
    np.testing.assert_allclose(e(third), exact, atol=1e-9)


def test_cubature_not_exact_at_degree_four_in_two_dimensions() -> None:
    pts = cubature.cubature_points(np.zeros(2), np.eye(2))
    assert math.isclose((pts[:, 0] ** 4).mean(), 2.0)            # Gaussian E[x⁴] = 3: the rule is degree 3


def test_weighted_mean_cov_is_centred() -> None:
    y = np.array([[1e8 + 1.0], [1e8 - 1.0], [1e8 + 3.0], [1e8 - 3.0]])
    mean, cov = cubature.weighted_mean_cov(y)
    assert mean[0] == 1e8 and cov[0, 0] == 5.0


def test_robust_cholesky_positive_definite_matches_numpy() -> None:
    _, p = random_gaussian(3, 3)
    np.testing.assert_array_equal(cubature.robust_cholesky(p), np.linalg.cholesky(p))
    np.testing.assert_allclose(cubature.cholesky_2x2(p[:2, :2]), np.linalg.cholesky(p[:2, :2]), rtol=1e-14)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=4, max_size=4),
       st.sampled_from([0.0, float("nan"), float("inf")]))
def test_robust_cholesky_never_raises_or_nan(values: list[float], poison: float) -> None:
    p = np.array(values).reshape(2, 2)
    p[1, 0] = p[0, 1] if poison == 0.0 else poison
    s = cubature.robust_cholesky(p)
    assert np.all(np.isfinite(s))
    assert np.all(np.isfinite(cubature.cholesky_2x2(np.where(np.isfinite(p), p, 0.0))))


def test_robust_cholesky_singular_reconstructs() -> None:
    p = np.array([[1.0, 1.0], [1.0, 1.0]]) * 1e-14         # rank one, radian-sized
    s = cubature.robust_cholesky(p)
    np.testing.assert_allclose(s @ s.T, p, atol=1e-25)


# ---------------------------------------------------- CKF against a plain KF


def test_ckf_equals_kalman_filter_on_linear_gaussian_model() -> None:
    rng = np.random.default_rng(7)
    n, m = 3, 2
    f_mat = np.eye(n) + 0.1 * rng.normal(size=(n, n))
    h_mat = rng.normal(size=(m, n))
    q = 0.05 * np.eye(n)
    r = np.array([[0.3, 0.05], [0.05, 0.2]])
    x_c, p_c = np.zeros(n), np.eye(n)
    x_k, p_k = x_c.copy(), p_c.copy()
    for _ in range(30):
        z = rng.normal(size=m)
        x_c, p_c = ckf.ckf_predict(x_c, p_c, lambda pts: pts @ f_mat.T, q)
        inn = ckf.ckf_innovation(x_c, p_c, z, lambda pts: pts @ h_mat.T, r)
        x_c, p_c = ckf.ckf_update(x_c, p_c, inn, r)
        x_k, p_k = f_mat @ x_k, f_mat @ p_k @ f_mat.T + q
        s = h_mat @ p_k @ h_mat.T + r
        k = p_k @ h_mat.T @ np.linalg.inv(s)
        x_k, p_k = x_k + k @ (z - h_mat @ x_k), p_k - k @ s @ k.T
        np.testing.assert_allclose(x_c, x_k, atol=1e-9)
        np.testing.assert_allclose(p_c, p_k, atol=1e-9)


def test_adaptive_factor_and_features() -> None:
    pzz = np.array([[10.0]])
    assert ckf.adaptive_factor(np.array([3.0]), pzz) == 1.0
    assert ckf.adaptive_factor(np.array([5.0]), pzz) == 10.0 / 25.0
    inn = ckf.Innovation(np.array([100.0]), np.array([5.0]), pzz, np.array([[1.0], [0.5]]))
    f1, f2, f3 = ckf.features_of(inn, np.array([[9.0]]), 0.4)
    assert (f1, f2, f3) == (5.0, 2.5, 22.5)


def test_ackf_equals_ckf_when_eta_is_one() -> None:
    x, p = random_gaussian(11, 2)
    inn = ckf.Innovation(np.array([1.0]), np.array([0.7]), np.array([[4.0]]), np.array([[0.5], [-0.2]]))
    plain = ckf.ckf_update(x, p, inn, np.array([[1.0]]))
    adapted = ckf.ckf_update(x, p, inn, np.array([[1.0]]), eta=ckf.adaptive_factor(inn.residual, inn.pzz))
    np.testing.assert_array_equal(plain[0], adapted[0])
    np.testing.assert_array_equal(plain[1], adapted[1])
    s = State2(LAT, LON, 1 / B0 ** 2, 0.0, 1 / A0 ** 2)
    small = ckf.range_innovation(s, 500.5, (*to_rad(300.0, 400.0), 0.0), 0.0, 9.0)
    assert small is not None and small.eta == 1.0 and small.r_adapted == 9.0
    assert ckf.range_update(s, small, 9.0, adaptive=True) == ckf.range_update(s, small, 9.0, adaptive=False)


def test_isolation_keeps_the_prediction() -> None:
    s = State2(LAT, LON, 4 / B0 ** 2, 0.0, 4 / A0 ** 2)
    inn = ckf.range_innovation(s, 530.0, (*to_rad(300.0, 400.0), 0.0), 0.0, 9.0)
    assert ckf.range_update(s, inn, 9.0, adaptive=True, gain=False) == s
    x, p = s.x, s.p
    assert ckf.ckf_update(x, p, ckf.Innovation(np.zeros(1), np.ones(1), np.eye(1), np.ones((2, 1))),
                          np.eye(1), gain=False) == (x, p)


def test_isolation_action_caps_consecutive_isolations() -> None:
    streak, actions = 0, []
    for flagged in [True] * 8 + [False, True]:
        action, streak = ckf.isolation_action(flagged, streak, cap=6)
        actions.append(action)
    assert actions == ["isolate"] * 6 + ["capped", "capped", "update", "isolate"]


# ------------------------------------------------- fast path = general path


def test_range_innovation_and_update_match_general_ckf() -> None:
    s = State2(*to_rad(12.0, -7.0), 6.0 / B0 ** 2, 1.5 / (A0 * B0), 3.0 / A0 ** 2)
    leader = (*to_rad(-250.0, 380.0), 1.0)
    z, r_var = 485.0, 9.0
    fast = ckf.range_innovation(s, z, leader, 4.0, r_var)
    h = lambda pts: model.horizontal_range(pts, 4.0, *leader)[..., None]   # noqa: E731
    general = ckf.ckf_innovation(s.x, s.p, np.array([z]), h, np.array([[r_var]]))
    assert abs(fast.z_hat - general.z_hat[0]) < 1e-6
    assert abs(fast.pzz - general.pzz[0, 0]) < 1e-6
    np.testing.assert_allclose([fast.pxz_lat * B0, fast.pxz_lon * A0], general.pxz[:, 0] * [B0, A0], atol=1e-6)
    eta = ckf.adaptive_factor(general.residual, general.pzz)
    assert eta < 1.0 and abs(fast.eta - eta) < 1e-9
    for adaptive in (False, True):
        out = ckf.range_update(s, fast, r_var, adaptive)
        x, p = ckf.ckf_update(s.x, s.p, general, np.array([[r_var]]), eta if adaptive else 1.0)
        assert abs((out.lat - x[0]) * B0) < 1e-6 and abs((out.lon - x[1]) * A0) < 1e-6
        np.testing.assert_allclose(model.cov_radians_to_metres(out.p, LAT),
                                   model.cov_radians_to_metres(p, LAT), atol=1e-6)


def test_dr_predict_matches_general_ckf_predict() -> None:
    s = State2(*to_rad(5.0, 5.0), 2.0 / B0 ** 2, 0.5 / (A0 * B0), 1.0 / A0 ** 2)
    args = (0.7, 1.5, 0.1, 0.3, 2.0)
    fast = ckf.dr_predict(s, *args, (1.0, 0.5))
    x, p = ckf.ckf_predict(s.x, s.p, lambda pts: model.dead_reckon_step(pts, *args),
                           ckf.process_noise(s.x, 0.7, (1.0, 0.5), 2.0))
    assert abs((fast.lat - x[0]) * B0) < 1e-6 and abs((fast.lon - x[1]) * A0) < 1e-6
    np.testing.assert_allclose(model.cov_radians_to_metres(fast.p, LAT),
                               model.cov_radians_to_metres(p, LAT), atol=1e-6)
    # Q = diag(1, 0.5)² m² per second, scaled by Δt
    grown = model.cov_radians_to_metres(fast.p, fast.lat, 2.0) - model.cov_radians_to_metres(s.p, s.lat, 2.0)
    np.testing.assert_allclose(np.diag(grown), [0.7, 0.25 * 0.7], atol=1e-3)


def test_range_ckf_class_wires_the_functions() -> None:
    s = State2(LAT, LON, 1 / B0 ** 2, 0.0, 1 / A0 ** 2)
    f = ckf.RangeCkf(s, 9.0, (1.0, 1.0), adaptive=True)
    f.predict(1.0, 1.0, 0.0, 0.0, 0.0)
    assert f.state == ckf.dr_predict(s, 1.0, 1.0, 0.0, 0.0, 0.0, (1.0, 1.0))
    before = f.state
    inn = f.update(510.0, (*to_rad(300.0, 400.0), 0.0), 0.0)
    assert inn is not None and f.state == ckf.range_update(before, inn, 9.0, True)


# ---------------------------------------------------------- degenerate input


@settings(max_examples=100, deadline=None)
@given(st.sampled_from([float("nan"), float("inf"), -float("inf"), 0.0, -5.0, 1e300]),
       st.sampled_from(["z", "lat", "lon", "depth"]))
def test_range_path_never_nan(bad: float, where: str) -> None:
    s = State2(LAT, LON, 1 / B0 ** 2, 0.0, 1 / A0 ** 2)
    leader = [*to_rad(300.0, 400.0), 0.0]
    z, depth = 500.0, 0.0
    if where == "z":
        z = bad
    elif where == "depth":
        depth = bad
    else:
        leader[0 if where == "lat" else 1] = bad
    inn = ckf.range_innovation(s, z, tuple(leader), depth, 9.0)
    if inn is not None:
        out = ckf.range_update(s, inn, 9.0, adaptive=True)
        assert all(map(math.isfinite, out)) and out.p11 > 0 and out.p22 > 0
        assert all(map(math.isfinite, inn.features))


def test_leader_on_top_is_rejected() -> None:
    s = State2(LAT, LON, 1 / B0 ** 2, 0.0, 1 / A0 ** 2)
    assert ckf.range_innovation(s, 0.5, (LAT, LON, 0.0), 3.0, 9.0) is None
    assert ckf.range_innovation(s, 0.5, (*to_rad(0.3, 0.0), 0.0), 3.0, 9.0) is None


# -------------------------------------------------- Monte Carlo consistency


def test_nees_and_nis_inside_chi_square_bounds() -> None:
    """CKF on a simulated follower: averaged NEES ~ χ²(2N)/N and NIS ~ χ²(N)/N per epoch."""
    rng = np.random.default_rng(2024)
    runs, epochs, dt, q = 60, 40, 5.0, (0.5, 0.5)
    leaders = [(*to_rad(400.0, -300.0), 0.0), (*to_rad(-350.0, 450.0), 0.0)]
    p0_m = np.diag([4.0, 4.0])
    nees = np.zeros((runs, epochs))
    nis = np.zeros((runs, epochs))
    for run in range(runs):
        truth = np.array(to_rad(*rng.multivariate_normal([0.0, 0.0], p0_m)))
        s = State2(LAT, LON, 4.0 / B0 ** 2, 0.0, 4.0 / A0 ** 2)
        for k in range(epochs):
            heading = 0.3 + 0.05 * k
            truth = model.dead_reckon_step(truth, dt, 1.2, 0.1, heading, 0.0)
            qr = ckf.process_noise(truth, dt, q, 0.0)
            truth = truth + rng.normal(size=2) * np.sqrt(np.diag(qr))
            s = ckf.dr_predict(s, dt, 1.2, 0.1, heading, 0.0, q)
            leader = leaders[k % 2]
            z = float(model.horizontal_range(truth, 0.0, *leader)) + rng.normal(0.0, 3.0)
            inn = ckf.range_innovation(s, z, leader, 0.0, 9.0)
            nis[run, k] = inn.residual ** 2 / inn.pzz
            s = ckf.range_update(s, inn, 9.0, adaptive=False)
            err = truth - s.x
            nees[run, k] = err @ np.linalg.solve(s.p, err)
    lo2, hi2 = chi2.ppf([0.005, 0.995], 2 * runs) / runs
    lo1, hi1 = chi2.ppf([0.005, 0.995], runs) / runs
    mean_nees, mean_nis = nees.mean(axis=0), nis.mean(axis=0)
    assert np.mean((mean_nees > lo2) & (mean_nees < hi2)) >= 0.9
    assert np.mean((mean_nis > lo1) & (mean_nis < hi1)) >= 0.9
    # and over all epochs together
    all_lo, all_hi = chi2.ppf([0.005, 0.995], 2 * runs * epochs) / (runs * epochs)
    assert all_lo < nees.mean() < all_hi
    assert chi2.ppf(0.005, runs * epochs) / (runs * epochs) < nis.mean() < chi2.ppf(0.995, runs * epochs) / (
        runs * epochs)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000))
def test_position_update_is_the_kalman_update(seed: int) -> None:
    """A direct position fix (H = I) through the scalar path equals the textbook Kalman update."""
    rng = np.random.default_rng(seed)
    x, p = random_gaussian(seed, 2)
    p, x = p * 1e-12, LAT + x * 1e-6                      # rad² and rad of a few metres
    a = rng.normal(size=(2, 2))
    r = (a @ a.T + 0.1 * np.eye(2)) * 1e-12
    z = x + rng.normal(size=2) * 1e-6
    out = ckf.position_update(State2.from_arrays(x, p), z[0], z[1], r[0, 0], r[0, 1], r[1, 1])
    k = p @ np.linalg.inv(p + r)
    np.testing.assert_allclose(out.x, x + k @ (z - x), rtol=0, atol=1e-15)
    np.testing.assert_allclose(out.p, p - k @ p, rtol=1e-9, atol=1e-24)


def test_position_update_rejects_what_it_cannot_use() -> None:
    s = State2(LAT, LON, 1e-12, 0.0, 1e-12)
    assert ckf.position_update(s, float("nan"), LON, 1e-12, 0.0, 1e-12) is None
    assert ckf.position_update(s, LAT, LON, 1e-12, 0.0, float("inf")) is None
    assert ckf.position_update(s, LAT, LON, -3e-12, 0.0, -3e-12) is None       # S not positive definite
    tight = ckf.position_update(s, LAT + 1e-6, LON, 1e-16, 0.0, 1e-16)        # a near-exact fix wins
    assert abs(tight.lat - (LAT + 1e-6)) < 1e-9 and tight.p11 < 1e-15
