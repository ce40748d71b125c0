"""AQPSO-GA: batched fitness against a one-by-one reference, operators, and the whole search."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.detectors import anfis as A
from replay.stack.detectors import aqpso as Q


def data(seed: int, n: int = 120) -> tuple[np.ndarray, np.ndarray]:
    """A smooth nonlinear target on [0, 1]^3 with a little noise."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 1.0, (n, 3))
    y = 4.0 * np.exp(-8.0 * (x[:, 0] - 0.3) ** 2) + x[:, 1] * x[:, 2] + rng.normal(0.0, 0.02, n)
    return x, y


def test_population_fitness_matches_one_particle_at_a_time() -> None:
    x, y = data(1)
    s = Q.AqpsoSettings()
    low, high = Q.search_box(np.zeros(3), np.ones(3), 2, s)
    rng = np.random.default_rng(2)
    pop = low + rng.random((7, low.size)) * (high - low)
    rules = A.rule_table(3, 2)
    fit, cons = Q.population_fitness(x, y, pop, rules)
    assert fit.shape == (7,) and cons.shape == (7, 8, 4)
    for k in range(7):
        a, b, c = Q.unflatten(pop[k], 3, 2)
        _, wbar = A.normalized_firing(x, a, b, c, rules)
        q = A.fit_consequents(x, wbar, y)
        model = A.AnfisModel(a, b, c, q, rules)
        assert fit[k] == pytest.approx(A.rmse(model, x, y), rel=1e-8)
        np.testing.assert_allclose(cons[k], q, rtol=1e-7, atol=1e-8)


def test_search_box_layout() -> None:
    s = Q.AqpsoSettings()
    low, high = Q.search_box(np.array([0.0, 10.0]), np.array([1.0, 30.0]), 2, s)
    a_lo, b_lo, c_lo = Q.unflatten(low, 2, 2)
    a_hi, b_hi, c_hi = Q.unflatten(high, 2, 2)
    np.testing.assert_allclose(a_lo, [[0.02, 0.02], [0.4, 0.4]])
    np.testing.assert_allclose(a_hi, [[1.0, 1.0], [20.0, 20.0]])
    np.testing.assert_allclose(b_lo, 0.5)
    np.testing.assert_allclose(b_hi, 8.0)
    np.testing.assert_allclose(c_lo, [[-0.25, -0.25], [5.0, 5.0]])
    np.testing.assert_allclose(c_hi, [[1.25, 1.25], [35.0, 35.0]])


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.01, 1e3), min_size=1, max_size=30), st.floats(0.01, 1e3))
def test_adaptive_beta_bounds_and_order(fits: list[float], best: float) -> None:
    s = Q.AqpsoSettings()
    f = np.array(fits) + best          # every particle at or behind the best
    beta = Q.adaptive_beta(f, best, s)
    assert np.all(beta >= s.beta_min - 1e-12) and np.all(beta <= s.beta_max + 1e-12)
    order = np.argsort(f, kind="stable")
    assert np.all(np.diff(beta[order]) <= 1e-12)   # farther from the best -> smaller beta


def test_adaptive_beta_at_the_best_is_beta_max() -> None:
    s = Q.AqpsoSettings()
    beta = Q.adaptive_beta(np.array([2.0, 2.0 * 50, np.inf]), 2.0, s)
    assert beta[0] == pytest.approx(s.beta_max)
    assert beta[1] == pytest.approx(s.beta_min, abs=1e-12)
    assert beta[2] == pytest.approx(s.beta_min, abs=1e-12)


def test_qpso_move_collapses_when_the_swarm_agrees() -> None:
    rng = np.random.default_rng(0)
    point = np.array([0.3, 1.5, 0.7])
    pos = np.tile(point, (5, 1))
    moved = Q.qpso_move(pos, pos.copy(), point, np.full(5, 1.0), rng)
    np.testing.assert_allclose(moved, pos)


