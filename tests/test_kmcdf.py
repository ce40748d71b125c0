"""KMCDF: support weights, k-means, re-clustering, OR fusion, ML fix, per-epoch API, Monte Carlo."""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.positioning import kmcdf as km
from replay.stack.positioning import kmcdf_montecarlo as mc

PARAMS = km.KmcdfParams()
KD0 = PARAMS.kappa_d0


def observe(node_xy: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise-free delays and phase differences (T, N) for targets (T, 2)."""
    d = target[:, None, :] - node_xy
    r = np.hypot(d[..., 0], d[..., 1])
    return r / PARAMS.sound_speed_mps, KD0 * d[..., 0] / r, KD0 * d[..., 1] / r


def brute_force_kmeans(values: np.ndarray) -> set[int]:
    """Indices of the higher group of the best 2-partition, trying every partition (the judge)."""
    best, best_sse = set(), math.inf
    n = len(values)
    for bits in itertools.product([0, 1], repeat=n):
        if 0 < sum(bits) < n:
            a, b = values[np.array(bits) == 0], values[np.array(bits) == 1]
            sse = np.sum((a - a.mean()) ** 2) + np.sum((b - b.mean()) ** 2)
            if sse < best_sse - 1e-15:
                best_sse = sse
                best = {i for i in range(n) if bits[i] == (1 if b.mean() > a.mean() else 0)}
    return best


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=2, max_size=9, unique=True))
def test_kmeans_matches_exhaustive_partition_search(values: list[float]) -> None:
    w = np.array(values)
    if np.min(np.diff(np.sort(w))) < 1e-6:
        return
    high = km.kmeans2_1d(w[None, :], np.ones((1, w.size), dtype=bool))[0]
    assert set(np.nonzero(high)[0]) == brute_force_kmeans(w)


def test_kmeans_ignores_masked_entries() -> None:
    w = np.array([[0.9, 0.1, 0.85, 5.0, 0.12]])
    mask = np.array([[True, True, True, False, True]])
    assert km.kmeans2_1d(w, mask)[0].tolist() == [True, False, True, False, False]


def test_perron_weights_are_the_principal_eigenvector() -> None:
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(1, 12, 2)) * 10
    mask = np.ones((1, 12), dtype=bool)
    mask[0, 4] = False
    dist = km.pairwise_distances(pts, mask)
    w = km.perron_weights(dist, mask)[0]
    sub = dist[0][np.ix_(mask[0], mask[0])]
    b = 1 - sub / sub.max()
    v = np.ones(11)
    for _ in range(500):                        # power iteration as the slow judge
        v = b @ v
        v /= v.sum()
    np.testing.assert_allclose(w[mask[0]], v, rtol=1e-8)
    assert w[4] == 0.0 and math.isclose(w.sum(), 1.0)


def test_clustering_keeps_the_tight_group_and_reclusters_a_near_outlier() -> None:
    rng = np.random.default_rng(7)
    tight = rng.normal(scale=3.0, size=(12, 2))
    near = np.array([[45.0, 0.0]])                          # close enough to share C1 at first
    far = np.array([[900.0, 300.0], [-700.0, 800.0], [600.0, -950.0]])
    pts = np.concatenate([tight, near, far])[None]
    valid = np.ones((1, 16), dtype=bool)
    result = km.cluster_fixes(pts, valid, 30.0)
    assert result.cluster1[0].tolist() == [True] * 12 + [False] * 4
    assert result.rounds[0] >= 2
    valid[0, 13:] = False                                   # missing fixes are never in C1
    result = km.cluster_fixes(pts, valid, 30.0)
    assert result.cluster1[0].tolist() == [True] * 12 + [False] * 4


def test_all_normal_when_spread_within_rho() -> None:
    pts = np.array([[[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]])
    result = km.cluster_fixes(pts, np.ones((1, 3), dtype=bool), 30.0)
    assert result.cluster1.all() and result.rounds[0] == 0


def test_or_fusion() -> None:
    incidence = np.array([[1, 0, 1], [0, 1, 1], [1, 1, 0]], dtype=bool)
    c1 = np.array([[True, False, False], [False, False, False]])
    assert km.or_fusion(c1, incidence).tolist() == [[True, False, True], [False, False, False]]


def test_epoch_noise_free_is_exact_and_all_normal() -> None:
    for n in (4, 6):
        nodes = mc.node_layout(n)
        target = np.array([[123.0, -456.0]])
        fix = km.kmcdf_epoch(nodes, *(a[0] for a in observe(nodes, target)))
        np.testing.assert_allclose(fix.position_xy, target[0], atol=1e-6)
        assert fix.delay_normal.all() and fix.phase_normal.all()
        assert np.all(np.linalg.eigvalsh(fix.covariance) > 0)
        assert len(fix.fixes) + fix.missing_fixes == n + 2 * math.comb(n, 2) + math.comb(n, 3)
        assert fix.rounds == 0 and fix.spread_m < 1e-6


def test_epoch_finds_abnormal_delay_and_phases() -> None:
    nodes = mc.node_layout(6)
    target = np.array([[300.0, 200.0]])
    delays, px, py = (a[0].copy() for a in observe(nodes, target))
    delays[1] = 0.9              # 1350 m instead of the truth
    px[4], py[4] = 2.5, -1.0     # node 4's phases abnormal
    delays[4] = 0.2
    fix = km.kmcdf_epoch(nodes, delays, px, py)
    assert fix.delay_normal.tolist() == [True, False, True, True, False, True]
    assert fix.phase_normal.tolist() == [[True, True]] * 4 + [[False, False], [True, True]]
    np.testing.assert_allclose(fix.position_xy, target[0], atol=1e-6)
    in_c1 = [f for f in fix.fixes if f.cluster == 1]
    assert in_c1 and all(1 not in f.parameters and 4 not in f.parameters for f in in_c1)
    assert {f.kind for f in fix.fixes} == {"usbl", "bearing_pair", "circle_pair", "range_triple"}


def test_fix_columns_are_the_preliminary_fixes_columns() -> None:
    nodes = mc.node_layout(6)
    delays, px, py = (a[0].copy() for a in observe(nodes, np.array([[300.0, 200.0]])))
    delays[1], delays[3] = 0.9, np.nan
    px[4] = 2.5
    for fix in (km.kmcdf_epoch(nodes, delays, px, py), km.kmcdf_epoch(nodes, *([np.full(6, np.nan)] * 3))):
        east, north, cluster = fix.fix_columns()
        assert east == [f.xy[0] for f in fix.fixes] and north == [f.xy[1] for f in fix.fixes]
        assert cluster == [f.cluster for f in fix.fixes]
    assert len(km.kmcdf_epoch(nodes, delays, px, py).fix_columns()[0]) > 0


def test_epoch_with_missing_measurement_does_not_raise() -> None:
    nodes = mc.node_layout(4)
    target = np.array([[-250.0, 610.0]])
    delays, px, py = (a[0].copy() for a in observe(nodes, target))
    delays[2] = np.nan
    with np.errstate(all="raise"):
        fix = km.kmcdf_epoch(nodes, delays, px, py)
    assert fix.delay_normal.tolist() == [True, True, False, True]
    np.testing.assert_allclose(fix.position_xy, target[0], atol=1e-6)


def test_epoch_with_nothing_usable_gives_nan_position() -> None:
    nodes = mc.node_layout(4)
    nan = np.full(4, np.nan)
    fix = km.kmcdf_epoch(nodes, nan, nan, nan)
    assert np.isnan(fix.position_xy).all() and not fix.delay_normal.any() and not fix.fixes


def test_ml_fix_covariance_matches_scatter() -> None:
    rng = np.random.default_rng(11)
    nodes = mc.node_layout(6)
    target = np.repeat(np.array([[150.0, 80.0]]), 400, 0)
    d, px, py = observe(nodes, target)
    d = d + PARAMS.sigma_delay_s * rng.standard_normal(d.shape)
    px = px + PARAMS.sigma_phase_rad * rng.standard_normal(d.shape)
    py = py + PARAMS.sigma_phase_rad * rng.standard_normal(d.shape)
    xy, cov = km.ml_fix(nodes, d, px, py, np.ones((400, 18), dtype=bool), target + 5.0, PARAMS)
    err = xy - target
    np.testing.assert_allclose(np.cov(err.T), cov[0], atol=0.25 * float(cov[0, 0, 0]))
    assert abs(np.mean(err)) < 0.05


def test_simulation_draws_the_requested_abnormal_nodes() -> None:
    nodes = mc.node_layout(6)
    sim = mc.simulate(nodes, 2, 300, True, mc.point_rng(0, 6, 2, 2))
    assert np.all(sim.delay_abnormal.sum(1) == 2)
    assert np.array_equal(sim.phase_abnormal, sim.delay_abnormal)
    assert np.all(np.abs(sim.phase_x[sim.phase_abnormal]) <= math.pi)
    assert np.all((sim.delays_s[sim.delay_abnormal] > 0) & (sim.delays_s[sim.delay_abnormal] < 2830 / 1500))
    assert np.all(np.abs(sim.target_xy) <= 1000.0)
    again = mc.simulate(nodes, 2, 300, True, mc.point_rng(0, 6, 2, 2))
    assert np.array_equal(sim.delays_s, again.delays_s)


def test_layouts_follow_the_paper() -> None:
    np.testing.assert_allclose(mc.node_layout(6)[1], [400.0, 400.0 * math.sqrt(3)], atol=1e-9)
    np.testing.assert_allclose(mc.node_layout(4), [[800, 800], [-800, 800], [-800, -800], [800, -800]],
                               atol=1e-9)


def test_monte_carlo_point_is_seeded_and_plausible() -> None:
    a = mc.success_point(6, 3, "kmcdf1", 150, seed=5)
    b = mc.success_point(6, 3, "kmcdf1", 150, seed=5)
    assert a == b and a > 0.8
    assert mc.success_point(6, 0, "kmcdf2", 150, seed=5) > 0.95
    assert mc.success_point(4, 4, "kmcdf2", 50, seed=5) == 0.0     # nothing normal is left
