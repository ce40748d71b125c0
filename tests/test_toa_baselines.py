"""Delay-only baselines: range fixes exact, each method finds a gross outlier, LHC's majorization descends."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.positioning import toa_baselines as tb
from replay.stack.positioning.kmcdf_montecarlo import node_layout, run_baseline, simulate

NODES = node_layout(6)
coord = st.floats(-1000.0, 1000.0, allow_nan=False)


def ranges_to(target: np.ndarray, nodes: np.ndarray = NODES) -> np.ndarray:
    """Noise-free ranges (T, N)."""
    d = target[:, None, :] - nodes
    return np.hypot(d[..., 0], d[..., 1])


def huber_cost(nodes: np.ndarray, ranges: np.ndarray, xy: np.ndarray, k: float) -> np.ndarray:
    """Sum of Huber losses of the range residuals, per trial."""
    e = np.abs(tb.toa_residuals(nodes, ranges, xy))
    return np.sum(np.where(e <= k, 0.5 * e**2, k * e - 0.5 * k**2), axis=-1)


@settings(max_examples=50, deadline=None)
@given(coord, coord)
def test_linear_and_mmse_fixes_are_exact(x: float, y: float) -> None:
    target = np.array([[x, y]])
    r = ranges_to(target)
    w = np.ones_like(r)
    np.testing.assert_allclose(tb.toa_linear_fix(NODES, r, w), target, atol=1e-6)
    np.testing.assert_allclose(tb.toa_mmse(NODES, r, w), target, atol=1e-6)
    mask = np.array([[1.0, 0, 1, 1, 0, 0]])
    np.testing.assert_allclose(tb.toa_mmse(NODES, r, mask), target, atol=1e-6)


def test_linear_fix_of_collinear_nodes_is_nan() -> None:
    nodes = np.array([[0.0, 0.0], [10.0, 0.0], [30.0, 0.0]])
    out = tb.toa_linear_fix(nodes, np.array([[5.0, 6.0, 25.0]]), np.ones((1, 3)))
    assert np.isnan(out).all()


def noisy_with_outlier(seed: int, bad: int = 2, value: float = 1700.0) -> tuple[np.ndarray, np.ndarray]:
    """Ranges of random targets with 0.3 m noise and one gross outlier at node `bad`."""
    rng = np.random.default_rng(seed)
    target = rng.uniform(-600, 600, size=(40, 2))
    r = ranges_to(target) + 0.3 * rng.standard_normal((40, 6))
    r[:, bad] = value
    return target, r


def test_each_baseline_flags_one_gross_outlier() -> None:
    target, r = noisy_with_outlier(1)
    expected = np.ones((40, 6), dtype=bool)
    expected[:, 2] = False
    far = np.abs(r[:, 2] - ranges_to(target)[:, 2]) > 50
    results = {
        "gar": tb.gar(NODES, r, threshold_m2=5.76 * 0.75**2),
        "ear": tb.ear(NODES, r, ring_width_m=4.5),
        "lms": tb.lms(NODES, r),
        "lhc": tb.lhc(NODES, r, huber_k_m=1.5),
    }
    for name, res in results.items():
        ok = np.all(res.normal == expected, axis=-1) | ~far
        assert ok.mean() >= 0.8, name               # LMS's scale from 6 residuals runs low
        assert not np.any(res.normal[far, 2]), name
        err = np.hypot(*(res.position - target).T)[ok & far]
        assert np.median(err) < (3.0 if name == "ear" else 1.0), name


def test_gar_keeps_a_consistent_set_and_stops_at_three() -> None:
    target = np.array([[100.0, -200.0]])
    r = ranges_to(target)
    res = tb.gar(NODES, r, threshold_m2=1.0)
    assert res.normal.all() and res.resolved.all()
    wild = np.array([[10.0, 2500.0, 40.0, 1900.0, 700.0, 1200.0]])
    res = tb.gar(NODES, wild, threshold_m2=1.0)
    assert res.normal.sum() == 3 and not res.resolved[0]


def test_lms_breaks_down_at_half_outliers() -> None:
    rng = np.random.default_rng(4)
    target = rng.uniform(-600, 600, size=(30, 2))
    r = ranges_to(target) + 0.3 * rng.standard_normal((30, 6))
    r[:, :3] = rng.uniform(0, 2830, size=(30, 3))
    res = tb.lms(NODES, r)
    assert not np.any(np.all(res.normal == np.array([False] * 3 + [True] * 3), axis=-1))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000))
def test_huber_majorization_never_increases_the_cost(seed: int) -> None:
    rng = np.random.default_rng(seed)
    r = ranges_to(rng.uniform(-900, 900, size=(1, 2))) + rng.normal(scale=0.7, size=(1, 6))
    r[0, rng.integers(6)] = rng.uniform(0, 2830)
    xy = rng.uniform(-900, 900, size=(1, 2))
    cost = huber_cost(NODES, r, xy, 1.5)
    for _ in range(30):
        xy = tb._majorization_step(NODES, r, xy, 1.5)
        new = huber_cost(NODES, r, xy, 1.5)
        assert new[0] <= cost[0] + 1e-9
        cost = new


def test_ear_voting_finds_the_cell_of_the_majority() -> None:
    target = np.array([[321.0, -123.0]])
    r = ranges_to(target)
    r[0, 0] += 400.0
    res = tb.ear(NODES, r, ring_width_m=4.5)
    assert res.normal[0].tolist() == [False] + [True] * 5
    assert np.hypot(*(res.position[0] - target[0])) < 2.0
    shifted = tb.ear(NODES + 5000.0, r, ring_width_m=4.5, field_centre_xy=(5000.0, 5000.0))
    assert np.hypot(*(shifted.position[0] - target[0] - 5000.0)) < 2.0


def test_run_baseline_uses_the_papers_constants() -> None:
    sim = simulate(NODES, 1, 200, False, np.random.default_rng(2))
    for name in tb.BASELINES:
        res = run_baseline(name, sim)
        assert res.normal.shape == (200, 6)
        success = np.mean(np.all(res.normal == ~sim.delay_abnormal, axis=-1))
        assert success > 0.4, name