def test_qpso_move_spreads_around_the_attractor() -> None:
    rng = np.random.default_rng(1)
    pos = np.zeros((20000, 1))
    pbest = np.ones((20000, 1))      # mbest = 1, attractor = 1: x = 1 +- beta |1 - 0| ln(1/u)
    moved = Q.qpso_move(pos, pbest, np.ones(1), np.full(20000, 0.5), rng)
    jump = np.abs(moved[:, 0] - 1.0)
    # ln(1/u) with u ~ U(0, 1) is Exp(1): mean beta = 0.5
    assert jump.mean() == pytest.approx(0.5, rel=0.03)
    assert np.mean(moved[:, 0] > 1.0) == pytest.approx(0.5, abs=0.02)


def test_ga_reseed_only_touches_stalled_particles_and_stays_between_parents() -> None:
    rng = np.random.default_rng(3)
    pos = rng.normal(size=(6, 4))
    pbest = rng.uniform(0.0, 1.0, (6, 4))
    stalled = np.array([False, True, False, False, True, False])
    out = Q.ga_reseed(pos, stalled, pbest, rng.random(6), rng)
    np.testing.assert_array_equal(out[~stalled], pos[~stalled])
    assert np.all((out[stalled] >= pbest.min(axis=0)) & (out[stalled] <= pbest.max(axis=0)))
    assert out is not pos


def test_ga_mutate_rate() -> None:
    rng = np.random.default_rng(4)
    s = Q.AqpsoSettings(mutation_rate=0.2)
    pos = np.zeros((500, 10))
    out = Q.ga_mutate(pos, np.zeros(10), np.ones(10), s, rng)
    assert np.mean(out != 0.0) == pytest.approx(0.2, abs=0.02)


def test_search_improves_reproducibly_and_keeps_its_history() -> None:
    x, y = data(5)
    s = Q.AqpsoSettings(particles=12, iterations=25, seed=9)
    r1 = Q.train_aqpso_ga(x, y, settings=s, lo=np.zeros(3), hi=np.ones(3))
    r2 = Q.train_aqpso_ga(x, y, settings=s, lo=np.zeros(3), hi=np.ones(3))
    np.testing.assert_array_equal(r1.history.rmse, r2.history.rmse)
    h = r1.history
    assert h.epochs == 26 and h.a.shape == (26, 3, 2) and h.consequents.shape == (26, 8, 4)
    assert np.all(np.diff(h.rmse) <= 0.0)                  # the global best never gets worse
    assert r1.rmse == h.rmse[-1]
    assert A.rmse(r1.model, x, y) == pytest.approx(r1.rmse, rel=1e-8)
    # never worse than the genfis1 start it contains, and here much better
    start = A.initial_model(x, 2, lo=np.zeros(3), hi=np.ones(3))
    _, wbar = A.normalized_firing(x, start.a, start.b, start.c, start.rules)
    start_rmse = A.rmse(start.with_consequents(A.fit_consequents(x, wbar, y)), x, y)
    assert r1.rmse < 0.7 * start_rmse
    low, high = Q.search_box(np.zeros(3), np.ones(3), 2, s)
    flat = np.concatenate([r1.model.a.ravel(), r1.model.b.ravel(), r1.model.c.ravel()])
    assert np.all((flat >= low) & (flat <= high))


def test_other_seed_other_path() -> None:
    x, y = data(6)
    lo, hi = np.zeros(3), np.ones(3)
    r1 = Q.train_aqpso_ga(x, y, settings=Q.AqpsoSettings(particles=8, iterations=5, seed=1), lo=lo, hi=hi)
    r2 = Q.train_aqpso_ga(x, y, settings=Q.AqpsoSettings(particles=8, iterations=5, seed=2), lo=lo, hi=hi)
    assert not np.array_equal(r1.history.rmse, r2.history.rmse)


def test_diagonal_rules() -> None:
    x, y = data(7)
    r = Q.train_aqpso_ga(x, y, mfs=3, structure="diagonal",
                         settings=Q.AqpsoSettings(particles=10, iterations=10), lo=np.zeros(3), hi=np.ones(3))
    assert r.model.n_rules == 3 and r.model.consequents.shape == (3, 4)
    assert np.isfinite(r.rmse)
